#pragma once

/// @file
/// The web client's built files (clients/web, bundled at build time) served
/// at `/` without a token (docs/API.md, "HTTP conventions": only health, openapi.json and these
/// are open). Only GET and HEAD of paths outside /api/ are served; "/" is
/// index.html. A request path maps to a file only if every segment is
/// 1–128 characters of [A-Za-z0-9._-] not starting with '.', and the file,
/// symlinks resolved, lies inside the root: path traversal is impossible.
/// Content types by extension; hashed bundle names ("app-AB12CD34.js") are
/// cached for a year as immutable, everything else is revalidated
/// ("no-cache").

#include "server/http/message.h"

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>

namespace fesbench::server::http {

class StaticFiles {
 public:
  /// @param root the folder holding index.html (need not exist: then
  /// nothing is served).
  explicit StaticFiles(std::filesystem::path root);

  /// Serves `req` from the root if it names a file there: fills `res` and
  /// returns true. False (res untouched) for other methods, /api/ paths,
  /// refused or missing files.
  bool Serve(const Request& req, Response& res) const;

  /// The file under the root that `request_path` names, if it may be
  /// served and exists as a regular file.
  std::optional<std::filesystem::path> Resolve(std::string_view request_path) const;

  const std::filesystem::path& root() const { return root_; }

 private:
  std::filesystem::path root_;  ///< canonical, or empty if missing.
};

/// The Content-Type for a file name by its extension
/// ("application/octet-stream" if unknown).
std::string_view ContentTypeFor(std::string_view file_name);

/// True for bundle names carrying a content hash: "<name>-<8+ of [A-Z0-9]>.<ext>".
bool IsHashedAssetName(std::string_view file_name);

}  // namespace fesbench::server::http
