#include "model/identify_common.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "model/conditioning.h"

namespace fesbench::model {

std::string_view IdentificationMethodName(IdentificationMethod method) {
  switch (method) {
    case IdentificationMethod::kThesis:
      return "thesis";
    case IdentificationMethod::kRapid:
      return "rapid";
    case IdentificationMethod::kPassive:
      return "passive";
  }
  return "unknown";
}

std::optional<IdentificationMethod> IdentificationMethodFromName(std::string_view name) {
  for (IdentificationMethod m : kIdentificationMethods) {
    if (IdentificationMethodName(m) == name) return m;
  }
  return std::nullopt;
}

double TrialColumns::SampleRateHz() const {
  if (t_s.size() < 2) throw std::invalid_argument("trial: need at least 2 samples for a rate");
  const double span = t_s.back() - t_s.front();
  if (!(span > 0.0) || !std::isfinite(span)) {
    throw std::invalid_argument("trial: t_s must increase");
  }
  return static_cast<double>(t_s.size() - 1) / span;
}

void RequireColumn(const char* what, const char* column, std::span<const double> values,
                   std::size_t n) {
  if (values.size() != n) {
    throw std::invalid_argument(std::string(what) + ": wrong argument size: column " + column +
                                " expected " + std::to_string(n) + " samples, got " +
                                std::to_string(values.size()));
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (!std::isfinite(values[i])) {
      throw std::invalid_argument(std::string(what) + ": column " + column +
                                  " has a non-finite value at sample " + std::to_string(i));
    }
  }
}

std::vector<double> ResolveBreakpoints(const BreakpointSpec& spec, std::span<const double> x) {
  if (!spec.explicit_x.empty()) {
    for (std::size_t i = 1; i < spec.explicit_x.size(); ++i) {
      if (!(spec.explicit_x[i] > spec.explicit_x[i - 1])) {
        throw std::invalid_argument("breakpoints: explicit breakpoints not strictly increasing");
      }
    }
    return spec.explicit_x;
  }
  if (spec.count < 2) throw std::invalid_argument("breakpoints: count must be at least 2");
  if (x.empty()) throw std::invalid_argument("breakpoints: no data to place breakpoints on");
  const auto [lo_it, hi_it] = std::minmax_element(x.begin(), x.end());
  const double lo = *lo_it, hi = *hi_it;
  if (!(hi > lo)) throw std::invalid_argument("breakpoints: the data do not vary");
  std::vector<double> bp(static_cast<std::size_t>(spec.count));
  const double dx = (hi - lo) / static_cast<double>(spec.count - 1);
  for (std::size_t i = 0; i < bp.size(); ++i) bp[i] = lo + dx * static_cast<double>(i);
  bp.back() = hi;
  return bp;
}

void IdentifyReport::Merge(const IdentifyReport& other) {
  for (const auto& [k, v] : other.fit_rms) fit_rms[k] = v;
  for (const auto& [k, v] : other.values) values[k] = v;
  warnings.insert(warnings.end(), other.warnings.begin(), other.warnings.end());
}

PulseTrain TrialPulses(const TrialColumns& trial, double pulse_rate_hz) {
  const std::size_t n = trial.t_s.size();
  if (n < 2) throw std::invalid_argument("TrialPulses: t_s needs at least 2 samples");
  RequireColumn("TrialPulses", "stim_ma", trial.stim_ma, n);
  if (!(pulse_rate_hz > 0.0)) throw std::invalid_argument("TrialPulses: pulse_rate_hz must be > 0");
  SampledSignal env;
  env.rate_hz = trial.SampleRateHz();
  env.t0_s = 0.0;
  env.values = trial.stim_ma;
  return PulsesFromEnvelope(env, pulse_rate_hz);
}

void AddKinematics(TrialColumns& trial) {
  std::vector<double> t(trial.t_s.size());
  for (std::size_t i = 0; i < t.size(); ++i) t[i] = trial.t_s[i] - trial.t_s.front();
  const SmoothingSplineFit fit = GcvSmoothingSpline(t, trial.angle_deg);
  trial.velocity_deg_s = fit.first;
  trial.accel_deg_s2 = fit.second;
}

}  // namespace fesbench::model
