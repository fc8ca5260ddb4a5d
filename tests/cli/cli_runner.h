#pragma once

// The `fesbench` binary run as a separate process by the CLI integration
// tests: a temporary HOME / XDG_CONFIG_HOME, stdout and stderr to files (so
// stdout is not a terminal), optional standard input.

#include <fcntl.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <regex>
#include <string>
#include <vector>

#include "server_process.h"

#ifndef FESBENCH_CLI_EXE
#error "FESBENCH_CLI_EXE must name the fesbench binary"
#endif

namespace fesbench::testing {

namespace fs = std::filesystem;

struct CliRun {
  int exit_code = -1;
  std::string out;
  std::string err;
};

inline std::string ReadAll(const fs::path& path) {
  std::ifstream in(path);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// Runs the CLI as a separate process with HOME and XDG_CONFIG_HOME in a
// temporary folder, stdout and stderr to files (so stdout is not a terminal).
class Cli {
 public:
  Cli() {
    dir_ = fs::temp_directory_path() /
           ("fesbench-cli-" + std::to_string(::getpid()) + "-" + std::to_string(counter_++));
    fs::create_directories(dir_ / "home");
  }
  ~Cli() {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  const fs::path& dir() const { return dir_; }
  fs::path config_file() const { return dir_ / "xdg" / "fesbench" / "config.json"; }

  CliRun Run(const std::vector<std::string>& args, const std::string& token_env = "") const {
    return Finish(Start(args, token_env));
  }

  // Runs the CLI with `input` as its standard input.
  CliRun RunWithInput(const std::vector<std::string>& args, const std::string& input) const {
    {
      std::ofstream in(dir_ / "stdin.txt");
      in << input;
    }
    return Finish(Start(args, "", dir_ / "stdin.txt"));
  }

  // Starts the CLI without waiting (Finish collects it): for signals.
  pid_t Start(const std::vector<std::string>& args, const std::string& token_env = "",
              const fs::path& stdin_file = {}) const {
    const fs::path out_file = dir_ / "stdout.txt";
    const fs::path err_file = dir_ / "stderr.txt";
    const pid_t pid = ::fork();
    if (pid == 0) {
      const int out = ::open(out_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
      const int err = ::open(err_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
      ::dup2(out, STDOUT_FILENO);
      ::dup2(err, STDERR_FILENO);
      if (!stdin_file.empty()) {
        const int in = ::open(stdin_file.c_str(), O_RDONLY);
        ::dup2(in, STDIN_FILENO);
      }
      ::setenv("HOME", (dir_ / "home").c_str(), 1);
      ::setenv("XDG_CONFIG_HOME", (dir_ / "xdg").c_str(), 1);
      if (token_env.empty()) {
        ::unsetenv("FESBENCH_TOKEN");
      } else {
        ::setenv("FESBENCH_TOKEN", token_env.c_str(), 1);
      }
      std::vector<std::string> all = {FESBENCH_CLI_EXE};
      all.insert(all.end(), args.begin(), args.end());
      std::vector<char*> argv;
      for (auto& a : all) argv.push_back(a.data());
      argv.push_back(nullptr);
      ::execv(argv[0], argv.data());
      ::_exit(127);
    }
    return pid;
  }

  // What the CLI printed so far (while it runs).
  std::string OutSoFar() const { return ReadAll(dir_ / "stdout.txt"); }

  CliRun Finish(pid_t pid) const {
    const fs::path out_file = dir_ / "stdout.txt";
    const fs::path err_file = dir_ / "stderr.txt";
    int status = 0;
    ::waitpid(pid, &status, 0);
    CliRun run;
    run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    run.out = ReadAll(out_file);
    run.err = ReadAll(err_file);
    return run;
  }

 private:
  static inline int counter_ = 0;
  fs::path dir_;
};

inline std::string Url(const ServerProcess& server) {
  return "http://127.0.0.1:" + std::to_string(server.port());
}

// Exactly one line on stderr, "fesbench: error: ...", nothing like a trace.
inline void ExpectOneErrorLine(const CliRun& run) {
  EXPECT_THAT(run.err, ::testing::StartsWith("fesbench: error: "));
  EXPECT_EQ(std::count(run.err.begin(), run.err.end(), '\n'), 1) << run.err;
}

inline std::int64_t LastNumber(const std::string& text, const std::string& after) {
  const std::regex pattern(after + " ([0-9]+)");
  std::int64_t value = -1;
  for (std::sregex_iterator it(text.begin(), text.end(), pattern), end; it != end; ++it) {
    value = std::stoll((*it)[1]);
  }
  return value;
}

}  // namespace fesbench::testing
