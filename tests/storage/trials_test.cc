#include "storage/trials.h"

#include <gtest/gtest.h>

#include <cmath>

#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "storage_test_util.h"

namespace fesbench::storage {
namespace {

using testing::MakeTrial;
using testing::StorageTest;

TEST_P(StorageTest, TrialRoundTripKeepsItsDeliveredPulsesExactly) {
  const Session session = MakeSession("T1");
  api::Trial trial = MakeTrial(400);
  api::PulseRecord pulses;
  pulses.pulse_rate_hz = 33.0;
  pulses.pulse_width_us = 250.0;
  for (int k = 17; k < 50; ++k) pulses.Append(k / 33.0, 20.0 + 0.1 * k);
  pulses.Append(1.7512345, 45.0);  // a single pulse off the grid
  trial.pulses = pulses;
  TrialRepository trials(*db_);
  auto id = trials.Insert({session.id, std::nullopt}, trial);
  ASSERT_TRUE(id.ok()) << id.status().ToString();
  auto back = trials.Get(*id);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  ASSERT_TRUE(back->pulses.has_value());
  EXPECT_EQ(*back->pulses, pulses);  // bit-exact
  // A trial without pulses stays without.
  auto plain = trials.Insert({session.id, std::nullopt}, MakeTrial(10));
  ASSERT_TRUE(plain.ok());
  EXPECT_FALSE(trials.Get(*plain)->pulses.has_value());
  // Invalid pulses are refused with the field named.
  trial.pulses->t_s[3] = trial.pulses->t_s[2] - 0.01;
  auto bad = trials.Insert({session.id, std::nullopt}, trial);
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().field(), "pulses.t_s[3]");
  // Append-only like every trial row.
  auto update = db_->Write(
      [](Connection& c) { return c.ExecScript("UPDATE trial_pulses SET pulse_count = 0"); });
  EXPECT_FALSE(update.ok());
}

TEST_P(StorageTest, TrialRoundTripKeepsItsDeviceCommandsExactly) {
  const Session session = MakeSession("T1D");
  api::Trial trial = MakeTrial(100);
  api::DeviceCommandLog log;
  log.device = "sciencemode4";
  log.pulse_rate_hz = 33.0;
  log.current_step_ma = 0.5;
  log.start_monotonic_ns = 987654321098765;
  for (int k = 0; k < 40; ++k) {
    log.t_s.push_back(k / 33.0 + 1e-4 * k);
    log.requested_ma.push_back(20.0 + 0.3 * k);
    log.commanded_ma.push_back(std::floor((20.0 + 0.3 * k) / 0.5) * 0.5);
    log.single_pulse.push_back(k % 7 == 0);
  }
  trial.device_commands = log;
  TrialRepository trials(*db_);
  auto id = trials.Insert({session.id, std::nullopt}, trial);
  ASSERT_TRUE(id.ok()) << id.status().ToString();
  auto back = trials.Get(*id);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  ASSERT_TRUE(back->device_commands.has_value());
  EXPECT_EQ(*back->device_commands, log);  // bit-exact
  auto plain = trials.Insert({session.id, std::nullopt}, MakeTrial(10));
  ASSERT_TRUE(plain.ok());
  EXPECT_FALSE(trials.Get(*plain)->device_commands.has_value());
  trial.device_commands->commanded_ma[5] = 100.0;
  auto bad = trials.Insert({session.id, std::nullopt}, trial);
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().field(), "device_commands.commanded_ma[5]");
  auto update = db_->Write([](Connection& c) {
    return c.ExecScript("UPDATE trial_device_commands SET command_count = 0");
  });
  EXPECT_FALSE(update.ok());
}

TEST_P(StorageTest, TrialRoundTripKeepsEveryChannelExactly) {
  const Session session = MakeSession("T1");
  auto run = SessionRepository(*db_).CreateRun(session.id, {"free_swing", "1.0", "{}"});
  ASSERT_TRUE(run.ok());
  api::Trial trial = MakeTrial(2000);
  // EMG at 1 kHz in its own group.
  api::ChannelGroup emg;
  emg.sample_rate_hz = 1000.0;
  std::vector<double> t(50), mv(50);
  for (int i = 0; i < 50; ++i) {
    t[static_cast<std::size_t>(i)] = i / 1000.0;
    mv[static_cast<std::size_t>(i)] = 0.001 * i - 0.02;
  }
  emg.Set("t_s", t);
  emg.Set("emg_mv", mv);
  trial.emg = emg;

  TrialRepository trials(*db_);
  auto id = trials.Insert({session.id, run->id}, trial);
  ASSERT_TRUE(id.ok()) << id.status().ToString();
  auto back = trials.Get(*id);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  api::Trial expected = trial;
  expected.id = *id;
  EXPECT_EQ(*back, expected);  // bit-exact samples, units, rates, names
  ASSERT_EQ(back->channels.size(), 4u);
  EXPECT_EQ(back->channels[2].unit, "N.m");
  EXPECT_EQ(back->emg->sample_rate_hz, 1000.0);

  auto owner = trials.Owner(*id);
  ASSERT_TRUE(owner.ok());
  EXPECT_EQ(owner->session_id, session.id);
  EXPECT_EQ(owner->run_id, run->id);
  auto list = trials.ListForSession(session.id);
  ASSERT_TRUE(list.ok());
  ASSERT_EQ(list->size(), 1u);
  EXPECT_EQ(list->front().num_samples, 2000u);
  EXPECT_EQ(list->front().sample_rate_hz, 200.0);
  EXPECT_EQ(list->front().name, "free_swing");

  // A run's trials by the run: only its own, oldest first.
  auto second_run = SessionRepository(*db_).CreateRun(session.id, {"free_swing", "1.0", "{}"});
  ASSERT_TRUE(second_run.ok());
  auto other = trials.Insert({session.id, second_run->id}, MakeTrial(5));
  auto later = trials.Insert({session.id, run->id}, MakeTrial(5));
  ASSERT_TRUE(other.ok() && later.ok());
  auto of_run = trials.IdsOfRun(run->id);
  ASSERT_TRUE(of_run.ok());
  EXPECT_EQ(*of_run, (std::vector<std::int64_t>{*id, *later}));
  EXPECT_EQ(*trials.IdsOfRun(second_run->id), std::vector<std::int64_t>{*other});
  EXPECT_TRUE(trials.IdsOfRun(31337)->empty());

  // The BLOB is 8 bytes per sample.
  auto bytes = db_->Read([&](Connection& c) {
    return c.QueryText("SELECT sum(length(samples_f64le)) FROM trial_channels WHERE grp = 'main'");
  });
  ASSERT_TRUE(bytes.ok());
  EXPECT_EQ(*bytes, std::to_string(4 * 2000 * 8 + 2 * 4 * 5 * 8));
}

TEST_P(StorageTest, TrialsAreStoredWithTheKindOfTheirName) {
  const Session session = MakeSession("K1");
  TrialRepository trials(*db_);
  api::Trial swing = MakeTrial(10);
  swing.name = "active_random_binary_rb1";  // a member of the "active" family
  auto swing_id = trials.Insert({session.id, std::nullopt}, swing);
  ASSERT_TRUE(swing_id.ok()) << swing_id.status().ToString();
  auto back = trials.Get(*swing_id);
  ASSERT_TRUE(back.ok());
  EXPECT_EQ(back->kind, api::TrialKind::kActive);

  api::Trial nameless = MakeTrial(10);  // "free_swing" is no kind
  auto nameless_id = trials.Insert({session.id, std::nullopt}, nameless);
  ASSERT_TRUE(nameless_id.ok());
  auto list = trials.ListForSession(session.id);
  ASSERT_TRUE(list.ok());
  ASSERT_EQ(list->size(), 2u);
  EXPECT_EQ((*list)[0].kind, api::TrialKind::kActive);
  EXPECT_EQ((*list)[1].kind, std::nullopt);

  // A kind that is not the name's is refused, naming the field.
  api::Trial wrong = MakeTrial(10);
  wrong.name = "free_swing_passive";
  wrong.kind = api::TrialKind::kActive;
  auto refused = trials.Insert({session.id, std::nullopt}, wrong);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.status().code(), api::ErrorCode::kInvalidArgument);
  EXPECT_EQ(refused.status().field(), "kind");
}

TEST_P(StorageTest, MigrationFourteenGivesTrialsStoredBeforeTheKindOfTheirName) {
  // A database at schema 13 whose trials have names but no kind column yet.
  std::unique_ptr<::fesbench::testing::ScratchDatabase> scratch;
  DatabaseOptions v13 = Options();
  if (GetParam() == Engine::kPostgres) {
    scratch = std::make_unique<::fesbench::testing::ScratchDatabase>();
    ASSERT_TRUE(scratch->ok()) << scratch->skip_reason();
    v13.path = scratch->url();
  } else {
    v13.path = (dir_ / "v13.db").string();
  }
  v13.target_schema_version = 13;
  const std::vector<std::pair<std::string, std::optional<std::string>>> names = {
      {"free_swing_passive", "free_swing_passive"},
      {"passive_simultaneous_3", "passive_simultaneous"},
      {"active_random_binary_rb1", "active_random_binary"},
      {"prediction_random_binary_s4", "prediction_random_binary"},
      {"rapid_isometric_ramp_irc", "rapid_isometric_ramp_irc"},
      {"active_", std::nullopt},  // a stem with no suffix
      {"t1", std::nullopt},
  };
  {
    auto db = Database::Open(v13);
    ASSERT_TRUE(db.ok()) << db.status().ToString();
    ASSERT_TRUE((*db)
                    ->Write([&](Connection& c) -> api::Status {
                      std::string sql =
                          "INSERT INTO subjects (id, code, created_at_utc) VALUES"
                          " (1, 'K2', '2026-01-01T00:00:00.000000Z');"
                          "INSERT INTO legs (id, subject_id, side, created_at_utc) VALUES"
                          " (1, 1, 'left', '2026-01-01T00:00:00.000000Z');"
                          "INSERT INTO sessions (id, subject_id, leg_id, created_at_utc) VALUES"
                          " (1, 1, 1, '2026-01-01T00:00:00.000000Z');";
                      for (std::size_t i = 0; i < names.size(); ++i) {
                        sql += "INSERT INTO trials (id, session_id, name, created_at_utc) VALUES (" +
                               std::to_string(i + 1) + ", 1, '" + names[i].first +
                               "', '2026-01-01T00:00:00.000000Z');";
                      }
                      return c.ExecScript(sql);
                    })
                    .ok());
  }
  DatabaseOptions latest = v13;
  latest.target_schema_version.reset();
  auto db = Database::Open(latest);
  ASSERT_TRUE(db.ok()) << db.status().ToString();
  for (std::size_t i = 0; i < names.size(); ++i) {
    auto kind = (*db)->Read([&](Connection& c) -> api::Result<std::string> {
      return c.QueryText("SELECT coalesce(kind, '-') FROM trials WHERE id = " +
                         std::to_string(i + 1));
    });
    ASSERT_TRUE(kind.ok()) << kind.status().ToString();
    EXPECT_EQ(*kind, names[i].second.value_or("-")) << names[i].first;
    // The back-fill agrees with the kind the name has today.
    const std::optional<api::TrialKind> today = api::TrialKindOf(names[i].first);
    EXPECT_EQ(today ? std::string(api::TrialKindName(*today)) : "-", *kind) << names[i].first;
  }
  // trials is append-only again after the back-fill.
  auto update = (*db)->Write(
      [](Connection& c) { return c.ExecScript("UPDATE trials SET kind = 'tracking' WHERE id = 7"); });
  EXPECT_FALSE(update.ok());
}

TEST_P(StorageTest, TrialBadInputNamesTheProblem) {
  const Session session = MakeSession("T2");
  TrialRepository trials(*db_);
  EXPECT_EQ(trials.Insert({999, std::nullopt}, MakeTrial(5)).status().message(),
            "session 999 not found");
  EXPECT_EQ(trials.Insert({session.id, 42}, MakeTrial(5)).status().message(), "run 42 not found");
  const Session other = MakeSession("T3");
  auto other_run = SessionRepository(*db_).CreateRun(other.id, {"p", "1", "{}"});
  ASSERT_TRUE(other_run.ok());
  EXPECT_EQ(trials.Insert({session.id, other_run->id}, MakeTrial(5)).status().field(), "run_id");
  api::Trial bad = MakeTrial(5);
  bad.channels[1].values.pop_back();  // ragged
  auto invalid = trials.Insert({session.id, std::nullopt}, bad);
  EXPECT_EQ(invalid.status().code(), api::ErrorCode::kInvalidArgument);
  EXPECT_FALSE(invalid.status().field().empty());
  EXPECT_EQ(trials.Get(31337).status().message(), "trial 31337 not found");
  auto none = trials.ListForSession(session.id);
  ASSERT_TRUE(none.ok());
  EXPECT_TRUE(none->empty());
}

}  // namespace
}  // namespace fesbench::storage
