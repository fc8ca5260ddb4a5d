#pragma once

/// @file
/// The one place an exception from model/ becomes a Status (docs/ARCHITECTURE.md,
/// "Errors"). The model reports input it cannot take — too few samples, a
/// parameter out of its domain — by throwing std::invalid_argument; every
/// caller outside model/ runs the call through CallModel and gets
/// api::Status or api::Result back, so nothing throws past a boundary.

#include <exception>
#include <functional>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <typeinfo>
#include <utility>

#include "api/status.h"

namespace fesbench::api {

/// What CallModel returns for a call returning R: Status for void, else
/// Result<R>.
template <typename R>
using ModelCallResult = std::conditional_t<std::is_void_v<R>, Status, Result<R>>;

/// Runs `call` (a call into model/) and returns its value, or what the
/// model reported as a Status with the exception's message:
///  - std::invalid_argument (input the model cannot take) → `refused`
///    (kInvalidArgument unless the caller says what a refusal means for it,
///    e.g. kFailedPrecondition for stored trials a fit cannot use), with
///    `field`, the input it concerns, if given;
///  - std::runtime_error itself (a computation that could not finish, e.g.
///    an integration that diverged, model/integrators.h) → kFailedPrecondition.
/// Any other exception (a subclass of std::runtime_error included) is not
/// the model's report and passes through.
template <typename F>
auto CallModel(F&& call, std::string field = {}, ErrorCode refused = ErrorCode::kInvalidArgument)
    -> ModelCallResult<std::invoke_result_t<F>> {
  using R = std::invoke_result_t<F>;
  try {
    if constexpr (std::is_void_v<R>) {
      std::invoke(std::forward<F>(call));
      return Status::Ok();
    } else {
      return Result<R>(std::invoke(std::forward<F>(call)));
    }
  } catch (const std::invalid_argument& e) {
    return Status(refused, e.what(), std::move(field));
  } catch (const std::runtime_error& e) {
    // The model's own, not a caller's subclass passing through the call
    // (e.g. a command line's usage error).
    if (typeid(e) != typeid(std::runtime_error)) throw;
    return Status(ErrorCode::kFailedPrecondition, e.what());
  }
}

}  // namespace fesbench::api
