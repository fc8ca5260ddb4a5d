#pragma once

/// @file
/// UTC timestamps as stored in the database: ISO 8601 with microseconds,
/// "YYYY-MM-DDTHH:MM:SS.ffffffZ". The fixed width makes text order equal time
/// order, so `*_utc` columns are range-scanned through ordinary indexes.

#include <chrono>
#include <optional>
#include <string>
#include <string_view>

#include "api/clock.h"

namespace fesbench::api {

/// "2026-11-21T10:36:43.123456Z". Years outside 0000–9999 are clamped.
std::string FormatUtc(UtcTime t);

/// Inverse of FormatUtc; nullopt unless `text` has exactly that form and
/// names a valid calendar date and time of day.
std::optional<UtcTime> ParseUtc(std::string_view text);

/// True when `text` is a valid calendar date "YYYY-MM-DD".
bool IsIsoDate(std::string_view text);

}  // namespace fesbench::api
