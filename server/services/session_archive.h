#pragma once

/// @file
/// Data in and out of a session (docs/API.md "Session archives"): one archive per session,
/// laid out after BIDS (api/bids.h) with the session's parameter sets, run
/// log and a README of the layout; and imports — such an archive, or one
/// recording made elsewhere (api/trial_import.h) — stored as trials of a
/// session with their provenance, all or nothing.
///
/// Archive layout (root directory fesbench-session-<id>/; docs/API.md
/// "Session archives"):
///
///     README.md                      this layout, for people
///     dataset_description.json       BIDS: Name, BIDSVersion, GeneratedBy
///     participants.tsv, .json        the subject by pseudonymous code only
///     sub-S/ses-N/sub-S_ses-N_scans.tsv   each motion file and its acq_time
///     sub-S/ses-N/motion/…           the trials (api/bids.h)
///     derivatives/fesbench/dataset_description.json
///     derivatives/fesbench/sub-S/ses-N/{motion,emg}/…   the trials' own
///                                    records, .mot and EMG (api/bids.h)
///     derivatives/fesbench/session.json   subject, leg and session values
///     derivatives/fesbench/runs.json      every run with its states and reason
///     derivatives/fesbench/parameter_sets/paramset-<id>.json
///                                    {id, version, created_at, supersedes_id,
///                                     parameter_set (docs/MODEL.md)}
///     derivatives/fesbench/predictions.tsv, predictions/prediction-<id>.json,
///     evaluations.json               the sets' predictions and evaluations
///                                    on these trials, with their errors
///
/// An imported archive holds these files and no others, under one root
/// directory fesbench-session-<id>/ of any id (import_upload.h).

#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "api/bids.h"
#include "api/import_result.h"
#include "api/status.h"
#include "api/trial_import.h"
#include "storage/database.h"

namespace fesbench::server::services {

enum class ArchiveFormat { kZip, kTarGz };

/// "zip" or "tar.gz" (also "tgz"); nullopt otherwise.
std::optional<ArchiveFormat> ParseArchiveFormat(std::string_view name);
std::string_view ArchiveFormatName(ArchiveFormat format);
/// "application/zip" or "application/gzip".
std::string_view ArchiveMediaType(ArchiveFormat format);

/// Packs `files` under the directory `root` (libarchive). Entries are
/// regular files, mode 0644, sorted by path.
api::Result<std::string> PackArchive(const api::FileMap& files, ArchiveFormat format,
                                     std::string_view root);

/// What a session export holds besides the trials, in resource shapes the
/// HTTP layer renders (so the archive's JSON matches the API's).
struct SessionExportInfo {
  std::int64_t session_id = 0;
  nlohmann::json session;  ///< GET /sessions/{id}
  nlohmann::json subject;  ///< GET /subjects/{id}
  nlohmann::json runs;     ///< array of GET /runs/{id}
  std::string software_version;
};

/// The files of a session's archive (layout above): its trials and the
/// parameter sets identified from them, read from `db`.
api::Result<api::FileMap> SessionExportFiles(storage::Database& db, const SessionExportInfo& info);

/// What an import stored (api/import_result.h).
using api::ImportedItem;
using api::ImportResult;

/// Stores one recording (ImportTrialText) as a trial of the session.
/// `text` is the file's content. Joins a caller's write transaction.
api::Result<ImportResult> ImportRecording(storage::Database& db, std::int64_t session_id,
                                          std::string_view text, const api::ImportSpec& spec,
                                          std::string_view imported_by);

/// Stores every trial of an unpacked session archive (ReadBidsTrials;
/// import_upload.h UnpackArchive reads it) in the session, and the
/// archive's parameter sets whose provenance trials all came with it (trial
/// ids mapped to the new ones, stored for the session's subject and leg).
/// Each parameter-set file is read strictly: the fields the export writes
/// and no others (kInvalidArgument naming the file and the field). All or
/// nothing: checked first, then one write transaction.
api::Result<ImportResult> ImportArchive(storage::Database& db, std::int64_t session_id,
                                        const api::FileMap& files, std::string_view archive_name,
                                        std::string_view imported_by);

}  // namespace fesbench::server::services
