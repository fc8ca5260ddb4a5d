#include "server/protocols/tolerance_detector.h"

#include <algorithm>
#include <cstdio>
#include <string>

namespace fesbench::server::protocols {

void ToleranceDetector::SetOffsetNoise(double offset_sd_nm) {
  result_.noise_band_nm = std::max(settings_.threshold_torque_nm, 4.0 * offset_sd_nm);
}

void ToleranceDetector::Sample(double torque_nm, double applied_ma) {
  window_.push_back(torque_nm);
  sum_ += torque_nm;
  if (window_.size() > kWindow) {
    sum_ -= window_.front();
    window_.pop_front();
  }
  const double mean = sum_ / static_cast<double>(window_.size());
  result_.max_torque_nm = std::max(result_.max_torque_nm, mean);
  if (!result_.threshold_ma && window_.size() == kWindow && mean > result_.noise_band_nm) {
    result_.threshold_ma = applied_ma;
  }
  result_.max_tolerated_ma = applied_ma;
}

ToleranceResult ToleranceDetector::Finish() const {
  ToleranceResult out = result_;
  if (out.max_torque_nm < settings_.min_torque_at_max_nm) {
    char text[96];
    std::snprintf(text, sizeof text, "torque at max below the %g N·m of Appendix F part II.K.3",
                  settings_.min_torque_at_max_nm);
    out.warnings.push_back(text);
  }
  if (!out.threshold_ma) out.warnings.push_back("no torque response above the noise band");
  return out;
}

}  // namespace fesbench::server::protocols
