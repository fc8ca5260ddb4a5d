#include "server/services/prediction_service.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <stdexcept>
#include <vector>

#include "api/model_call.h"
#include "api/trial_import.h"
#include "api/trial_kind.h"
#include "model/conditioning.h"
#include "model/evaluation.h"
#include "model/extrapolate.h"
#include "model/identify_passive_only.h"
#include "model/identify_rapid.h"
#include "model/signal.h"
#include "model/strength_history.h"
#include "server/protocols/model_gate.h"
#include "server/services/analysis_json.h"
#include "server/services/stored_trials.h"
#include "storage/audit_log.h"
#include "storage/parameter_sets.h"
#include "storage/predictions.h"
#include "storage/trials.h"

namespace fesbench::server::services {
namespace {

bool InRange(double v, double lo, double hi) { return std::isfinite(v) && v >= lo && v <= hi; }

// Mean of the measured samples before the first stimulation (up to 50, §5.3),
// or 0 when the trial starts stimulated (the runner already removed it).
double MeasuredOffset(const model::TrialColumns& c) {
  std::size_t n = 0;
  while (n < c.size() && n < 50 && !(c.stim_ma.size() == c.size() && c.stim_ma[n] > 0.0)) ++n;
  return n == 0 ? 0.0 : model::TorqueOffset(c.torque_nm, n);
}

PredictionErrors Errors(const std::vector<double>& predicted, const std::vector<double>& data,
                        bool isometric, double exclude_fraction) {
  PredictionErrors e;
  e.channel = isometric ? "torque_nm" : "angle_deg";
  e.unit = isometric ? "N.m" : "deg";
  e.samples = data.size();
  e.e_rms = model::RmsError(predicted, data);  // Eq. 6.9
  e.e_abs = model::AbsError(predicted, data);  // Eq. 6.10
  for (std::size_t i = 0; i < data.size(); ++i) {
    e.max_abs = std::max(e.max_abs, std::abs(predicted[i] - data[i]));
  }
  // Eq. 6.1 and Eq. 6.2 are undefined on some data (every sample excluded,
  // Σ data = 0): then null.
  if (const auto n = model::NormalisedRmsError(predicted, data, exclude_fraction)) {
    e.normalised_rms = n->value;
    e.normalised_samples_used = n->samples_used;
  }
  if (const auto e_ave = model::AveragedRmsError(predicted, data)) e.e_ave = *e_ave;
  return e;
}

}  // namespace

api::Status ValidatePredictionRequest(const PredictionRequest& r, const PredictionConfig& config) {
  if (r.parameter_set_id <= 0) {
    return api::Status::InvalidArgument("must be a positive id", "parameter_set_id");
  }
  if (r.trial_id.has_value() == r.stimulus.has_value()) {
    return api::Status::InvalidArgument("give exactly one of trial_id and stimulus",
                                        r.trial_id ? "stimulus" : "trial_id");
  }
  if (r.trial_id && *r.trial_id <= 0) {
    return api::Status::InvalidArgument("must be a positive id", "trial_id");
  }
  if (r.fit_scale && !r.trial_id) {
    return api::Status::InvalidArgument("needs trial_id (an isometric trial to fit against)",
                                        "fit_scale");
  }
  if (r.trial_id) {
    for (const auto& [set, field] :
         {std::pair{r.initial_angle_deg.has_value(), "initial_angle_deg"},
          std::pair{r.initial_velocity_deg_s != 0.0, "initial_velocity_deg_s"},
          std::pair{r.duration_s.has_value(), "duration_s"}}) {
      if (set) {
        return api::Status::InvalidArgument(
            "not with trial_id: the trial's measured state and length are used", field);
      }
    }
  }
  if (r.stimulus) {
    const model::GeneratorDescription* g = model::FindStimulusGenerator(r.stimulus->generator);
    if (g == nullptr) {
      return api::Status::InvalidArgument(
          "unknown stimulus generator \"" + r.stimulus->generator + "\"", "stimulus.generator");
    }
    for (const auto& [name, value] : r.stimulus->params) {
      const std::string field = "stimulus.params." + name;
      const model::GeneratorParameter* p = g->FindParameter(name);
      if (p == nullptr) {
        return api::Status::InvalidArgument("not a parameter of " + g->name, field);
      }
      if (!InRange(value, p->min_value, p->max_value)) {
        char range[96];
        std::snprintf(range, sizeof range, " must be %.10g–%.10g, got %.10g", p->min_value,
                      p->max_value, value);
        return api::Status::InvalidArgument(name + range, field);
      }
      if (p->integer && value != std::floor(value)) {
        return api::Status::InvalidArgument("must be a whole number", field);
      }
    }
  }
  if (r.initial_angle_deg && !InRange(*r.initial_angle_deg, -30.0, 180.0)) {
    return api::Status::InvalidArgument(
        "initial_angle_deg must be −30–180 deg, got " + std::to_string(*r.initial_angle_deg),
        "initial_angle_deg");
  }
  if (!InRange(r.initial_velocity_deg_s, -2000.0, 2000.0)) {
    return api::Status::InvalidArgument("initial_velocity_deg_s must be -2000–2000 deg/s, got " +
                                            std::to_string(r.initial_velocity_deg_s),
                                        "initial_velocity_deg_s");
  }
  if (r.duration_s && !(std::isfinite(*r.duration_s) && *r.duration_s > 0.0 &&
                        *r.duration_s <= config.max_duration_s)) {
    return api::Status::InvalidArgument(
        "must be in (0, " + std::to_string(config.max_duration_s) + "] s", "duration_s");
  }
  return api::Status::Ok();
}

PredictionService::PredictionService(storage::Database& db, PredictionConfig config)
    : db_(db), config_(config) {}

namespace {

// A prediction's input, its mode and start, before the simulation. `stage`
// names what is being done, for the error of an exception thrown by a model
// function.
struct PredictionInput {
  model::SimulationOptions options;
  model::PulseTrain pulses;
  std::optional<model::TrialColumns> measured;  // with a trial: what it is compared with
  std::string stage = "stimulus";
  bool imported = false;  // the trial was recorded elsewhere (not on this bench)
  std::optional<model::JointLimits> imported_stops;  // the stops its spec declared
  std::optional<LoadedTrial> trial;                  // with a trial: the stored trial
};

// A stored trial's stimulation on the session's clock: its start relative to
// `origin_ms` (s) and its delivered pulses.
std::optional<model::StimulationRecord> StimulationOf(const api::Trial& t, std::int64_t origin_ms) {
  if (!t.start_time_unix_ms || !t.pulses) return std::nullopt;
  model::StimulationRecord r;
  r.start_s = static_cast<double>(*t.start_time_unix_ms - origin_ms) / 1000.0;
  r.pulses = t.pulses->Train();
  r.pulse_rate_hz = t.pulses->pulse_rate_hz;
  return r;
}

bool IsFreeSwing(const api::Trial& t) {
  if (!t.kind) return false;
  const api::TrialKindInfo& k = api::InfoOf(*t.kind);
  return !k.knee_locked && !k.motor;
}

// docs/MODEL.md, "The strength at a trial's start": the strength state at
// the stored trial's start from its session's earlier trials (their start
// times and delivered pulses, rested before the first), relative to the
// strength of the set's free-swing trials of that session (the trials its
// τ_scale was fitted to; 1 if none is in the session). Unset for a trial
// without a start time.
api::Result<std::optional<model::SimulationStrength>> SessionStrength(
    storage::Database& db, const model::StrengthParameters& parameters,
    const model::ParameterSet& params, const LoadedTrial& trial) {
  if (!trial.trial.start_time_unix_ms) return std::optional<model::SimulationStrength>();
  const std::int64_t origin = *trial.trial.start_time_unix_ms;
  storage::TrialRepository repo(db);
  api::Result<std::vector<storage::TrialSummary>> list = repo.ListForSession(trial.session_id);
  if (!list.ok()) return list.status();
  std::vector<model::StimulationRecord> history;
  std::vector<model::StimulationRecord> reference_trials;
  const std::vector<std::int64_t>& fitted = params.provenance.trial_ids;
  for (const storage::TrialSummary& summary : *list) {
    if (summary.id == trial.id) continue;
    api::Result<api::Trial> other = repo.Get(summary.id);
    if (!other.ok()) return other.status();
    std::optional<model::StimulationRecord> r = StimulationOf(*other, origin);
    if (!r) continue;
    if (IsFreeSwing(*other) && std::find(fitted.begin(), fitted.end(), summary.id) != fitted.end()) {
      reference_trials.push_back(*r);
    }
    history.push_back(std::move(*r));
  }
  const model::StrengthModel m(parameters);
  model::SimulationStrength out;
  out.parameters = parameters;
  out.initial = model::StrengthAtStart(m, params.irc, history, 0.0);
  double sum = 0.0, count = 0.0;
  for (const model::StimulationRecord& r : reference_trials) {
    const model::StrengthTrace trace(m, params.irc, r.pulses, r.pulse_rate_hz,
                                     model::StrengthAtStart(m, params.irc, history, r.start_s));
    if (const std::optional<double> w = trace.ActivationWeightedFactor()) sum += *w, count += 1.0;
  }
  if (count > 0.0) out.reference_factor = sum / count;
  return std::optional<model::SimulationStrength>(out);
}

// The angles a real knee takes, deg: hyperextension to −30°, flexion to 180°.
constexpr double kMinKneeAngleDeg = -30.0;
constexpr double kMaxKneeAngleDeg = 180.0;

// A stimulus from a generator (no trial): its pulses, length and start.
api::Status PrepareFromStimulus(const PredictionRequest& request, const PredictionConfig& config,
                                const model::ParameterSet& params, PredictionInput& in,
                                PredictionResult& out) {
  const model::SampledSignal env =
      model::MakeStimulus(request.stimulus->generator, request.stimulus->params);
  const double duration = request.duration_s.value_or(env.EndTime());
  if (duration > config.max_duration_s) {
    return api::Status::InvalidArgument("the stimulus lasts " + std::to_string(duration) +
                                            " s, over the " +
                                            std::to_string(config.max_duration_s) + " s limit",
                                        "stimulus");
  }
  in.pulses = protocols::EnvelopePulses(env, config.pulse_rate_hz);
  in.options.duration_s = duration;
  in.options.output_rate_hz = config.output_rate_hz;
  out.mode = request.mode.value_or(PredictionMode::kFreeSwing);
  if (out.mode == PredictionMode::kIsometric) {
    out.initial_angle_deg = request.initial_angle_deg.value_or(model::kReferenceAngleDeg);
  } else if (request.initial_angle_deg) {
    out.initial_angle_deg = *request.initial_angle_deg;
  } else {
    out.initial_angle_deg = protocols::FreeSwingStartAngleDeg(params);
  }
  out.initial_velocity_deg_s = request.initial_velocity_deg_s;
  return api::Status::Ok();
}

// A stored trial: its stored pulses replayed (docs/MODEL.md, pulse timing), its length, its
// measured start, and the columns the prediction is judged against. A trial
// whose knee is locked (by its kind, or an angle that does not move) is
// predicted isometrically.
api::Status PrepareFromTrial(storage::Database& db, const PredictionRequest& request,
                             const PredictionConfig& config, PredictionInput& in,
                             PredictionResult& out) {
  api::Result<LoadedTrial> trial = LoadTrial(db, *request.trial_id);
  if (!trial.ok()) return trial.status();
  const std::string name = trial->trial.name.value_or("");
  if (trial->trial.kind && api::InfoOf(*trial->trial.kind).motor) {
    return api::Status::FailedPrecondition(
        "trial " + std::to_string(trial->id) + " (\"" + name +
        "\") is a motor trial; predictions replay free-swing or isometric trials");
  }
  model::TrialColumns c = api::ToTrialColumns(trial->trial);
  // A passive free swing (a pendulum test) has no stimulation to record:
  // its stimulation is zero throughout.
  const bool passive = trial->trial.kind == api::TrialKind::kFreeSwingPassive ||
                       trial->trial.kind == api::TrialKind::kPendulum;
  if (passive && c.stim_ma.empty() && !trial->trial.pulses) c.stim_ma.assign(c.size(), 0.0);
  if (c.size() < 2 || c.angle_deg.size() != c.size() || c.stim_ma.size() != c.size()) {
    return api::Status::FailedPrecondition(
        "trial " + std::to_string(trial->id) +
        " needs t_s, stim_ma and angle_deg channels (an imported recording of a stimulated "
        "trial maps its stimulation column to stim_ma)");
  }
  // A pendulum test is held until the examiner lets go: it is predicted,
  // and judged, from the release on (the hold's torque is not the knee's).
  if (passive && std::all_of(c.stim_ma.begin(), c.stim_ma.end(), [](double u) { return u == 0.0; })) {
    const std::size_t release = model::PendulumReleaseIndex(c.t_s, c.angle_deg);
    if (release > 0 && c.size() - release >= 2) {
      // The velocity at the release from the whole recording (§5.1), not
      // from the edge of the part kept.
      if (c.velocity_deg_s.size() != c.size()) {
        c.velocity_deg_s = model::GcvSmoothingSpline(c.t_s, c.angle_deg).first;
      }
      out.released_at_s = c.t_s[release] - c.t_s.front();
      c = model::TrialFromSample(c, release);
    }
  }
  api::Result<std::optional<storage::TrialImport>> provenance =
      storage::TrialRepository(db).ImportOf(trial->id);
  if (!provenance.ok()) return provenance.status();
  in.imported = provenance->has_value();
  if (in.imported) {
    api::Result<api::ImportSpec> spec =
        api::ImportSpecFromJson(nlohmann::json::parse((*provenance)->spec_json, nullptr, false));
    if (spec.ok() && spec->stops_deg) {
      in.imported_stops = model::JointLimits{spec->stops_deg->first, spec->stops_deg->second};
    }
  }
  const double rate = trial->trial.sample_rate_hz;
  const double span = c.t_s.back() - c.t_s.front();
  if (span > config.max_duration_s) {
    return api::Status::InvalidArgument("trial lasts " + std::to_string(span) + " s, over the " +
                                            std::to_string(config.max_duration_s) + " s limit",
                                        "trial_id");
  }
  const auto [lo, hi] = std::minmax_element(c.angle_deg.begin(), c.angle_deg.end());
  const bool locked = (trial->trial.kind && api::InfoOf(*trial->trial.kind).knee_locked) || (*hi - *lo) < 0.5;
  out.mode = request.mode.value_or(locked ? PredictionMode::kIsometric : PredictionMode::kFreeSwing);
  if (request.fit_scale && out.mode != PredictionMode::kIsometric) {
    return api::Status::InvalidArgument("isometric predictions only (trial " +
                                            std::to_string(trial->id) +
                                            " is predicted in free swing)",
                                        "fit_scale");
  }
  if (out.mode == PredictionMode::kIsometric && c.torque_nm.size() != c.size()) {
    return api::Status::FailedPrecondition("trial " + std::to_string(trial->id) +
                                           " has no torque_nm channel to compare");
  }
  in.stage = "trial stimulation";
  in.pulses = TrialStimulation(trial->trial, c, config.pulse_rate_hz, in.options.pulse_rate_hz);
  const std::size_t n = c.size();
  in.options.output_rate_hz = rate;
  in.options.duration_s = std::max((static_cast<double>(n) + 0.5) / rate, span + 1.5 / rate);
  if (out.mode == PredictionMode::kIsometric) {
    double sum = 0.0;
    for (double a : c.angle_deg) sum += a;
    out.initial_angle_deg = sum / static_cast<double>(n);
  } else {
    out.initial_angle_deg = c.angle_deg.front();
    if (c.velocity_deg_s.size() == n) {
      out.initial_velocity_deg_s = c.velocity_deg_s.front();
    } else {
      in.stage = "initial velocity (GCV spline, §5.1)";
      out.initial_velocity_deg_s = model::GcvSmoothingSpline(c.t_s, c.angle_deg).first.front();
    }
  }
  in.measured = std::move(c);
  in.trial = std::move(trial).value();
  return api::Status::Ok();
}

// The start inside 0–180°, and a free swing inside the bench's stops (a
// measured start a sensor-noise step past a stop is at the stop; a requested
// one outside is refused).
api::Status ApplyStartAndStops(const PredictionRequest& request, const PredictionConfig& config,
                               PredictionInput& in, PredictionResult& out) {
  if (!InRange(out.initial_angle_deg, kMinKneeAngleDeg, kMaxKneeAngleDeg)) {
    return api::Status::InvalidArgument(
        "initial angle " + std::to_string(out.initial_angle_deg) + " deg is outside −30–180",
        request.trial_id ? "trial_id" : "initial_angle_deg");
  }
  // The stops of the bench that recorded the trial: this bench's for its own
  // trials and for stimuli; none for a recording made elsewhere, where the
  // passive end-range stiffness stops the swing as the knee's own does.
  const std::optional<model::JointLimits> bench_stops =
      in.imported ? in.imported_stops : config.joint_limits;
  if (out.mode == PredictionMode::kFreeSwing && bench_stops) {
    const model::JointLimits& stops = *bench_stops;
    if (request.trial_id) {
      out.initial_angle_deg =
          std::clamp(out.initial_angle_deg, stops.min_angle_deg, stops.max_angle_deg);
    } else if (out.initial_angle_deg < stops.min_angle_deg ||
               out.initial_angle_deg > stops.max_angle_deg) {
      return api::Status::InvalidArgument(
          "initial angle " + std::to_string(out.initial_angle_deg) +
              " deg is outside the range of motion " + std::to_string(stops.min_angle_deg) + "-" +
              std::to_string(stops.max_angle_deg) + " deg",
          "initial_angle_deg");
    }
    in.options.joint_limits = stops;
    out.joint_limits = stops;
  }
  in.options.initial_angle_deg = out.initial_angle_deg;
  in.options.initial_velocity_deg_s = out.initial_velocity_deg_s;
  return api::Status::Ok();
}

// The prediction against the measured trial (Eqs. 6.1, 6.2, 6.9, 6.10), with
// the §6.1.2 scale fitted first when asked.
api::Status CompareWithTrial(const PredictionRequest& request, const PredictionConfig& config,
                             const PredictionInput& in, PredictionResult& out) {
  const model::TrialColumns& c = *in.measured;
  const bool iso = out.mode == PredictionMode::kIsometric;
  model::SampledSignal sim;
  sim.rate_hz = in.options.output_rate_hz;
  sim.values = iso ? out.predicted.torque_nm : out.predicted.angle_deg;
  std::vector<double> at(c.size()), data(c.size());
  const double offset = iso ? MeasuredOffset(c) : 0.0;
  for (std::size_t i = 0; i < c.size(); ++i) {
    at[i] = sim.InterpolateAt(c.t_s[i] - c.t_s.front());
    data[i] = iso ? c.torque_nm[i] - offset : c.angle_deg[i];
  }
  if (request.fit_scale) {
    // §6.1.2: the constant k minimising Σ(k·prediction − data)².
    double pd = 0.0, pp = 0.0;
    for (std::size_t i = 0; i < at.size(); ++i) pd += at[i] * data[i], pp += at[i] * at[i];
    if (!(pp > 0.0)) {
      return api::Status::FailedPrecondition(
          "fit_scale: the predicted torque is zero throughout, no scale fits");
    }
    const double k = pd / pp;
    for (double& v : at) v *= k;
    for (double& v : out.predicted.torque_nm) v *= k;
    out.fitted_scale = k;
  }
  out.errors = Errors(at, data, iso, config.normalised_exclude_fraction);
  return api::Status::Ok();
}

}  // namespace

api::Result<PredictionResult> PredictionService::Compute(const PredictionRequest& request) const {
  if (api::Status s = ValidatePredictionRequest(request, config_); !s.ok()) return s;
  api::Result<storage::StoredParameterSet> set =
      storage::ParameterSetRepository(db_).Get(request.parameter_set_id);
  if (!set.ok()) return set.status();
  const model::ParameterSet& params = set->params;

  PredictionResult out;
  out.parameter_set_id = request.parameter_set_id;
  out.trial_id = request.trial_id;
  out.model = std::string(model::ModelKindName(params.model));

  PredictionInput in;
  in.options.pulse_rate_hz = config_.pulse_rate_hz;
  const auto predict = [&]() -> api::Result<PredictionResult> {
    api::Status prepared = request.stimulus
                               ? PrepareFromStimulus(request, config_, params, in, out)
                               : PrepareFromTrial(db_, request, config_, in, out);
    if (!prepared.ok()) return prepared;
    // A passive-only set (docs/MODEL.md) has no IRC or active curves: it
    // would predict a stimulated knee as if nothing stimulated it.
    if (model::IsPassiveOnly(params) &&
        std::any_of(in.pulses.begin(), in.pulses.end(),
                    [](const model::Pulse& p) { return p.stim_ma > 0.0; })) {
      return api::Status::FailedPrecondition(
          "parameter set " + std::to_string(request.parameter_set_id) +
          " is passive only (identified from unstimulated swings: no IRC, contraction dynamics "
          "or active curves); it predicts swings without stimulation, and this " +
          std::string(request.stimulus ? "stimulus" : "trial") + " stimulates");
    }
    if (api::Status st = ApplyStartAndStops(request, config_, in, out); !st.ok()) return st;
    if (config_.strength && in.trial && !in.imported) {
      in.stage = "strength at the trial's start";
      api::Result<std::optional<model::SimulationStrength>> strength =
          SessionStrength(db_, *config_.strength, params, *in.trial);
      if (!strength.ok()) return strength.status();
      if (*strength) {
        // The pulses' times are the trial's own from its first sample; a
        // pendulum test's release does not stimulate.
        in.options.strength = **strength;
        out.strength_at_start = model::StrengthFactor((*strength)->initial) /
                                (*strength)->reference_factor;
      }
    }
    in.stage = "simulation";
    out.predicted =
        out.mode == PredictionMode::kIsometric
            ? model::SimulateIsometric(params, in.pulses, out.initial_angle_deg, in.options)
            : protocols::SimulateStimulatedSwing(params, in.pulses, in.options);
    if (out.mode == PredictionMode::kFreeSwing) {
      // Where the prediction leans on extrapolated curves (docs/MODEL.md, "Extrapolation").
      out.share_outside_identified_ranges = model::ShareOutsideIdentifiedRanges(
          params.provenance, out.predicted.angle_deg, out.predicted.velocity_deg_s);
    }
    if (out.mode == PredictionMode::kIsometric && !out.predicted.torque_nm.empty()) {
      // The torque before any activation is the offset the bench removes (§5.3).
      const double offset = out.predicted.torque_nm.front();
      for (double& v : out.predicted.torque_nm) v -= offset;
    }
    if (in.measured) {
      in.stage = "errors";
      if (api::Status st = CompareWithTrial(request, config_, in, out); !st.ok()) return st;
    }
    return out;
  };
  api::Result<api::Result<PredictionResult>> computed = api::CallModel(predict);
  if (!computed.ok()) {
    // What the model refuses in the simulation or the comparison is a
    // failed precondition of the stored set; before them, of the request.
    const bool of_the_set = in.stage == "simulation" || in.stage == "errors";
    return api::Status(of_the_set ? api::ErrorCode::kFailedPrecondition : computed.status().code(),
                       std::string(in.stage) + ": " + computed.status().message());
  }
  return std::move(computed).value();
}

api::Result<PredictionResult> PredictionService::Predict(const Actor& actor,
                                                         const PredictionRequest& request) {
  // Clinicians too: the model check of a set on fresh trials (docs/API.md).
  if (api::Status s = Require(actor, Permission::kPredict, "a prediction"); !s.ok()) return s;
  api::Result<PredictionResult> computed = Compute(request);
  if (!computed.ok()) return computed.status();
  PredictionResult result = std::move(computed).value();
  try {
    const std::string input = api::PredictionRequestToJson(request).dump();
    const std::string output = PredictionResultToJson(result).dump();
    api::Status stored = db_.Write([&](storage::Connection&) -> api::Status {
      storage::PredictionRepository repo(db_);
      storage::NewPrediction p;
      p.parameter_set_id = request.parameter_set_id;
      p.trial_id = request.trial_id;
      p.input_json = input;
      p.output_json = output;
      api::Result<storage::Prediction> pred = repo.InsertPrediction(p);
      if (!pred.ok()) return pred.status();
      result.prediction_id = pred->id;
      result.evaluation_id.reset();
      std::string target = "predictions/" + std::to_string(pred->id);
      if (result.errors) {
        const PredictionErrors& e = *result.errors;
        storage::NewEvaluation ev;
        ev.parameter_set_id = request.parameter_set_id;
        ev.trial_id = *request.trial_id;
        ev.prediction_id = pred->id;
        ev.channel = e.channel;
        ev.unit = e.unit;
        ev.rms_error = e.e_rms;
        ev.max_abs_error = e.max_abs;
        ev.details_json = PredictionErrorsToJson(e).dump();
        api::Result<storage::Evaluation> eval = repo.InsertEvaluation(ev);
        if (!eval.ok()) return eval.status();
        result.evaluation_id = eval->id;
        target += ",evaluations/" + std::to_string(eval->id);
      }
      storage::NewAuditEntry entry;
      if (actor.user_id > 0) entry.user_id = actor.user_id;
      entry.actor = actor.user_name;
      entry.action = "prediction.create";
      entry.target = target;
      nlohmann::json summary = {{"parameter_set_id", request.parameter_set_id},
                                {"mode", PredictionModeName(result.mode)}};
      if (request.trial_id) summary["trial_id"] = *request.trial_id;
      if (request.stimulus) summary["generator"] = request.stimulus->generator;
      entry.request_summary = summary.dump();
      entry.outcome = "ok";
      api::Result<std::int64_t> audit = storage::AuditLog(db_).Append(entry);
      return audit.ok() ? api::Status::Ok() : audit.status();
    });
    if (!stored.ok()) return stored;
  } catch (const std::exception& e) {
    return api::Status::Internal(std::string("storing the prediction: ") + e.what());
  }
  return result;
}

}  // namespace fesbench::server::services
