// Integration: HTTPS end to end. At test time the `openssl`
// command-line tool makes a throwaway CA and a server certificate for
// 127.0.0.1 (subjectAltName IP) in a temporary folder; the real
// fesbench-server runs with --tls-cert/--tls-key and the real `fesbench`
// binary talks to https://127.0.0.1:PORT with FESBENCH_CA_FILE naming the
// CA: login with --token-file, then a read with --json. Without the CA, or
// with another CA, the CLI stops with exit 3 and one line naming the
// untrusted certificate, and writes no config file.

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <string>

#include "cli_runner.h"
#include "server_process.h"

#ifndef FESBENCH_OPENSSL_TOOL
#error "FESBENCH_OPENSSL_TOOL must name the openssl command-line tool"
#endif

namespace fesbench::testing {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using ::testing::HasSubstr;

// A CA and a server certificate signed by it (P-256 keys, valid one day),
// made with the openssl tool in a temporary folder removed afterwards.
class TestCa {
 public:
  explicit TestCa(const std::string& name) {
    std::random_device rd;
    dir_ = fs::temp_directory_path() /
           ("fesbench-ca-" + name + "-" + std::to_string(::getpid()) + "-" + std::to_string(rd()));
    fs::create_directories(dir_);
    {
      std::ofstream ext(dir_ / "server.ext");
      ext << "basicConstraints=critical,CA:FALSE\n"
             "keyUsage=critical,digitalSignature\n"
             "extendedKeyUsage=serverAuth\n"
             "subjectAltName=IP:127.0.0.1\n";
    }
    const std::string d = "'" + dir_.string() + "'/";
    const std::string key = " -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes";
    Openssl("req -x509" + key + " -keyout " + d + "ca.key -out " + d + "ca.pem -days 1 -subj '/CN=" +
            name + " test CA'");
    Openssl("req" + key + " -keyout " + d + "server.key -out " + d +
            "server.csr -subj '/CN=127.0.0.1'");
    Openssl("x509 -req -in " + d + "server.csr -CA " + d + "ca.pem -CAkey " + d +
            "ca.key -CAcreateserial -days 1 -extfile " + d + "server.ext -out " + d + "server.pem");
  }
  ~TestCa() {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  TestCa(const TestCa&) = delete;
  TestCa& operator=(const TestCa&) = delete;

  fs::path ca() const { return dir_ / "ca.pem"; }
  fs::path cert() const { return dir_ / "server.pem"; }
  fs::path key() const { return dir_ / "server.key"; }

 private:
  void Openssl(const std::string& args) const {
    const std::string command = std::string("'") + FESBENCH_OPENSSL_TOOL + "' " + args + " >>'" + (dir_ / "openssl.log").string() + "' 2>&1";
    ASSERT_EQ(std::system(command.c_str()), 0)
        << command << "\n" << ReadAll(dir_ / "openssl.log");
  }

  fs::path dir_;
};

// FESBENCH_CA_FILE for the CLI processes started while this lives (they
// inherit the environment); unset when `value` is empty, restored after.
class ScopedCaFile {
 public:
  explicit ScopedCaFile(const std::string& value) {
    if (const char* old = std::getenv("FESBENCH_CA_FILE")) old_ = old, had_ = true;
    if (value.empty()) {
      ::unsetenv("FESBENCH_CA_FILE");
    } else {
      ::setenv("FESBENCH_CA_FILE", value.c_str(), 1);
    }
  }
  ~ScopedCaFile() {
    if (had_) {
      ::setenv("FESBENCH_CA_FILE", old_.c_str(), 1);
    } else {
      ::unsetenv("FESBENCH_CA_FILE");
    }
  }

 private:
  std::string old_;
  bool had_ = false;
};

std::unique_ptr<ServerProcess> StartTlsServer(const TestCa& ca) {
  auto server = std::make_unique<ServerProcess>(std::vector<std::string>{
      "--tls-cert", ca.cert().string(), "--tls-key", ca.key().string()});
  EXPECT_THAT(server->output(),
              HasSubstr("listening on https://127.0.0.1:" + std::to_string(server->port()) + "/"));
  return server;
}

std::string HttpsUrl(const ServerProcess& server) {
  return "https://127.0.0.1:" + std::to_string(server.port());
}

// Whether `openssl s_client` completes a handshake with `cipher_args`.
bool Handshakes(const ServerProcess& server, const std::string& cipher_args) {
  const std::string command = std::string("'") + FESBENCH_OPENSSL_TOOL +
                              "' s_client -connect 127.0.0.1:" + std::to_string(server.port()) +
                              " " + cipher_args + " </dev/null >/dev/null 2>&1";
  return std::system(command.c_str()) == 0;
}

TEST(CliHttpsTest, OnlyForwardSecretAeadSuitesAreOffered) {
  TestCa ca("fesbench");
  if (::testing::Test::HasFatalFailure()) return;
  auto server = StartTlsServer(ca);
  EXPECT_TRUE(Handshakes(*server, "-tls1_3"));
  EXPECT_TRUE(Handshakes(*server, "-tls1_2 -cipher ECDHE-ECDSA-AES128-GCM-SHA256"));
  EXPECT_TRUE(Handshakes(*server, "-tls1_2 -cipher ECDHE-ECDSA-CHACHA20-POLY1305"));
  // Forward secret but not AEAD (CBC with HMAC): refused.
  EXPECT_FALSE(Handshakes(*server, "-tls1_2 -cipher ECDHE-ECDSA-AES128-SHA"));
  EXPECT_FALSE(Handshakes(*server, "-tls1_2 -cipher ECDHE-ECDSA-AES256-SHA384"));
  EXPECT_FALSE(Handshakes(*server, "-tls1_1"));
}

TEST(CliHttpsTest, LoginAndJsonReadWithTheTestCa) {
  TestCa ca("fesbench");
  if (::testing::Test::HasFatalFailure()) return;
  auto server = StartTlsServer(ca);
  const fs::path token_file = server->dir() / "data" / "admin.token";
  ASSERT_TRUE(fs::exists(token_file));
  ScopedCaFile trust(ca.ca().string());
  Cli cli;

  auto login = cli.Run({"login", HttpsUrl(*server), "--token-file", token_file.string()});
  ASSERT_EQ(login.exit_code, 0) << login.err;
  EXPECT_THAT(login.out, HasSubstr("logged in to " + HttpsUrl(*server)));
  const json config = json::parse(ReadAll(cli.config_file()));
  EXPECT_EQ(config["server"], HttpsUrl(*server));
  EXPECT_EQ(config["token"], server->admin_token());

  // A write and a JSON read over the stored https config.
  auto created = cli.Run({"subjects", "create", "TLS-01", "--leg", "right", "--weight-kg", "70",
                          "--shank-length-cm", "42"});
  ASSERT_EQ(created.exit_code, 0) << created.err;
  auto listed = cli.Run({"subjects", "list", "--json"});
  ASSERT_EQ(listed.exit_code, 0) << listed.err;
  EXPECT_EQ(listed.err, "");
  const json subjects = json::parse(listed.out);  // throws (test fails) if not JSON
  ASSERT_TRUE(subjects.is_array()) << listed.out;
  ASSERT_EQ(subjects.size(), 1u) << listed.out;
  EXPECT_EQ(subjects[0]["code"], "TLS-01");

  EXPECT_EQ(server->Terminate(), 0) << server->Stderr();
}

TEST(CliHttpsTest, UntrustedCertificateIsRefusedWithExit3) {
  TestCa ca("fesbench");
  TestCa other("other");
  if (::testing::Test::HasFatalFailure()) return;
  auto server = StartTlsServer(ca);
  const fs::path token_file = server->dir() / "data" / "admin.token";
  const std::string untrusted =
      "cannot reach " + HttpsUrl(*server) +
      ": the server's certificate is not trusted (set FESBENCH_CA_FILE to its CA file)";

  for (const std::string& ca_file : {std::string(), other.ca().string()}) {
    SCOPED_TRACE(ca_file.empty() ? "FESBENCH_CA_FILE unset (system CAs)" : "another CA");
    ScopedCaFile trust(ca_file);
    Cli cli;
    auto login = cli.Run({"login", HttpsUrl(*server), "--token-file", token_file.string()});
    EXPECT_EQ(login.exit_code, 3) << login.out << login.err;
    ExpectOneErrorLine(login);
    EXPECT_THAT(login.err, HasSubstr(untrusted));
    EXPECT_EQ(login.out, "");
    EXPECT_FALSE(fs::exists(cli.config_file())) << "no config written on a failed login";

    // Also with the token given directly (no login first).
    auto read = cli.Run({"--server", HttpsUrl(*server), "subjects", "list", "--json"},
                        server->admin_token());
    EXPECT_EQ(read.exit_code, 3) << read.out << read.err;
    EXPECT_THAT(read.err, HasSubstr(untrusted));
    EXPECT_EQ(read.out, "");
  }

  // The refused handshakes leave the server serving: the right CA still works.
  ScopedCaFile trust(ca.ca().string());
  Cli cli;
  auto read = cli.Run({"--server", HttpsUrl(*server), "subjects", "list", "--json"},
                      server->admin_token());
  ASSERT_EQ(read.exit_code, 0) << read.err;
  EXPECT_EQ(json::parse(read.out), json::array());

  EXPECT_EQ(server->Terminate(), 0) << server->Stderr();
}

}  // namespace
}  // namespace fesbench::testing
