#pragma once

/// @file
/// Exports of stored records for analysts: a trial as CSV or as an OpenSim
/// Storage (.sto) time series (api/trial.h writers), a parameter set as its
/// JSON wire form. kNotFound for an unknown id.

#include <cstdint>
#include <string>

#include "api/status.h"
#include "storage/database.h"

namespace fesbench::storage {

/// The trial's main channel group as CSV (header of channel names, which
/// carry their units; one row per sample).
api::Result<std::string> ExportTrialCsv(Database& db, std::int64_t trial_id);
/// The trial's main channel group as OpenSim .sto (version 1, `time` first).
api::Result<std::string> ExportTrialSto(Database& db, std::int64_t trial_id);
/// The parameter set's JSON (docs/MODEL.md), pretty-printed.
api::Result<std::string> ExportParameterSetJson(Database& db, std::int64_t parameter_set_id);

}  // namespace fesbench::storage
