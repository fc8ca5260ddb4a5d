#pragma once

/// @file
/// (The functions live in api/time_utc.h, shared with the clients.)
/// UTC timestamps as stored in the database: ISO 8601 with microseconds,
/// "YYYY-MM-DDTHH:MM:SS.ffffffZ". The fixed width makes text order equal time
/// order, so `*_utc` columns are range-scanned through ordinary indexes.

#include <chrono>
#include <optional>
#include <string>
#include <string_view>

#include "api/clock.h"
#include "api/time_utc.h"

namespace fesbench::storage {

/// A point in time, UTC, microsecond resolution (api/clock.h).
using UtcTime = api::UtcTime;
using api::FormatUtc;
using api::IsIsoDate;
using api::ParseUtc;

}  // namespace fesbench::storage
