// Crash safety (integration): a child process writes trials and parameter
// sets in a loop and acknowledges each committed id through a pipe; the
// parent kills it with SIGKILL at seeded random moments, then reopens the
// file. After every kill the database must open (integrity_check at open),
// and every write the child acknowledged must be present and intact.

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <thread>

#include "storage/database.h"
#include "storage/parameter_sets.h"
#include "storage/sessions.h"
#include "storage/subjects.h"
#include "storage/trials.h"
#include "storage_test_util.h"

namespace fesbench::storage {
namespace {

constexpr std::size_t kSamples = 50;

double PhaseOf(long long seq) { return 0.001 * static_cast<double>(seq); }
double PoleOf(long long seq) { return 10.0 + 0.01 * static_cast<double>(seq % 1000); }

bool SendLine(int fd, const std::string& line) {
  // Lines are far below PIPE_BUF, so each write is atomic: a kill never
  // leaves half an acknowledgement.
  return ::write(fd, line.data(), line.size()) == static_cast<ssize_t>(line.size());
}

// The child: writes until killed. Acknowledges only after commit.
[[noreturn]] void ChildLoop(const std::string& path, int fd, std::int64_t subject_id,
                            std::int64_t leg_id, std::int64_t session_id, long long seq) {
  ::signal(SIGPIPE, SIG_IGN);
  DatabaseOptions options;
  options.path = path;
  options.reader_count = 1;
  auto db = Database::Open(options);
  if (!db.ok()) {
    SendLine(fd, "E " + db.status().ToString() + "\n");
    ::_exit(2);
  }
  TrialRepository trials(**db);
  ParameterSetRepository sets(**db);
  while (true) {
    auto trial_id =
        trials.Insert({session_id, std::nullopt}, testing::MakeTrial(kSamples, PhaseOf(seq)));
    if (!trial_id.ok()) {
      SendLine(fd, "E " + trial_id.status().ToString() + "\n");
      ::_exit(3);
    }
    if (!SendLine(fd, "T " + std::to_string(*trial_id) + " " + std::to_string(seq) + "\n")) {
      ::_exit(4);
    }
    if (seq % 2 == 0) {
      model::ParameterSet params = model::ExampleParameterSet();
      params.contraction.pole_per_s = PoleOf(seq);
      params.provenance.trial_ids = {*trial_id};
      auto set = sets.Insert({subject_id, leg_id, params, std::nullopt, std::nullopt});
      if (!set.ok()) {
        SendLine(fd, "E " + set.status().ToString() + "\n");
        ::_exit(5);
      }
      if (!SendLine(fd, "P " + std::to_string(set->id) + " " + std::to_string(seq) + "\n")) {
        ::_exit(6);
      }
    }
    ++seq;
  }
}

TEST(StorageCrash, AcknowledgedWritesSurviveSigkill) {
  const auto dir = testing::MakeTempDir("crash");
  const std::string path = (dir / "crash.db").string();
  DatabaseOptions options;
  options.path = path;
  std::int64_t subject_id = 0;
  std::int64_t leg_id = 0;
  std::int64_t session_id = 0;
  {
    auto db = Database::Open(options);
    ASSERT_TRUE(db.ok());
    auto subject = SubjectRepository(**db).Create("CRASH", SubjectDetails{});
    ASSERT_TRUE(subject.ok());
    auto leg = SubjectRepository(**db).AddLeg(subject->id, Side::kRight);
    ASSERT_TRUE(leg.ok());
    auto session =
        SessionRepository(**db).Create(subject->id, leg->id, {"2026-05-06", "shank", {}, {}, ""});
    ASSERT_TRUE(session.ok());
    subject_id = subject->id;
    leg_id = leg->id;
    session_id = session->id;
  }  // closed before any fork: no connection crosses a fork

  constexpr int kKills = 60;
  std::mt19937 rng(20261121);
  std::uniform_int_distribution<int> delay_us(0, 120000);
  std::map<std::int64_t, long long> acked_trials;  // id → seq
  std::map<std::int64_t, long long> acked_sets;
  int killed = 0;
  for (int k = 0; k < kKills; ++k) {
    int fds[2];
    ASSERT_EQ(::pipe(fds), 0);
    const long long first_seq = static_cast<long long>(k) * 1000000;
    const pid_t pid = ::fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
      ::close(fds[0]);
      ChildLoop(path, fds[1], subject_id, leg_id, session_id, first_seq);
    }
    ::close(fds[1]);
    std::this_thread::sleep_for(std::chrono::microseconds(delay_us(rng)));
    ASSERT_EQ(::kill(pid, SIGKILL), 0);
    int wait_status = 0;
    ASSERT_EQ(::waitpid(pid, &wait_status, 0), pid);
    if (WIFSIGNALED(wait_status) && WTERMSIG(wait_status) == SIGKILL) ++killed;

    std::string text;
    char buffer[4096];
    ssize_t n = 0;
    while ((n = ::read(fds[0], buffer, sizeof buffer)) > 0)
      text.append(buffer, static_cast<std::size_t>(n));
    ::close(fds[0]);
    std::istringstream lines(text);
    std::string kind;
    std::map<std::int64_t, long long> new_trials;
    std::map<std::int64_t, long long> new_sets;
    while (lines >> kind) {
      ASSERT_NE(kind, "E") << "child failed: " << text;
      std::int64_t id = 0;
      long long seq = 0;
      lines >> id >> seq;
      (kind == "T" ? new_trials : new_sets)[id] = seq;
    }

    // Reopen after the crash: integrity_check runs at open.
    auto db = Database::Open(options);
    ASSERT_TRUE(db.ok()) << "after kill " << k << ": " << db.status().ToString();
    TrialRepository trials(**db);
    ParameterSetRepository sets(**db);
    for (const auto& [id, seq] : new_trials) {
      auto trial = trials.Get(id);
      ASSERT_TRUE(trial.ok()) << "acknowledged trial " << id << " lost after kill " << k;
      api::Trial expected = testing::MakeTrial(kSamples, PhaseOf(seq));
      expected.id = id;
      ASSERT_EQ(*trial, expected) << "trial " << id;
    }
    for (const auto& [id, seq] : new_sets) {
      auto set = sets.Get(id);
      ASSERT_TRUE(set.ok()) << "acknowledged parameter set " << id << " lost after kill " << k;
      EXPECT_EQ(set->params.contraction.pole_per_s, PoleOf(seq));
      ASSERT_EQ(set->trial_ids.size(), 1u);
      EXPECT_EQ(set->summary.subject_id, subject_id);
    }
    acked_trials.insert(new_trials.begin(), new_trials.end());
    acked_sets.insert(new_sets.begin(), new_sets.end());
  }
  EXPECT_EQ(killed, kKills);
  // The test must have exercised real writes, not just kills during open.
  EXPECT_GT(acked_trials.size(), 100u);
  EXPECT_GT(acked_sets.size(), 50u);

  // Final pass: every acknowledged write, from every round, is still there.
  auto db = Database::Open(options);
  ASSERT_TRUE(db.ok()) << db.status().ToString();
  EXPECT_TRUE((*db)->CheckIntegrity().ok());
  TrialRepository trials(**db);
  ParameterSetRepository sets(**db);
  for (const auto& [id, seq] : acked_trials) {
    auto trial = trials.Get(id);
    ASSERT_TRUE(trial.ok()) << "trial " << id;
    EXPECT_EQ(trial->channels[1].values,
              testing::MakeTrial(kSamples, PhaseOf(seq)).channels[1].values);
  }
  for (const auto& [id, seq] : acked_sets) {
    auto set = sets.Get(id);
    ASSERT_TRUE(set.ok()) << "parameter set " << id;
    EXPECT_EQ(set->params.contraction.pole_per_s, PoleOf(seq));
  }
  auto history =
      sets.History({subject_id, leg_id, std::nullopt, std::nullopt, std::nullopt, 1000000});
  ASSERT_TRUE(history.ok());
  EXPECT_GE(history->size(), acked_sets.size());
  // Versions stay a gap-free sequence 1..N: no half-written set survived.
  for (std::size_t i = 0; i < history->size(); ++i) {
    EXPECT_EQ((*history)[i].version, static_cast<int>(i + 1));
  }
  std::printf("crash test: %d kills, %zu trials and %zu parameter sets acknowledged\n", killed,
              acked_trials.size(), acked_sets.size());
  db->reset();
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace fesbench::storage
