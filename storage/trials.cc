#include "storage/trials.h"

#include "storage/row_helpers.h"

namespace fesbench::storage {
namespace {

api::Status InsertChannels(Connection& c, std::int64_t trial_id, std::string_view group,
                           double rate_hz, const std::vector<api::Channel>& channels) {
  for (std::size_t i = 0; i < channels.size(); ++i) {
    const api::Channel& channel = channels[i];
    auto insert = c.Prepare(
        "INSERT INTO trial_channels (trial_id, grp, ordinal, name, unit, sample_rate_hz,"
        " sample_count, samples_f64le) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8)");
    if (!insert.ok()) return insert.status();
    const std::vector<std::byte> blob = PackFloat64Le(channel.values);
    insert->Bind(1, trial_id)
        .Bind(2, group)
        .Bind(3, static_cast<std::int64_t>(i))
        .Bind(4, channel.name)
        .Bind(5, channel.unit)
        .Bind(6, rate_hz)
        .Bind(7, static_cast<std::int64_t>(channel.values.size()))
        .BindBlob(8, blob);
    if (auto s = insert->Run(); !s.ok()) return s;
  }
  return api::Status::Ok();
}

api::Result<api::Trial> GetTrialIn(Connection& c, std::int64_t id) {
  auto head = c.Prepare("SELECT name, start_time_unix_ms FROM trials WHERE id = ?1");
  if (!head.ok()) return head.status();
  head->Bind(1, id);
  auto found = head->Step();
  if (!found.ok()) return found.status();
  if (!*found) return api::Status::NotFound("trial " + std::to_string(id) + " not found");
  api::Trial trial;
  trial.id = id;
  if (!head->IsNull(0)) trial.name = head->Text(0);
  trial.start_time_unix_ms = head->OptionalInt64(1);

  auto channels = c.Prepare(
      "SELECT grp, name, unit, sample_rate_hz, sample_count, samples_f64le FROM trial_channels"
      " WHERE trial_id = ?1 ORDER BY grp DESC, ordinal");  // 'main' before 'emg'
  if (!channels.ok()) return channels.status();
  channels->Bind(1, id);
  while (true) {
    auto row = channels->Step();
    if (!row.ok()) return row.status();
    if (!*row) break;
    const std::string group = channels->Text(0);
    auto values = UnpackFloat64Le(channels->Blob(5));
    if (!values || values->size() != static_cast<std::size_t>(channels->Int64(4))) {
      return internal::BadStoredValue("samples of trial " + std::to_string(id));
    }
    api::Channel channel{channels->Text(1), channels->Text(2), std::move(*values)};
    const double rate_hz = channels->Double(3);
    if (group == "main") {
      trial.sample_rate_hz = rate_hz;
      trial.channels.push_back(std::move(channel));
    } else {
      if (!trial.emg) trial.emg = api::ChannelGroup{rate_hz, {}};
      trial.emg->channels.push_back(std::move(channel));
    }
  }
  return trial;
}

}  // namespace

api::Result<std::int64_t> TrialRepository::Insert(const TrialOwner& owner,
                                                  const api::Trial& trial) {
  if (auto s = api::ValidateTrial(trial); !s.ok()) return s;
  return db_.Write([&](Connection& c) -> api::Result<std::int64_t> {
    if (auto s = internal::RequireRow(c, "SELECT 1 FROM sessions WHERE id = ?1", owner.session_id,
                                      "session");
        !s.ok()) {
      return s;
    }
    if (owner.run_id) {
      auto run = c.Prepare("SELECT session_id FROM runs WHERE id = ?1");
      if (!run.ok()) return run.status();
      run->Bind(1, *owner.run_id);
      auto found = run->Step();
      if (!found.ok()) return found.status();
      if (!*found)
        return api::Status::NotFound("run " + std::to_string(*owner.run_id) + " not found");
      if (run->Int64(0) != owner.session_id) {
        return api::Status::InvalidArgument(
            "run " + std::to_string(*owner.run_id) + " belongs to another session", "run_id");
      }
    }
    auto insert = c.Prepare(
        "INSERT INTO trials (session_id, run_id, name, start_time_unix_ms, created_at_utc)"
        " VALUES (?1, ?2, ?3, ?4, ?5)");
    if (!insert.ok()) return insert.status();
    insert->Bind(1, owner.session_id)
        .Bind(2, owner.run_id)
        .Bind(3, trial.name)
        .Bind(4, trial.start_time_unix_ms)
        .Bind(5, FormatUtc(db_.Now()));
    if (auto s = insert->Run(); !s.ok()) return s;
    const std::int64_t id = c.LastInsertRowId();
    if (auto s = InsertChannels(c, id, "main", trial.sample_rate_hz, trial.channels); !s.ok()) {
      return s;
    }
    if (trial.emg) {
      if (auto s = InsertChannels(c, id, "emg", trial.emg->sample_rate_hz, trial.emg->channels);
          !s.ok()) {
        return s;
      }
    }
    return id;
  });
}

api::Result<api::Trial> TrialRepository::Get(std::int64_t trial_id) {
  return db_.Read([&](Connection& c) { return GetTrialIn(c, trial_id); });
}

api::Result<TrialOwner> TrialRepository::Owner(std::int64_t trial_id) {
  return db_.Read([&](Connection& c) -> api::Result<TrialOwner> {
    auto statement = c.Prepare("SELECT session_id, run_id FROM trials WHERE id = ?1");
    if (!statement.ok()) return statement.status();
    statement->Bind(1, trial_id);
    auto found = statement->Step();
    if (!found.ok()) return found.status();
    if (!*found) return api::Status::NotFound("trial " + std::to_string(trial_id) + " not found");
    return TrialOwner{statement->Int64(0), statement->OptionalInt64(1)};
  });
}

api::Result<std::vector<TrialSummary>> TrialRepository::ListForSession(std::int64_t session_id) {
  return db_.Read([&](Connection& c) -> api::Result<std::vector<TrialSummary>> {
    if (auto s =
            internal::RequireRow(c, "SELECT 1 FROM sessions WHERE id = ?1", session_id, "session");
        !s.ok()) {
      return s;
    }
    auto statement = c.Prepare(
        "SELECT t.id, t.session_id, t.run_id, t.name, t.created_at_utc,"
        " (SELECT sample_count FROM trial_channels WHERE trial_id = t.id AND grp = 'main'"
        "  AND ordinal = 0),"
        " (SELECT sample_rate_hz FROM trial_channels WHERE trial_id = t.id AND grp = 'main'"
        "  AND ordinal = 0)"
        " FROM trials t WHERE t.session_id = ?1 ORDER BY t.id");
    if (!statement.ok()) return statement.status();
    statement->Bind(1, session_id);
    std::vector<TrialSummary> trials;
    while (true) {
      auto row = statement->Step();
      if (!row.ok()) return row.status();
      if (!*row) break;
      TrialSummary t;
      t.id = statement->Int64(0);
      t.session_id = statement->Int64(1);
      t.run_id = statement->OptionalInt64(2);
      if (!statement->IsNull(3)) t.name = statement->Text(3);
      const auto created = ParseUtc(statement->Text(4));
      if (!created) return internal::BadStoredValue("trial");
      t.created_at = *created;
      t.num_samples = static_cast<std::size_t>(statement->Int64(5));
      t.sample_rate_hz = statement->Double(6);
      trials.push_back(std::move(t));
    }
    return trials;
  });
}

}  // namespace fesbench::storage
