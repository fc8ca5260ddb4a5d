#pragma once

/// @file
/// Helpers shared by the analysis services: stored trials as identification
/// columns with the subject and leg they belong to, and the one place where
/// an exception from model/ becomes a Status (nothing throws past a service).

#include <cstdint>
#include <exception>
#include <string>
#include <string_view>

#include "api/status.h"
#include "api/trial.h"
#include "model/identify_common.h"
#include "storage/database.h"

namespace fesbench::server::services {

/// A stored trial with its owner.
struct LoadedTrial {
  std::int64_t id = 0;
  std::int64_t session_id = 0;
  std::int64_t subject_id = 0;
  std::int64_t leg_id = 0;
  api::Trial trial;
};

/// Loads trial `trial_id` and its session's subject and leg, in one read
/// transaction. kNotFound ("trial <id>") for an unknown trial.
api::Result<LoadedTrial> LoadTrial(storage::Database& db, std::int64_t trial_id);

/// The Status for an exception thrown by model code during `what`:
/// std::invalid_argument (broken precondition: bad data or options) →
/// `invalid_code`, anything else (e.g. a diverging integration) →
/// kFailedPrecondition. The message is "<what>: <e.what()>".
api::Status ModelFailure(std::string_view what, const std::exception& e,
                         api::ErrorCode invalid_code);

}  // namespace fesbench::server::services
