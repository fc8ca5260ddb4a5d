// Unit tests of the web client's static file serving: path mapping, path
// traversal refused (dot segments, encoded or odd characters, symlinks out
// of the root), content types, cache headers, methods.

#include "server/http/static_files.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

namespace fesbench::server::http {
namespace {

namespace fs = std::filesystem;

class StaticFilesTest : public ::testing::Test {
 protected:
  void SetUp() override {
    base_ = fs::temp_directory_path() / ("fesbench-static-" + std::to_string(::getpid()));
    fs::remove_all(base_);
    fs::create_directories(base_ / "root" / "assets");
    Write(base_ / "root" / "index.html", "<!doctype html>");
    Write(base_ / "root" / "app-AB12CD34.js", "console.log(1)");
    Write(base_ / "root" / "assets" / "logo.svg", "<svg/>");
    Write(base_ / "root" / ".secret", "hidden");
    Write(base_ / "outside.txt", "outside");
    fs::create_symlink(base_ / "outside.txt", base_ / "root" / "link.txt");
  }
  void TearDown() override { fs::remove_all(base_); }
  static void Write(const fs::path& p, const std::string& text) { std::ofstream(p) << text; }

  Response Get(const StaticFiles& files, const std::string& path, bool* served,
                        const std::string& method = "GET") {
    Request req;
    req.method = method;
    req.path = path;
    Response res;
    *served = files.Serve(req, res);
    return res;
  }

  fs::path base_;
};

TEST_F(StaticFilesTest, RootIsIndexWithHtmlTypeNoCacheAndCsp) {
  StaticFiles files(base_ / "root");
  bool served = false;
  auto res = Get(files, "/", &served);
  ASSERT_TRUE(served);
  EXPECT_EQ(res.status, 200);
  EXPECT_EQ(res.body, "<!doctype html>");
  EXPECT_EQ(res.get_header_value("Content-Type"), "text/html; charset=utf-8");
  EXPECT_EQ(res.get_header_value("Cache-Control"), "no-cache");
  EXPECT_NE(res.get_header_value("Content-Security-Policy").find("default-src 'self'"), std::string::npos);
}

TEST_F(StaticFilesTest, HashedBundleIsImmutableAndTyped) {
  StaticFiles files(base_ / "root");
  bool served = false;
  auto res = Get(files, "/app-AB12CD34.js", &served);
  ASSERT_TRUE(served);
  EXPECT_EQ(res.get_header_value("Content-Type"), "text/javascript; charset=utf-8");
  EXPECT_EQ(res.get_header_value("Cache-Control"), "public, max-age=31536000, immutable");
  EXPECT_EQ(res.headers.count("Cache-Control"), 1u);
  res = Get(files, "/assets/logo.svg", &served);
  ASSERT_TRUE(served);
  EXPECT_EQ(res.get_header_value("Content-Type"), "image/svg+xml");
  EXPECT_EQ(res.get_header_value("Cache-Control"), "no-cache");
  res = Get(files, "/index.html", &served, "HEAD");
  EXPECT_TRUE(served);
}

TEST_F(StaticFilesTest, TraversalAndOddPathsAreRefused) {
  StaticFiles files(base_ / "root");
  for (const char* path : {"/../outside.txt", "/assets/../../outside.txt", "/assets/..", "/.secret",
                           "/./index.html", "//index.html", "/assets/", "/link.txt", "/a%2f..",
                           "/index.html/", "/assets", "/missing.js", "index.html", "",
                           "/a b.js", "/\\..\\outside.txt"}) {
    EXPECT_FALSE(files.Resolve(path).has_value()) << path;
  }
  EXPECT_TRUE(files.Resolve("/assets/logo.svg").has_value());
}

TEST_F(StaticFilesTest, OnlyGetAndHeadOutsideTheApi) {
  Write(base_ / "root" / "api", "not the api");
  StaticFiles files(base_ / "root");
  bool served = true;
  Get(files, "/index.html", &served, "POST");
  EXPECT_FALSE(served);
  Get(files, "/api", &served);
  EXPECT_FALSE(served);
  Get(files, "/api/v1/health", &served);
  EXPECT_FALSE(served);
}

TEST_F(StaticFilesTest, MissingRootServesNothing) {
  StaticFiles files(base_ / "nope");
  EXPECT_TRUE(files.root().empty());
  EXPECT_FALSE(files.Resolve("/").has_value());
}

TEST(StaticFileNames, ContentTypesAndHashedNames) {
  EXPECT_EQ(ContentTypeFor("a.css"), "text/css; charset=utf-8");
  EXPECT_EQ(ContentTypeFor("a.json"), "application/json");
  EXPECT_EQ(ContentTypeFor("a.png"), "image/png");
  EXPECT_EQ(ContentTypeFor("README"), "application/octet-stream");
  EXPECT_EQ(ContentTypeFor("x.exe"), "application/octet-stream");
  EXPECT_TRUE(IsHashedAssetName("app-WEDP62N5.js"));
  EXPECT_FALSE(IsHashedAssetName("app-wedp62n5.js"));
  EXPECT_FALSE(IsHashedAssetName("app-ABC.js"));
  EXPECT_FALSE(IsHashedAssetName("index.html"));
  EXPECT_FALSE(IsHashedAssetName("my-index.html"));
}

}  // namespace
}  // namespace fesbench::server::http
