#include "server/services/import_upload.h"

#include <archive.h>
#include <archive_entry.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstring>
#include <memory>
#include <optional>
#include <vector>

#include "api/json_fields.h"

namespace fesbench::server::services {
namespace {

using nlohmann::json;

constexpr std::size_t kMiB = std::size_t{1} << 20;

std::string MiB(std::size_t bytes) { return std::to_string((bytes + kMiB - 1) / kMiB) + " MiB"; }

// Grows `memory` to `bytes`: too large when even an idle budget could not
// give that much (so retrying is pointless), unavailable while other
// uploads hold it.
api::Status Hold(MemoryBudget::Reservation& memory, std::size_t bytes, const MemoryBudget& budget,
                 const std::string& what) {
  if (bytes > budget.capacity()) {
    return api::Status::PayloadTooLarge(what + " needs " + MiB(bytes) +
                                        " of memory to import, more than the server's " +
                                        MiB(budget.capacity()) + " for imports");
  }
  return memory.Resize(bytes);
}

// --- The export layout (session_archive.h, api/bids.h) ------------------------

enum class EntryKind { kSmall, kParameterSet, kData };

bool IsLabel(std::string_view s) {
  return !s.empty() &&
         std::all_of(s.begin(), s.end(), [](unsigned char c) { return std::isalnum(c) != 0; });
}

bool IsDigits(std::string_view s) {
  return !s.empty() &&
         std::all_of(s.begin(), s.end(), [](unsigned char c) { return std::isdigit(c) != 0; });
}

std::vector<std::string_view> SplitSlashes(std::string_view path) {
  std::vector<std::string_view> parts;
  std::size_t start = 0;
  while (true) {
    const std::size_t end = path.find('/', start);
    parts.push_back(path.substr(start, end == std::string_view::npos ? end : end - start));
    if (end == std::string_view::npos) return parts;
    start = end + 1;
  }
}

// A trial file under sub-S/ses-N/<datatype>/ (api/bids.h), raw or in the
// derivative: named sub-S_ses-N_<entities>_<suffix>, entities of
// [A-Za-z0-9_-].
std::optional<EntryKind> TrialFileKind(std::string_view subject, std::string_view session,
                                       std::string_view datatype, std::string_view name,
                                       bool derivative) {
  static constexpr std::pair<std::string_view, EntryKind> kMotion[] = {
      {"_motion.tsv", EntryKind::kData},
      {"_events.tsv", EntryKind::kData},
      {"_channels.tsv", EntryKind::kSmall},
      {"_motion.json", EntryKind::kSmall},
      {"_events.json", EntryKind::kSmall}};
  static constexpr std::pair<std::string_view, EntryKind> kDerivedMotion[] = {
      {"_trial.json", EntryKind::kSmall}, {"_motion.mot", EntryKind::kData}};
  static constexpr std::pair<std::string_view, EntryKind> kDerivedEmg[] = {
      {"_emg.tsv", EntryKind::kData},
      {"_emg.edf", EntryKind::kData},
      {"_emg.json", EntryKind::kSmall},
      {"_channels.tsv", EntryKind::kSmall}};
  const std::string prefix = "sub-" + std::string(subject) + "_ses-" + std::string(session) + "_";
  if (!name.starts_with(prefix)) return std::nullopt;
  const auto allowed = [](unsigned char c) {
    return std::isalnum(c) != 0 || c == '_' || c == '-' || c == '.';
  };
  if (!std::all_of(name.begin(), name.end(), allowed)) return std::nullopt;
  const auto check = [&](const auto& suffixes) -> std::optional<EntryKind> {
    for (const auto& [suffix, kind] : suffixes) {
      if (name.size() > prefix.size() + suffix.size() && name.ends_with(suffix)) return kind;
    }
    return std::nullopt;
  };
  if (!derivative) return datatype == "motion" ? check(kMotion) : std::nullopt;
  if (datatype == "motion") return check(kDerivedMotion);
  if (datatype == "emg") return check(kDerivedEmg);
  return std::nullopt;
}

// sub-S/ses-N/... (p from index `at` on): its kind, or nullopt.
std::optional<EntryKind> SessionFileKind(const std::vector<std::string_view>& p, std::size_t at,
                                         bool derivative) {
  if (p.size() < at + 3 || !p[at].starts_with("sub-") || !p[at + 1].starts_with("ses-")) {
    return std::nullopt;
  }
  const std::string_view subject = p[at].substr(4);
  const std::string_view session = p[at + 1].substr(4);
  if (!IsLabel(subject) || !IsLabel(session)) return std::nullopt;
  if (p.size() == at + 3 && !derivative) {
    const std::string scans =
        "sub-" + std::string(subject) + "_ses-" + std::string(session) + "_scans.tsv";
    return p[at + 2] == scans ? std::optional(EntryKind::kSmall) : std::nullopt;
  }
  if (p.size() == at + 4) return TrialFileKind(subject, session, p[at + 2], p[at + 3], derivative);
  return std::nullopt;
}

// derivatives/fesbench/<directory>/<prefix><digits>.json
bool IsNumberedJson(const std::vector<std::string_view>& p, std::string_view directory,
                    std::string_view prefix) {
  return p.size() == 4 && p[2] == directory && p[3].starts_with(prefix) &&
         p[3].ends_with(".json") &&
         IsDigits(p[3].substr(prefix.size(), p[3].size() - prefix.size() - 5));
}

std::optional<EntryKind> LayoutKind(std::string_view path) {
  const std::vector<std::string_view> p = SplitSlashes(path);
  if (p.size() == 1) {
    if (p[0] == "README.md" || p[0] == "dataset_description.json" || p[0] == "participants.tsv" ||
        p[0] == "participants.json") {
      return EntryKind::kSmall;
    }
    return std::nullopt;
  }
  if (p[0] == "derivatives") {
    if (p.size() < 3 || p[1] != "fesbench") return std::nullopt;
    if (p.size() == 3) {
      if (p[2] == "dataset_description.json") return EntryKind::kSmall;
      if (p[2] == "session.json" || p[2] == "runs.json" || p[2] == "predictions.tsv" ||
          p[2] == "evaluations.json") {
        return EntryKind::kData;
      }
      return std::nullopt;
    }
    if (IsNumberedJson(p, "parameter_sets", "paramset-")) return EntryKind::kParameterSet;
    if (IsNumberedJson(p, "predictions", "prediction-")) return EntryKind::kData;
    return SessionFileKind(p, 2, true);
  }
  return SessionFileKind(p, 0, false);
}

// A directory of the layout ("sub-S/", "derivatives/fesbench/", ...), with
// its trailing slash; "" is the root itself.
bool IsLayoutDirectory(std::string_view dir) {
  if (dir.empty()) return true;
  if (!dir.ends_with('/')) return false;
  dir.remove_suffix(1);
  if (dir == "derivatives" || dir == "derivatives/fesbench" ||
      dir == "derivatives/fesbench/parameter_sets" || dir == "derivatives/fesbench/predictions") {
    return true;
  }
  std::vector<std::string_view> p = SplitSlashes(dir);
  const bool derivative = p.size() > 2 && p[0] == "derivatives" && p[1] == "fesbench";
  if (derivative) p.erase(p.begin(), p.begin() + 2);
  if (p.size() > 3 || !p[0].starts_with("sub-") || !IsLabel(p[0].substr(4))) return false;
  if (p.size() >= 2 && (!p[1].starts_with("ses-") || !IsLabel(p[1].substr(4)))) return false;
  return p.size() < 3 || p[2] == "motion" || (derivative && p[2] == "emg");
}

constexpr std::string_view kRootPrefix = "fesbench-session-";

// The root directory an entry lies under ("fesbench-session-12/"), or "".
std::string RootOf(std::string_view path) {
  const std::size_t slash = path.find('/');
  if (slash == std::string_view::npos) return "";
  const std::string_view top = path.substr(0, slash);
  if (!top.starts_with(kRootPrefix) || !IsDigits(top.substr(kRootPrefix.size()))) return "";
  return std::string(path.substr(0, slash + 1));
}

std::string NotInLayout(const std::string& path, const std::string& why) {
  return "archive entry '" + path + "' " + why +
         "; a session archive holds only the files GET /sessions/{id}/export writes, under one "
         "directory fesbench-session-<id>/";
}

// --- Unpacking ----------------------------------------------------------------

struct ReadArchiveDeleter {
  void operator()(archive* a) const {
    if (a != nullptr) archive_read_free(a);
  }
};

std::string ArchiveError(archive* a) {
  const char* message = archive_error_string(a);
  return message != nullptr ? message : "unknown archive error";
}

// One archive being read: its entries so far and the budget they hold.
class Unpacker {
 public:
  Unpacker(archive* a, MemoryBudget& budget, const UnpackLimits& limits)
      : a_(a), budget_(budget), limits_(limits), memory_(budget.Reserve(0).value()) {}

  api::Status ReadEntries(ArchiveFormat format);
  api::Status HoldParseMemory();
  UnpackedArchive Take() { return {std::move(files_), std::move(memory_)}; }

 private:
  api::Status CheckPath(const std::string& path);
  api::Status ReadEntry(archive_entry* entry, const std::string& path, EntryKind kind);
  api::Status Grow(std::string& content, std::size_t needed, bool exact, const std::string& path);
  std::size_t EntryLimit(EntryKind kind) const;

  archive* a_;
  MemoryBudget& budget_;
  const UnpackLimits& limits_;
  std::string root_;
  api::FileMap files_;
  MemoryBudget::Reservation memory_;
  std::size_t unpacked_ = 0;  // bytes of all entries read so far.
  std::size_t held_ = 0;      // capacity of their strings (what memory_ covers).
};

std::size_t Unpacker::EntryLimit(EntryKind kind) const {
  switch (kind) {
    case EntryKind::kSmall:
      return limits_.max_small_file_bytes;
    case EntryKind::kParameterSet:
      return limits_.max_parameter_set_bytes;
    case EntryKind::kData:
      return limits_.max_unpacked_bytes;
  }
  return 0;
}

// `path` (a directory's with its trailing slash) is relative, without "..",
// and under the archive's one root.
api::Status Unpacker::CheckPath(const std::string& path) {
  if (path.empty() || path.front() == '/' || path.find("..") != std::string::npos ||
      path.find('\\') != std::string::npos) {
    return api::Status::InvalidArgument("archive entry '" + path +
                                        "': absolute paths and '..' are refused");
  }
  const std::string root = RootOf(path);
  if (root.empty()) return api::Status::InvalidArgument(NotInLayout(path, "is outside the root"));
  if (root_.empty()) root_ = root;
  if (root != root_) {
    return api::Status::InvalidArgument(
        NotInLayout(path, "is under another root than '" + root_ + "'"));
  }
  return api::Status::Ok();
}

api::Status Unpacker::ReadEntries(ArchiveFormat format) {
  std::size_t entries = 0;
  archive_entry* entry = nullptr;
  while (true) {
    const int r = archive_read_next_header(a_, &entry);
    if (r == ARCHIVE_EOF) break;
    if (r != ARCHIVE_OK && entries == 0) {
      return api::Status::InvalidArgument(
          std::string(format == ArchiveFormat::kZip ? "not a zip" : "not a tar.gz") +
          " archive (as its Content-Type says): " + ArchiveError(a_));
    }
    if (r != ARCHIVE_OK) {
      return api::Status::InvalidArgument("corrupt archive after " + std::to_string(entries) +
                                          " entries: " + ArchiveError(a_));
    }
    if (entries++ == 0 && format == ArchiveFormat::kTarGz &&
        archive_filter_code(a_, 0) != ARCHIVE_FILTER_GZIP) {
      return api::Status::InvalidArgument(
          "the body is sent as application/gzip but is not gzip-compressed");
    }
    if (entries > limits_.max_entries) {
      return api::Status::PayloadTooLarge("the archive has more than " +
                                          std::to_string(limits_.max_entries) + " entries");
    }
    const char* raw_path = archive_entry_pathname(entry);
    const std::string path = raw_path != nullptr ? raw_path : "";
    const auto type = archive_entry_filetype(entry);
    if (type != AE_IFDIR && type != AE_IFREG) {
      return api::Status::InvalidArgument("archive entry '" + path +
                                          "' is not a regular file (links and devices are "
                                          "refused)");
    }
    const bool directory = type == AE_IFDIR;
    if (api::Status s = CheckPath(directory && !path.ends_with('/') ? path + "/" : path); !s.ok()) {
      return s;
    }
    if (directory) {
      const std::string relative = (path.ends_with('/') ? path : path + "/").substr(root_.size());
      if (!IsLayoutDirectory(relative)) {
        return api::Status::InvalidArgument(NotInLayout(path, "is not a directory of the layout"));
      }
      continue;
    }
    const std::string relative = path.substr(root_.size());
    const std::optional<EntryKind> kind = LayoutKind(relative);
    if (!kind) return api::Status::InvalidArgument(NotInLayout(path, "is not part of the layout"));
    if (files_.contains(relative)) {
      return api::Status::InvalidArgument("archive entry '" + path + "' appears twice");
    }
    if (api::Status s = ReadEntry(entry, path, *kind); !s.ok()) return s;
  }
  if (files_.empty()) return api::Status::InvalidArgument("the archive holds no files");
  return api::Status::Ok();
}

// Makes room for `needed` bytes in `content` (`exact`ly that many for an
// entry of declared size, else growing geometrically), its new capacity
// drawn from the budget first: while the string moves, the old and the new
// buffer both exist and both are held.
api::Status Unpacker::Grow(std::string& content, std::size_t needed, bool exact,
                           const std::string& path) {
  // A string's inline buffer (an empty one's capacity) is no allocation.
  const std::size_t old_capacity =
      content.capacity() > std::string().capacity() ? content.capacity() : 0;
  const std::size_t room = limits_.max_unpacked_bytes - (unpacked_ - content.size());
  const std::size_t capacity =
      exact ? needed : std::min(std::max({needed, 2 * old_capacity, std::size_t{64} << 10}), room);
  if (api::Status s = Hold(memory_, held_ + capacity, budget_, "archive entry '" + path + "'");
      !s.ok()) {
    return s;
  }
  content.reserve(capacity);
  held_ = held_ + content.capacity() - old_capacity;
  return memory_.Resize(held_);
}

api::Status Unpacker::ReadEntry(archive_entry* entry, const std::string& path, EntryKind kind) {
  const std::size_t entry_limit = EntryLimit(kind);
  const auto too_large = [&](std::size_t limit, const char* what) {
    return api::Status::PayloadTooLarge("archive entry '" + path + "' unpacks beyond " +
                                        MiB(limit) + ", the limit of " + what);
  };
  constexpr const char* kOfFile = "a file of its kind";
  constexpr const char* kOfArchive = "a whole archive unpacked";
  std::optional<std::size_t> declared;
  if (archive_entry_size_is_set(entry) != 0 && archive_entry_size(entry) >= 0) {
    declared = static_cast<std::size_t>(archive_entry_size(entry));
    if (unpacked_ + *declared > limits_.max_unpacked_bytes) {
      return too_large(limits_.max_unpacked_bytes, kOfArchive);
    }
    if (*declared > entry_limit) return too_large(entry_limit, kOfFile);
  }
  std::string content;
  if (declared && *declared > 0) {
    if (api::Status s = Grow(content, *declared, true, path); !s.ok()) return s;
  }
  char buffer[65536];
  while (true) {
    const la_ssize_t n = archive_read_data(a_, buffer, sizeof buffer);
    if (n == 0) break;
    if (n < 0) {
      return api::Status::InvalidArgument("archive entry '" + path +
                                          "' is corrupt: " + ArchiveError(a_));
    }
    const std::size_t size = content.size() + static_cast<std::size_t>(n);
    if (declared && size > *declared) {
      return api::Status::InvalidArgument("archive entry '" + path + "' holds more than the " +
                                          std::to_string(*declared) + " bytes its header declares");
    }
    if (unpacked_ + static_cast<std::size_t>(n) > limits_.max_unpacked_bytes) {
      return too_large(limits_.max_unpacked_bytes, kOfArchive);
    }
    if (size > entry_limit) return too_large(entry_limit, kOfFile);
    if (size > content.capacity()) {
      if (api::Status s = Grow(content, size, false, path); !s.ok()) return s;
    }
    content.append(buffer, static_cast<std::size_t>(n));
    unpacked_ += static_cast<std::size_t>(n);
  }
  files_[path.substr(root_.size())] = std::move(content);
  return api::Status::Ok();
}

// Reading the trials' tables (api::ReadBidsTrials) holds their values as
// doubles and an index of their lines; the pulse tables are read as
// strings. Held before any of it is read.
api::Status Unpacker::HoldParseMemory() {
  std::size_t parse = 0;
  for (const auto& [path, text] : files_) {
    if (path.ends_with("_events.tsv")) {
      parse += TableFootprintBytes(text, 64, 40);
    } else if (path.ends_with("_motion.tsv") || path.ends_with("_emg.tsv")) {
      parse += TableFootprintBytes(text, 16, 8);
    }
  }
  return Hold(memory_, held_ + parse, budget_, "the archive (" + MiB(unpacked_) + " unpacked)");
}

// The bytes of a spooled upload.
api::Result<std::string> ReadAll(int fd, std::size_t size) {
  std::string text(size, '\0');
  std::size_t done = 0;
  while (done < size) {
    const ssize_t n = ::pread(fd, text.data() + done, size - done, static_cast<off_t>(done));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      return api::Status::Internal("reading the spooled upload: " +
                                   std::string(n < 0 ? std::strerror(errno) : "file too short"));
    }
    done += static_cast<std::size_t>(n);
  }
  return text;
}

// A {spec, data} body holds a few hundred JSON values; more is not a
// recording (and would cost far more as a document than as text).
constexpr std::size_t kMaxRecordingJsonValues = 10000;

}  // namespace

bool IsExportLayoutFile(std::string_view path) { return LayoutKind(path).has_value(); }

std::size_t TableFootprintBytes(std::string_view text, std::size_t line_bytes,
                                std::size_t value_bytes) {
  std::size_t lines = 1;
  std::size_t separators = 0;
  for (const char c : text) {
    if (c == '\n') {
      ++lines;
    } else if (c == ',' || c == '\t' || c == ' ') {
      ++separators;
    }
  }
  return lines * line_bytes + (lines + separators) * value_bytes;
}

api::Result<UnpackedArchive> UnpackArchive(int fd, ArchiveFormat format, MemoryBudget& budget,
                                           const UnpackLimits& limits) {
  std::unique_ptr<archive, ReadArchiveDeleter> a(archive_read_new());
  if (!a) return api::Status::Internal("libarchive: out of memory");
  if (format == ArchiveFormat::kZip) {
    archive_read_support_format_zip(a.get());
  } else {
    archive_read_support_filter_gzip(a.get());
    archive_read_support_format_tar(a.get());
  }
  if (archive_read_open_fd(a.get(), fd, 65536) != ARCHIVE_OK) {
    return api::Status::InvalidArgument(
        std::string(format == ArchiveFormat::kZip ? "not a zip" : "not a tar.gz") +
        " archive (as its Content-Type says): " + ArchiveError(a.get()));
  }
  Unpacker unpacker(a.get(), budget, limits);
  if (api::Status s = unpacker.ReadEntries(format); !s.ok()) return s;
  if (api::Status s = unpacker.HoldParseMemory(); !s.ok()) return s;
  return unpacker.Take();
}

api::Result<RecordingUpload> ReadRecordingUpload(int fd, std::size_t size, MemoryBudget& budget) {
  RecordingUpload upload;
  upload.memory = budget.Reserve(0).value();
  // The text, and its document: the data string and at most
  // kMaxRecordingJsonValues small values.
  const std::size_t document = size + kMaxRecordingJsonValues * 128;
  if (api::Status s = Hold(upload.memory, size + document, budget, "the recording"); !s.ok()) {
    return s;
  }
  json body;
  {
    auto text = ReadAll(fd, size);
    if (!text.ok()) return text.status();
    auto parsed = api::ParseJsonObject(*text, {.max_values = kMaxRecordingJsonValues});
    if (!parsed.ok()) return parsed.status();
    body = std::move(*parsed);
  }
  api::JsonFields fields(body);
  const json* spec = fields.Object("spec", true);
  const json* data = fields.Any("data", true);
  if (data != nullptr && !data->is_string()) {
    fields.Fail("data", "must be a string: the recording's text");
  }
  if (api::Status s = fields.Finish(); !s.ok()) return s;
  auto read_spec = api::ImportSpecFromJson(*spec);
  if (!read_spec.ok()) {
    const std::string& field = read_spec.status().field();
    return api::Status::InvalidArgument(read_spec.status().message(),
                                        field.empty() ? "spec" : "spec." + field);
  }
  upload.spec = std::move(*read_spec);
  upload.spec_json = *spec;
  upload.data = std::move(body["data"].get_ref<std::string&>());
  body = nullptr;
  // The text, its lines and values read, and the trial's copy of them.
  const std::size_t parse = upload.data.size() + TableFootprintBytes(upload.data, 16, 16);
  if (api::Status s = Hold(upload.memory, parse, budget, "the recording"); !s.ok()) return s;
  return upload;
}

}  // namespace fesbench::server::services
