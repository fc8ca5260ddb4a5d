#include "storage/private_files.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <vector>

namespace fesbench::storage {

api::Status CreatePrivateFolders(const std::filesystem::path& folder) {
  // The missing ones, innermost last, made one by one with an explicit mode
  // (std::filesystem::create_directories takes its mode from the umask).
  std::vector<std::filesystem::path> missing;
  std::error_code ec;
  for (std::filesystem::path p = folder; !p.empty() && !std::filesystem::exists(p, ec);
       p = p.parent_path()) {
    missing.push_back(p);
    if (p == p.parent_path()) break;
  }
  for (auto it = missing.rbegin(); it != missing.rend(); ++it) {
    if (::mkdir(it->c_str(), kPrivateFolderMode) != 0 && errno != EEXIST) {
      return api::Status::Unavailable("cannot create the folder '" + it->string() +
                                      "': " + std::strerror(errno));
    }
    // mkdir's mode is masked by the umask; the folder must be 0700 anyway.
    (void)::chmod(it->c_str(), kPrivateFolderMode);
  }
  if (!std::filesystem::is_directory(folder, ec)) {
    return api::Status::Unavailable("'" + folder.string() + "' is not a folder");
  }
  return api::Status::Ok();
}

api::Status CreatePrivateFile(const std::filesystem::path& path) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, kPrivateFileMode);
  if (fd < 0) {
    if (errno == EEXIST) return api::Status::Ok();
    return api::Status::Unavailable("cannot create '" + path.string() +
                                    "': " + std::strerror(errno));
  }
  (void)::fchmod(fd, kPrivateFileMode);
  ::close(fd);
  return api::Status::Ok();
}

api::Result<std::optional<mode_t>> NarrowToOwner(const std::filesystem::path& path) {
  struct stat info {};
  if (::lstat(path.c_str(), &info) != 0) {
    if (errno == ENOENT) return std::optional<mode_t>();
    return api::Status::Unavailable("cannot read the mode of '" + path.string() +
                                    "': " + std::strerror(errno));
  }
  if (!S_ISREG(info.st_mode)) return std::optional<mode_t>();
  const mode_t mode = info.st_mode & 07777;
  if ((mode & 077) == 0) return std::optional<mode_t>();
  if (::chmod(path.c_str(), kPrivateFileMode) != 0) {
    return api::Status::Unavailable(
        "'" + path.string() + "' is readable by other users (mode " + ModeText(mode) +
        ") and its mode cannot be set to 0600: " + std::strerror(errno));
  }
  return std::optional<mode_t>(mode);
}

std::string ModeText(mode_t mode) {
  char text[8];
  std::snprintf(text, sizeof text, "%04o", static_cast<unsigned>(mode & 07777));
  return text;
}

}  // namespace fesbench::storage
