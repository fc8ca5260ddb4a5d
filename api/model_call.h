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
#include <utility>

#include "api/status.h"

namespace fesbench::api {

/// What CallModel returns for a call returning R: Status for void, else
/// Result<R>.
template <typename R>
using ModelCallResult = std::conditional_t<std::is_void_v<R>, Status, Result<R>>;

/// Runs `call` (a call into model/) and returns its value, or
/// kInvalidArgument with the exception's message (and `field`, the input it
/// concerns, if given) when the model throws std::invalid_argument. Any
/// other exception is a bug and passes through.
template <typename F>
auto CallModel(F&& call, std::string field = {}) -> ModelCallResult<std::invoke_result_t<F>> {
  using R = std::invoke_result_t<F>;
  try {
    if constexpr (std::is_void_v<R>) {
      std::invoke(std::forward<F>(call));
      return Status::Ok();
    } else {
      return Result<R>(std::invoke(std::forward<F>(call)));
    }
  } catch (const std::invalid_argument& e) {
    return Status::InvalidArgument(e.what(), std::move(field));
  }
}

}  // namespace fesbench::api
