#pragma once

/// @file
/// How an exception from model code becomes a Status for the analysis
/// services (identification, prediction).

#include <exception>
#include <string_view>

#include "api/status.h"

namespace fesbench::server::services {

/// The Status for an exception thrown by model code during `what`:
/// std::invalid_argument (broken precondition: bad data or options) →
/// `invalid_code`, anything else (e.g. a diverging integration) →
/// kFailedPrecondition. The message is "<what>: <e.what()>".
api::Status ModelFailure(std::string_view what, const std::exception& e,
                         api::ErrorCode invalid_code);

}  // namespace fesbench::server::services
