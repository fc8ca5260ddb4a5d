#pragma once

/// @file
/// Shared types of the identification methods (thesis ch. 4, §5.3–5.4;
/// docs/MODEL.md): the columns of one recorded trial, breakpoint choices for
/// piecewise-linear fits, and the report every method returns.

#include <array>
#include <cstddef>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "model/signal.h"

namespace fesbench::model {

/// The identification routines (docs/MODEL.md): the chapter 4 methods
/// (kThesis, each block by its own trials and method), the rapid routine of
/// §7.4.1 (kRapid) and the passive block alone from unstimulated free swings,
/// e.g. a pendulum test (kPassive).
enum class IdentificationMethod { kThesis, kRapid, kPassive };
/// Every identification method, in declaration order.
inline constexpr std::array<IdentificationMethod, 3> kIdentificationMethods = {
    IdentificationMethod::kThesis, IdentificationMethod::kRapid, IdentificationMethod::kPassive};

/// "thesis", "rapid", "passive".
std::string_view IdentificationMethodName(IdentificationMethod method);
/// The method called `name` (IdentificationMethodName's words), or nullopt.
std::optional<IdentificationMethod> IdentificationMethodFromName(std::string_view name);

/// The channels of one trial as plain columns, all sampled at the same
/// instants t_s (docs/ARCHITECTURE.md, units). A column the trial did not record is empty;
/// each method documents which columns it needs and throws
/// std::invalid_argument if one is missing or of the wrong length.
struct TrialColumns {
  std::vector<double> t_s;             ///< sample times, s, strictly increasing.
  std::vector<double> stim_ma;         ///< stimulation envelope, mA (≥ 0).
  std::vector<double> angle_deg;       ///< knee flexion, deg.
  std::vector<double> velocity_deg_s;  ///< deg/s.
  std::vector<double> accel_deg_s2;    ///< deg/s².
  std::vector<double> torque_nm;       ///< brace torque, N·m, + flexion.
  std::vector<double> activation;      ///< f_stim(t), dimensionless (computed).
  std::vector<double> emg;             ///< EMG, arbitrary units.

  std::size_t size() const { return t_s.size(); }
  /// Mean sample rate 1 / mean(Δt), Hz.
  /// @throws std::invalid_argument if fewer than 2 samples or t_s is not
  ///   strictly increasing at its ends.
  double SampleRateHz() const;
};

/// Throws std::invalid_argument naming `what` and `column` unless `values`
/// has exactly `n` entries, all finite.
void RequireColumn(const char* what, const char* column, std::span<const double> values,
                   std::size_t n);

/// Breakpoints of one piecewise-linear curve to be fitted: either explicit
/// (non-empty `explicit_x`, strictly increasing) or `count` breakpoints
/// spread evenly over the range the data visit.
struct BreakpointSpec {
  int count = 11;
  std::vector<double> explicit_x;
};

/// The breakpoints `spec` asks for, given the data abscissae x.
/// @throws std::invalid_argument if count < 2 with no explicit breakpoints,
///   the explicit breakpoints are not strictly increasing, or x is empty or
///   constant while count is used.
std::vector<double> ResolveBreakpoints(const BreakpointSpec& spec, std::span<const double> x);

/// What an identification reports besides the parameters: fit residuals
/// (per fitted part, in that part's unit), numerical rank, phase-plane
/// coverage and human-readable warnings (e.g. under-determined fits).
struct IdentifyReport {
  std::map<std::string, double> fit_rms;
  std::map<std::string, double> values;  ///< other figures (rank, delay_s, …).
  std::vector<std::string> warnings;
  /// Appends the other report's entries (its keys win on collision).
  void Merge(const IdentifyReport& other);
};

/// The stimulator's pulses for a trial's stim_ma envelope (200 Hz samples
/// held, PulsesFromEnvelope), times relative to t_s[0].
/// @throws std::invalid_argument if t_s has fewer than 2 samples, the
///   columns differ in length, or the pulse rate is not > 0.
PulseTrain TrialPulses(const TrialColumns& trial, double pulse_rate_hz);

/// Fills velocity_deg_s and accel_deg_s2 from angle_deg by a GCV cubic
/// smoothing spline (GcvSmoothingSpline, §5.1).
/// @throws std::invalid_argument as GcvSmoothingSpline.
void AddKinematics(TrialColumns& trial);

}  // namespace fesbench::model
