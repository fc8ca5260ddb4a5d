#pragma once

/// @file
/// The parameter makers the catalogue's protocol classes share
/// (docs/PROTOCOLS.md, "Parameters"): a parameter's default and limits in
/// its unit, and the parameters several protocols have (Appendix F: the
/// clinician sets the maximum to the subject's tolerance and the minimum
/// from threshold).

#include <string>
#include <utility>
#include <vector>

#include "server/protocols/protocol.h"

namespace fesbench::server::protocols::catalog {

// A parameter's default and inclusive limits, in its unit.
struct Range {
  double value = 0.0;
  double min = 0.0;
  double max = 0.0;
};

// A real-valued parameter (its default as `scaling` says).
inline ParameterSpec Number(std::string name, std::string description, Range range,
                            Scaling scaling = Scaling::kNone) {
  return {.name = std::move(name),
          .description = std::move(description),
          .default_value = range.value,
          .min_value = range.min,
          .max_value = range.max,
          .scaling = scaling};
}
// A whole number (counts, seeds).
inline ParameterSpec Count(std::string name, std::string description, Range range) {
  ParameterSpec p = Number(std::move(name), std::move(description), range);
  p.integer = true;
  return p;
}
// A choice among names: the index of the default name, 0 … n − 1.
inline ParameterSpec Choice(std::string name, std::string description, int default_index,
                            std::vector<std::string> choices) {
  ParameterSpec p = Count(std::move(name), std::move(description),
                          {.value = static_cast<double>(default_index),
                           .min = 0.0,
                           .max = static_cast<double>(choices.size()) - 1.0});
  p.choices = std::move(choices);
  return p;
}
// A rest period (never shorter than the protocol's min_rest_s).
inline ParameterSpec Rest(std::string name, std::string description, Range range) {
  ParameterSpec p = Number(std::move(name), std::move(description), range);
  p.is_rest = true;
  return p;
}

// `spec` with the protocol's own words for it (ParameterSpec::label).
inline ParameterSpec WithLabel(ParameterSpec spec, std::string label) {
  spec.label = std::move(label);
  return spec;
}

// Parameters shared by several protocols (Appendix F: the clinician sets
// the maximum to the subject's tolerance and the minimum from threshold).
inline ParameterSpec ThresholdMa() {
  return Number("threshold_ma", "subject's stimulation threshold for torque, mA",
                {.value = 20.0, .min = 0.0, .max = 100.0}, Scaling::kThreshold);
}
inline ParameterSpec MaxMa() {
  return Number("max_ma", "maximum stimulation (the subject's max tolerated), mA",
                {.value = 45.0, .min = 1.0, .max = 100.0}, Scaling::kMaxTolerated);
}
inline ParameterSpec LockAngleDeg() {
  return Number("lock_angle_deg", "knee angle the brace is locked at, deg",
                {.value = 90.0, .min = 10.0, .max = 110.0});
}
inline ParameterSpec SettleS(double default_s, const char* what) {
  return Number("settle_s", what, {.value = default_s, .min = 0.2, .max = 30.0});
}
inline ParameterSpec AmplitudeMa(double fraction) {
  return Number("amplitude_ma",
                "random-binary ON amplitude (the lowest level giving full extension, §5.4.3); "
                "default a fraction of threshold→max",
                {.value = fraction, .min = 0.0, .max = 100.0}, Scaling::kStimRange);
}

}  // namespace fesbench::server::protocols::catalog
