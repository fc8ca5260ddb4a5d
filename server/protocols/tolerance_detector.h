#pragma once

/// @file
/// The tolerance test's measurement (Appendix F part II.K): while the
/// amplitude ramps, the first amplitude whose 50 ms mean torque (10 samples
/// at 200 Hz, offset removed) leaves the offset's noise band is the
/// threshold; the amplitude when the clinician stops (or the ceiling) is the
/// max tolerated; a largest mean torque below the II.K.3 minimum is warned.

#include <cstddef>
#include <deque>

#include "server/protocols/plan.h"
#include "server/protocols/runner.h"

namespace fesbench::server::protocols {

class ToleranceDetector {
 public:
  explicit ToleranceDetector(const ToleranceSettings& settings) : settings_(settings) {}

  /// The noise band from the offset window's standard deviation:
  /// max(threshold_torque_nm, 4 σ).
  void SetOffsetNoise(double offset_sd_nm);
  /// One recorded sample of the ramp: offset-corrected torque and the
  /// amplitude applied.
  void Sample(double torque_nm, double applied_ma);
  void MarkStoppedByClinician() { result_.stopped_by_clinician = true; }

  /// What was measured so far (no warnings).
  const ToleranceResult& current() const { return result_; }
  /// The outcome, with its warnings.
  ToleranceResult Finish() const;

 private:
  static constexpr std::size_t kWindow = 10;  // 50 ms at 200 Hz
  ToleranceSettings settings_;
  ToleranceResult result_;
  std::deque<double> window_;
  double sum_ = 0.0;
};

}  // namespace fesbench::server::protocols
