// The project stands on its own: README.md and every docs/**/*.md
// point only inside the repository (links resolve to files in it, no path
// leaves it, no absolute path into a developer's machine, every *.md named
// exists), and every command shown in the README's code blocks exists — each
// fesbench / fesbench-server / fesbench-model / fesbench-dds-monitor
// invocation has its subcommands walked with `--help` (a word must be a
// listed subcommand while the level has subcommands), every --flag it uses
// appears in the help of its command path, and every scripts/* invocation
// answers `--help` with exit 0. Every program answers --version with the one
// project version.

#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#ifndef FESBENCH_SOURCE_DIR
#error "FESBENCH_SOURCE_DIR must name the repository root"
#endif

namespace {

namespace fs = std::filesystem;

const fs::path kRoot = fs::weakly_canonical(FESBENCH_SOURCE_DIR);

std::string ReadAll(const fs::path& path) {
  std::ifstream in(path);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

std::vector<std::string> Lines(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

// README.md and docs/**/*.md.
std::vector<fs::path> DocFiles() {
  std::vector<fs::path> files = {kRoot / "README.md"};
  for (const auto& entry : fs::recursive_directory_iterator(kRoot / "docs")) {
    if (entry.is_regular_file() && entry.path().extension() == ".md") files.push_back(entry.path());
  }
  std::sort(files.begin() + 1, files.end());
  return files;
}

bool InsideRoot(const fs::path& path) {
  const fs::path canonical = fs::weakly_canonical(path);
  const auto [root_end, _] =
      std::mismatch(kRoot.begin(), kRoot.end(), canonical.begin(), canonical.end());
  return root_end == kRoot.end();
}

std::string Where(const fs::path& file, std::size_t line) {
  return fs::relative(file, kRoot).string() + ":" + std::to_string(line + 1);
}

TEST(DocsTest, ReferencesStayInsideTheRepository) {
  const std::regex link(R"(\]\(([^)\s]+)\))");
  const std::regex parent_path(R"((?:\.\./)+[A-Za-z0-9_.\-/]*)");
  const std::regex machine_path(R"((^|[^A-Za-z0-9_.~])(/work/|/home/|/root/)[^\s`)]*)");
  const std::regex md_name(R"([A-Za-z0-9_.\-/]*[A-Za-z0-9_\-]\.md\b)");
  int checked_links = 0;
  for (const fs::path& file : DocFiles()) {
    const fs::path dir = file.parent_path();
    const std::vector<std::string> lines = Lines(ReadAll(file));
    for (std::size_t n = 0; n < lines.size(); ++n) {
      const std::string& line = lines[n];
      for (std::sregex_iterator it(line.begin(), line.end(), link), end; it != end; ++it) {
        std::string target = (*it)[1];
        if (target.starts_with("http://") || target.starts_with("https://") ||
            target.starts_with("mailto:") || target.starts_with("#")) {
          continue;
        }
        target = target.substr(0, target.find('#'));
        ++checked_links;
        EXPECT_TRUE(InsideRoot(dir / target))
            << Where(file, n) << ": link leaves the repository: " << target;
        EXPECT_TRUE(fs::exists(dir / target))
            << Where(file, n) << ": link to a missing file: " << target;
      }
      for (std::sregex_iterator it(line.begin(), line.end(), parent_path), end; it != end; ++it) {
        const std::string path = (*it)[0];
        EXPECT_TRUE(InsideRoot(dir / path))
            << Where(file, n) << ": path leaves the repository: " << path;
      }
      std::smatch machine;
      EXPECT_FALSE(std::regex_search(line, machine, machine_path))
          << Where(file, n) << ": absolute path of a developer's machine: " << machine[0];
      for (std::sregex_iterator it(line.begin(), line.end(), md_name), end; it != end; ++it) {
        const std::string name = (*it)[0];
        // Relative to the document, the root or docs/; a bare file name
        // (e.g. an output of the study, "study.md") anywhere under docs/.
        bool found =
            fs::exists(dir / name) || fs::exists(kRoot / name) || fs::exists(kRoot / "docs" / name);
        if (!found && name.find('/') == std::string::npos) {
          for (const auto& entry : fs::recursive_directory_iterator(kRoot / "docs")) {
            found = found || entry.path().filename() == name;
          }
        }
        EXPECT_TRUE(found) << Where(file, n) << ": names " << name
                           << ", which is not a file of the repository";
      }
    }
  }
  EXPECT_GT(checked_links, 5) << "the README points into docs/ with links";
}

// --- README commands ----------------------------------------------------------

struct Shown {
  std::string where;
  std::vector<std::string> words;
};

// The lines of the README's code blocks: fenced (```) and indented (four
// spaces after a blank line or another code line), with the file line.
std::vector<std::pair<std::size_t, std::string>> CodeLines(const std::vector<std::string>& lines) {
  std::vector<std::pair<std::size_t, std::string>> code;
  bool fenced = false, indented = false, previous_blank = true;
  for (std::size_t n = 0; n < lines.size(); ++n) {
    const std::string& line = lines[n];
    if (line.starts_with("```")) {
      fenced = !fenced;
      continue;
    }
    const bool blank = line.find_first_not_of(' ') == std::string::npos;
    if (fenced) {
      code.emplace_back(n, line);
    } else if (line.starts_with("    ") && !blank && (previous_blank || indented)) {
      indented = true;
      code.emplace_back(n, line.substr(4));
    } else if (!blank) {
      indented = false;
    }
    previous_blank = blank;
  }
  return code;
}

// Shell words of one command line: quotes group words, `#` after a space
// starts a comment, `;`, `&&`, `||` and ` | ` separate commands.
std::vector<std::vector<std::string>> ShellCommands(const std::string& line) {
  std::vector<std::vector<std::string>> commands(1);
  std::string word;
  bool in_word = false;
  char quote = 0;
  int paren = 0;
  auto flush = [&] {
    if (in_word) commands.back().push_back(word);
    word.clear();
    in_word = false;
  };
  for (std::size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (quote) {
      if (c == quote)
        quote = 0;
      else
        word += c;
      continue;
    }
    if (c == '(' && i > 0 && line[i - 1] == '$') ++paren;
    if (c == ')' && paren > 0) --paren;
    if (paren > 0) {
      word += c;
      in_word = true;
      continue;
    }
    if (c == '"' || c == '\'') {
      quote = c;
      in_word = true;
    } else if (c == '#' && !in_word) {
      break;
    } else if (c == ' ' || c == '\t') {
      flush();
    } else if (c == ';' || (c == '|' && !in_word) || (c == '&' && !in_word)) {
      flush();
      if (i + 1 < line.size() && line[i + 1] == c) ++i;
      commands.emplace_back();
    } else {
      word += c;
      in_word = true;
    }
  }
  flush();
  std::erase_if(commands, [](const auto& c) { return c.empty(); });
  return commands;
}

std::vector<Shown> ReadmeCommands() {
  const fs::path readme = kRoot / "README.md";
  const std::vector<std::string> lines = Lines(ReadAll(readme));
  std::vector<Shown> shown;
  std::map<std::string, std::string> variables;
  std::string pending;
  std::size_t pending_line = 0;
  for (const auto& [n, raw] : CodeLines(lines)) {
    if (pending.empty()) pending_line = n;
    if (!raw.empty() && raw.back() == '\\') {
      pending += raw.substr(0, raw.size() - 1) + " ";
      continue;
    }
    const std::string line = pending + raw;
    pending.clear();
    for (std::vector<std::string> words : ShellCommands(line)) {
      const std::size_t eq = words[0].find('=');
      if (words.size() == 1 && eq != std::string::npos && eq > 0) {
        variables[words[0].substr(0, eq)] = words[0].substr(eq + 1);
        continue;
      }
      for (std::string& w : words) {
        if (w.starts_with("$") && variables.contains(w.substr(1))) w = variables[w.substr(1)];
        std::erase(w, '[');
        std::erase(w, ']');
      }
      std::erase_if(words, [](const std::string& w) { return w.empty(); });
      if (!words.empty()) shown.push_back({Where(readme, pending_line), words});
    }
  }
  return shown;
}

struct Outcome {
  int exit_code = -1;
  std::string output;  // stdout and stderr
};

Outcome RunProgram(const std::vector<std::string>& argv) {
  int pipe_fds[2];
  if (::pipe(pipe_fds) != 0) return {};
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::dup2(pipe_fds[1], STDOUT_FILENO);
    ::dup2(pipe_fds[1], STDERR_FILENO);
    ::close(pipe_fds[0]);
    const int null = ::open("/dev/null", O_RDONLY);
    ::dup2(null, STDIN_FILENO);
    std::vector<char*> args;
    for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    ::execv(args[0], args.data());
    ::_exit(127);
  }
  ::close(pipe_fds[1]);
  Outcome outcome;
  char buffer[4096];
  for (ssize_t n; (n = ::read(pipe_fds[0], buffer, sizeof buffer)) > 0;) {
    outcome.output.append(buffer, static_cast<std::size_t>(n));
  }
  ::close(pipe_fds[0]);
  int status = 0;
  ::waitpid(pid, &status, 0);
  outcome.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return outcome;
}

// The subcommand names a CLI11 help text lists under "SUBCOMMANDS:".
std::vector<std::string> Subcommands(const std::string& help) {
  std::vector<std::string> names;
  bool in_section = false;
  for (const std::string& line : Lines(help)) {
    std::string upper = line;
    std::transform(upper.begin(), upper.end(), upper.begin(), ::toupper);
    if (upper.starts_with("SUBCOMMANDS")) {
      in_section = true;
      continue;
    }
    if (!in_section) continue;
    if (line.empty() || line[0] != ' ') {
      in_section = !line.empty() && line[0] == ' ';
      continue;
    }
    std::istringstream words(line);
    std::string name;
    words >> name;
    if (!name.empty()) names.push_back(name);
  }
  return names;
}

const std::map<std::string, std::string>& Executables() {
  static const std::map<std::string, std::string> exes = {
      {"fesbench", FESBENCH_CLI_EXE},
      {"fesbench-server", FESBENCH_SERVER_EXE},
      {"fesbench-model", FESBENCH_MODEL_EXE},
      {"fesbench-sm2-emulator", FESBENCH_SM2_EMULATOR_EXE},
#ifdef FESBENCH_DDS_MONITOR_EXE
      {"fesbench-dds-monitor", FESBENCH_DDS_MONITOR_EXE},
#endif
  };
  return exes;
}

TEST(DocsTest, EveryReadmeCommandExists) {
  int checked = 0;
  std::map<std::string, int> per_program;
  for (const Shown& shown : ReadmeCommands()) {
    const std::string first = shown.words[0];
    if (first.starts_with("scripts/")) {
      const fs::path script = kRoot / first;
      ASSERT_TRUE(fs::exists(script)) << shown.where << ": no " << first;
      // By its own interpreter line (bash or python3).
      const Outcome help = RunProgram({script.string(), "--help"});
      EXPECT_EQ(help.exit_code, 0) << shown.where << ": " << first << " --help\n" << help.output;
      ++checked;
      ++per_program["scripts"];
      continue;
    }
    const auto exe = Executables().find(fs::path(first).filename().string());
    if (exe == Executables().end()) continue;  // curl, cat, ...
    std::vector<std::string> argv = {exe->second};
    std::string helps;
    std::size_t i = 1;
    for (;;) {
      std::vector<std::string> with_help = argv;
      with_help.push_back("--help");
      const Outcome help = RunProgram(with_help);
      ASSERT_EQ(help.exit_code, 0) << shown.where << ": `" << exe->first << " ... --help` failed:\n"
                                   << help.output;
      helps += help.output;
      if (i >= shown.words.size() || shown.words[i].starts_with("-")) break;
      const std::vector<std::string> subcommands = Subcommands(help.output);
      if (subcommands.empty()) break;  // a positional argument
      const std::string& word = shown.words[i];
      ASSERT_NE(std::find(subcommands.begin(), subcommands.end(), word), subcommands.end())
          << shown.where << ": `" << word << "` is not a command of " << exe->first
          << " (help lists: " << ::testing::PrintToString(subcommands) << ")";
      argv.push_back(word);
      ++i;
    }
    for (; i < shown.words.size(); ++i) {
      std::string flag = shown.words[i];
      if (!flag.starts_with("--")) continue;
      flag = flag.substr(0, flag.find('='));
      const std::regex listed("(^|[\\s,])" + flag + "([\\s,=]|$)");
      EXPECT_TRUE(std::regex_search(helps, listed)) << shown.where << ": " << flag
                                                    << " is not an option of `" << exe->first
                                                    << (argv.size() > 1 ? " " : "") <<
          [&] {
            std::string path;
            for (std::size_t k = 1; k < argv.size(); ++k) path += (k > 1 ? " " : "") + argv[k];
            return path;
          }() << "`";
    }
    ++checked;
    ++per_program[exe->first];
  }
  // The README shows every program (a parser that found nothing would pass).
  for (const auto& [name, _] : Executables()) {
    EXPECT_GT(per_program[name], 0) << "no command of " << name << " found in the README";
  }
  EXPECT_GT(per_program["scripts"], 0);
  EXPECT_GT(checked, 40);
}

TEST(DocsTest, EveryProgramSaysItsVersion) {
  for (const auto& [name, path] : Executables()) {
    const Outcome version = RunProgram({path, "--version"});
    EXPECT_EQ(version.exit_code, 0) << name << "\n" << version.output;
    EXPECT_EQ(version.output, name + " " + FESBENCH_VERSION + "\n");
  }
}

}  // namespace
