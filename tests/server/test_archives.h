#pragma once

// Archives made as a user's tool would make them, for import tests: zip or
// tar.gz (libarchive), with any paths, and entries of zeros written piece by
// piece so that a bomb is never whole in the test's memory either.

#include <archive.h>
#include <archive_entry.h>
#include <gtest/gtest.h>

#include <memory>
#include <string>
#include <vector>

#include "server/services/session_archive.h"

namespace fesbench::testing {

inline la_ssize_t AppendTo(archive*, void* out, const void* buffer, size_t length) {
  static_cast<std::string*>(out)->append(static_cast<const char*>(buffer), length);
  return static_cast<la_ssize_t>(length);
}

/// One entry: `content`, or `zero_mib` MiB of zeros when that is not 0.
struct Entry {
  std::string path;
  std::string content;
  std::size_t zero_mib = 0;
};

/// The archive holding `entries` in order, as regular files.
inline std::string MakeArchive(const std::vector<Entry>& entries,
                               server::services::ArchiveFormat format) {
  constexpr std::size_t kMiB = std::size_t{1} << 20;
  std::unique_ptr<archive, decltype(&archive_write_free)> a(archive_write_new(),
                                                            archive_write_free);
  if (format == server::services::ArchiveFormat::kZip) {
    archive_write_set_format_zip(a.get());
  } else {
    archive_write_set_format_pax_restricted(a.get());
    archive_write_add_filter_gzip(a.get());
  }
  std::string out;
  EXPECT_EQ(archive_write_open(a.get(), &out, nullptr, AppendTo, nullptr), ARCHIVE_OK);
  const std::string zeros(kMiB, '\0');
  for (const Entry& e : entries) {
    std::unique_ptr<archive_entry, decltype(&archive_entry_free)> entry(archive_entry_new(),
                                                                        archive_entry_free);
    archive_entry_set_pathname(entry.get(), e.path.c_str());
    const std::size_t size = e.zero_mib != 0 ? e.zero_mib * kMiB : e.content.size();
    archive_entry_set_size(entry.get(), static_cast<la_int64_t>(size));
    archive_entry_set_filetype(entry.get(), AE_IFREG);
    archive_entry_set_perm(entry.get(), 0644);
    EXPECT_EQ(archive_write_header(a.get(), entry.get()), ARCHIVE_OK) << e.path;
    if (e.zero_mib != 0) {
      for (std::size_t i = 0; i < e.zero_mib; ++i) archive_write_data(a.get(), zeros.data(), kMiB);
    } else {
      archive_write_data(a.get(), e.content.data(), e.content.size());
    }
  }
  EXPECT_EQ(archive_write_close(a.get()), ARCHIVE_OK);
  return out;
}

}  // namespace fesbench::testing
