#pragma once

/// @file
/// Files and folders readable by their owner only (docs/SAFETY.md, "Files"):
/// the database holds subjects and token digests, so what storage and the
/// server create is 0600 (files) and 0700 (folders) whatever the process's
/// umask, and the server's own files found wider are narrowed to 0600.

#include <sys/types.h>

#include <filesystem>
#include <optional>
#include <string>

#include "api/status.h"

namespace fesbench::storage {

inline constexpr mode_t kPrivateFileMode = 0600;
inline constexpr mode_t kPrivateFolderMode = 0700;

/// Creates `folder` and its missing parents, each new one 0700; folders that
/// exist are left as they are. kUnavailable naming the folder on failure.
api::Status CreatePrivateFolders(const std::filesystem::path& folder);

/// Creates `path` empty with mode 0600 unless it exists (then leaves it).
/// kUnavailable naming the file when it cannot.
api::Status CreatePrivateFile(const std::filesystem::path& path);

/// When `path` exists and group or others have any access to it, sets its
/// mode to 0600 and returns the mode it had; nullopt when it is missing or
/// already private. kUnavailable naming the file when the mode cannot be
/// changed (a file of another user).
api::Result<std::optional<mode_t>> NarrowToOwner(const std::filesystem::path& path);

/// "0644": a permission mode as ls and chmod write it.
std::string ModeText(mode_t mode);

}  // namespace fesbench::storage
