#include "model/integrators.h"

namespace fesbench::model {

std::string_view IntegratorKindName(IntegratorKind kind) {
  switch (kind) {
    case IntegratorKind::kRk4:
      return "rk4";
    case IntegratorKind::kAdaptive:
      return "adaptive";
  }
  return "unknown";
}

std::optional<IntegratorKind> ParseIntegratorKind(std::string_view name) {
  if (name == "rk4") return IntegratorKind::kRk4;
  if (name == "adaptive") return IntegratorKind::kAdaptive;
  return std::nullopt;
}

namespace {

void RequirePositive(double v, const char* field) {
  if (!std::isfinite(v) || !(v > 0.0)) {
    throw std::invalid_argument(std::string(field) + " must be finite and > 0");
  }
}

}  // namespace

void ValidateTolerances(const AdaptiveTolerances& tol) {
  RequirePositive(tol.rtol, "tolerances.rtol");
  RequirePositive(tol.atol, "tolerances.atol");
  RequirePositive(tol.min_step_s, "tolerances.min_step_s");
  RequirePositive(tol.max_step_s, "tolerances.max_step_s");
  if (tol.max_step_s < tol.min_step_s) {
    throw std::invalid_argument("tolerances.max_step_s must be >= tolerances.min_step_s");
  }
  if (tol.max_steps <= 0) throw std::invalid_argument("tolerances.max_steps must be > 0");
}

void ValidateIntegratorSettings(const IntegratorSettings& settings) {
  RequirePositive(settings.step_s, "step_s");
  ValidateTolerances(settings.tolerances);
}

}  // namespace fesbench::model
