#include "server/services/comparison_service.h"

#include <cmath>
#include <exception>
#include <optional>
#include <set>

#include "api/model_call.h"
#include "server/services/stored_trials.h"
#include "storage/parameter_sets.h"

namespace fesbench::server::services {
namespace {

bool KnownMetric(const std::string& m) {
  return m == "e_rms" || m == "e_abs" || m == "normalised_rms" || m == "e_ave";
}

std::optional<double> Metric(const PredictionErrors& e, const std::string& metric) {
  if (metric == "e_rms") return e.e_rms;
  if (metric == "e_abs") return e.e_abs;
  if (metric == "normalised_rms") return e.normalised_rms;
  return e.e_ave;
}

}  // namespace

api::Status ValidateComparisonRequest(const ComparisonRequest& request) {
  if (request.pairs.empty()) {
    return api::Status::InvalidArgument("at least 1 pair", "pairs");
  }
  if (request.pairs.size() > 200) {
    return api::Status::InvalidArgument("at most 200 pairs", "pairs");
  }
  for (std::size_t i = 0; i < request.pairs.size(); ++i) {
    const ComparisonPair& p = request.pairs[i];
    const std::string field = "pairs[" + std::to_string(i) + "]";
    if (p.a_parameter_set_id <= 0) {
      return api::Status::InvalidArgument("must be a positive id", field + ".a_parameter_set_id");
    }
    if (p.b_parameter_set_id <= 0) {
      return api::Status::InvalidArgument("must be a positive id", field + ".b_parameter_set_id");
    }
    if (p.trial_ids.empty() || p.trial_ids.size() > 50) {
      return api::Status::InvalidArgument("1–50 trials", field + ".trial_ids");
    }
    std::set<std::int64_t> seen;
    for (std::size_t k = 0; k < p.trial_ids.size(); ++k) {
      const std::string tf = field + ".trial_ids[" + std::to_string(k) + "]";
      if (p.trial_ids[k] <= 0) return api::Status::InvalidArgument("must be a positive id", tf);
      if (!seen.insert(p.trial_ids[k]).second) {
        return api::Status::InvalidArgument("duplicate trial id", tf);
      }
    }
  }
  if (!KnownMetric(request.metric)) {
    return api::Status::InvalidArgument("must be e_rms, e_abs, normalised_rms or e_ave", "metric");
  }
  if (!(request.confidence > 0.0 && request.confidence < 1.0)) {
    return api::Status::InvalidArgument("must be in (0, 1)", "confidence");
  }
  return api::Status::Ok();
}

ComparisonService::ComparisonService(storage::Database& db, PredictionConfig config)
    : db_(db), predictions_(db, config) {}

api::Result<ComparisonResult> ComparisonService::Compare(const ComparisonRequest& request) const {
  if (api::Status s = ValidateComparisonRequest(request); !s.ok()) return s;
  ComparisonResult out;
  out.metric = request.metric;
  const bool dimensionless = request.metric == "normalised_rms" || request.metric == "e_ave";
  std::string channel;
  try {
    storage::ParameterSetRepository sets(db_);
    std::vector<double> a, b;
    for (std::size_t i = 0; i < request.pairs.size(); ++i) {
      const ComparisonPair& p = request.pairs[i];
      const std::string field = "pairs[" + std::to_string(i) + "]";
      api::Result<storage::StoredParameterSet> sa = sets.Get(p.a_parameter_set_id);
      if (!sa.ok()) return sa.status();
      api::Result<storage::StoredParameterSet> sb = sets.Get(p.b_parameter_set_id);
      if (!sb.ok()) return sb.status();
      if (sa->summary.leg_id != sb->summary.leg_id) {
        return api::Status::InvalidArgument(
            "parameter set " + std::to_string(p.b_parameter_set_id) + " is of another leg than " +
                std::to_string(p.a_parameter_set_id) + "; a pair is one subject's leg",
            field + ".b_parameter_set_id");
      }
      PairComparison pc;
      pc.a_parameter_set_id = p.a_parameter_set_id;
      pc.b_parameter_set_id = p.b_parameter_set_id;
      pc.subject_id = sa->summary.subject_id;
      pc.leg_id = sa->summary.leg_id;
      for (std::size_t k = 0; k < p.trial_ids.size(); ++k) {
        const std::string tf = field + ".trial_ids[" + std::to_string(k) + "]";
        api::Result<LoadedTrial> owner = LoadTrial(db_, p.trial_ids[k]);
        if (!owner.ok()) return owner.status();
        if (owner->leg_id != pc.leg_id) {
          return api::Status::InvalidArgument("trial of another leg than the pair's sets", tf);
        }
        TrialComparison tc;
        tc.trial_id = p.trial_ids[k];
        for (const bool use_a : {true, false}) {
          PredictionRequest pr;
          pr.parameter_set_id = use_a ? p.a_parameter_set_id : p.b_parameter_set_id;
          pr.trial_id = p.trial_ids[k];
          api::Result<PredictionResult> r = predictions_.Compute(pr);
          if (!r.ok()) {
            api::Status s = r.status();
            return api::Status(s.code(), tf + ": " + s.message(),
                               s.field().empty() ? tf : s.field());
          }
          const PredictionErrors& e = *r->errors;
          if (channel.empty()) {
            channel = e.channel;
            out.unit = dimensionless ? "1" : e.unit;
          } else if (e.channel != channel && !dimensionless) {
            return api::Status::InvalidArgument(
                "trial compares " + e.channel + " but earlier trials " + channel +
                    "; use a dimensionless metric (normalised_rms, e_ave) to mix them",
                tf);
          }
          const std::optional<double> v = Metric(e, request.metric);
          if (!v) {
            return api::Status::FailedPrecondition(tf + ": " + request.metric +
                                                   " is undefined on this trial (Eq. 6.1/6.2)");
          }
          (use_a ? tc.a_error : tc.b_error) = *v;
        }
        pc.a_error += tc.a_error / static_cast<double>(p.trial_ids.size());
        pc.b_error += tc.b_error / static_cast<double>(p.trial_ids.size());
        pc.trials.push_back(tc);
      }
      a.push_back(pc.a_error);
      b.push_back(pc.b_error);
      out.pairs.push_back(std::move(pc));
    }
    // Eq. 6.3 where it is defined: 2 pairs or more whose differences are
    // not all equal; otherwise the errors alone and why (docs/API.md, Jobs).
    if (a.size() < 2) {
      out.test_note = "no paired t-test: it needs at least 2 pairs, got " +
                      std::to_string(a.size()) + "; the errors of each set are given";
    } else {
      api::Result<model::PairedTTestResult> test =
          api::CallModel([&] { return model::PairedTTest(a, b, request.confidence); });
      if (test.ok()) {
        out.test = *std::move(test);
      } else {
        out.test_note =
            "no paired t-test: every pair's difference is the same (S_d = 0, t undefined); the "
            "errors of each set are given";
      }
    }
  } catch (const std::exception& e) {
    return api::Status::Internal(std::string("comparison: ") + e.what());
  }
  return out;
}

}  // namespace fesbench::server::services
