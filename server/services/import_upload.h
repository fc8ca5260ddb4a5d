#pragma once

/// @file
/// Reading an import's upload (POST /sessions/{id}/trials, docs/API.md
/// "Import") from the file the front end spooled it to, within bounds:
/// every byte the import holds in memory — an archive's unpacked entries,
/// a recording's text, and what reading their tables will hold — is drawn
/// from one MemoryBudget first, and an upload that could never fit is
/// refused as too large (docs/SAFETY.md "Uploads").
///
/// Refusals: kInvalidArgument naming the entry, file, line or field;
/// kPayloadTooLarge (413) naming the entry and the limit it passes;
/// kUnavailable (503) when the budget is momentarily spent by other
/// uploads.

#include <cstddef>
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>

#include "api/bids.h"
#include "api/status.h"
#include "api/trial_import.h"
#include "server/services/memory_budget.h"
#include "server/services/session_archive.h"

namespace fesbench::server::services {

/// Limits on one uploaded session archive.
struct UnpackLimits {
  std::size_t max_entries = 20000;
  /// Unpacked bytes of all entries together (held in memory).
  std::size_t max_unpacked_bytes = std::size_t{128} << 20;
  /// Each small file the import parses whole: README, JSON sidecars,
  /// participants, scans and channel tables.
  std::size_t max_small_file_bytes = std::size_t{1} << 20;
  /// Each derivatives/fesbench/parameter_sets/paramset-<id>.json.
  std::size_t max_parameter_set_bytes = std::size_t{4} << 20;
};

/// An archive read into memory, with the budget it holds.
struct UnpackedArchive {
  api::FileMap files;  ///< by path under the root directory (session_archive.h layout).
  /// The files' bytes and what reading their trials' tables will hold.
  MemoryBudget::Reservation memory;
};

/// Reads the archive in `fd` (a regular file; zip or tar.gz as `format`
/// says) entry by entry. Every entry must belong to the export layout
/// (session_archive.h) under one root directory `fesbench-session-<id>/`;
/// directories are skipped. Refused naming the entry: a body that is not
/// `format`, a corrupt or truncated archive, an entry outside the layout
/// (a stray file), an absolute path or "..", a link or device, a path twice,
/// more than `limits.max_entries` entries; as too large: an entry or the
/// archive beyond `limits`, or more memory than `budget` could ever give.
api::Result<UnpackedArchive> UnpackArchive(int fd, ArchiveFormat format, MemoryBudget& budget,
                                           const UnpackLimits& limits = {});

/// Whether `path` (relative to the archive's root) is a file of the export
/// layout (session_archive.h, api/bids.h).
bool IsExportLayoutFile(std::string_view path);

/// A recording upload, the JSON {spec, data} of docs/API.md, read and held
/// within the budget.
struct RecordingUpload {
  api::ImportSpec spec;
  nlohmann::json spec_json;  ///< as sent (for the audit log).
  std::string data;          ///< the recording's text.
  /// The text and what reading it as a trial will hold.
  MemoryBudget::Reservation memory;
};

/// Reads the {spec, data} body of `size` bytes in `fd` strictly
/// (api::ParseJsonObject: no duplicate keys, nesting ≤ 32; no fields but
/// spec and data; the spec as api::ImportSpecFromJson reads it, its errors
/// under "spec."). Too large when the text and its parse need more than
/// the budget's capacity.
api::Result<RecordingUpload> ReadRecordingUpload(int fd, std::size_t size, MemoryBudget& budget);

/// Memory beyond the text that reading `text` as a table and a trial holds
/// (api::ReadTextTable; an estimate from its lines and values, high for
/// any shape): `line_bytes` a line and `value_bytes` a value.
std::size_t TableFootprintBytes(std::string_view text, std::size_t line_bytes,
                                std::size_t value_bytes);

}  // namespace fesbench::server::services
