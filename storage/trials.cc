#include "storage/trials.h"

#include <algorithm>
#include <cstdint>

#include "storage/row_helpers.h"

namespace fesbench::storage {
namespace {

api::Status InsertChannels(Connection& c, std::int64_t trial_id, std::string_view group,
                           double rate_hz, const std::vector<api::Channel>& channels) {
  for (std::size_t i = 0; i < channels.size(); ++i) {
    const api::Channel& channel = channels[i];
    if (auto s = internal::Execute(
            c,
            "INSERT INTO trial_channels (trial_id, grp, ordinal, name, unit, sample_rate_hz,"
            " sample_count, samples_f64le) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8)",
            trial_id, group, static_cast<std::int64_t>(i), channel.name, channel.unit, rate_hz,
            static_cast<std::int64_t>(channel.values.size()), PackFloat64Le(channel.values));
        !s.ok()) {
      return s;
    }
  }
  return api::Status::Ok();
}

// One stored channel with its group ('main' or 'emg') and rate.
struct StoredChannel {
  std::string group;
  double rate_hz = 0;
  api::Channel channel;
};

// The kind column (NULL for a name of no kind, or a kind this build does
// not know).
std::optional<api::TrialKind> KindColumn(const Statement& s, int column) {
  if (s.IsNull(column)) return std::nullopt;
  return api::ParseTrialKind(s.Text(column));
}

// The kind a trial is stored with: its own, else its name's.
std::optional<std::string> StoredKind(const api::Trial& trial) {
  std::optional<api::TrialKind> kind = trial.kind;
  if (!kind && trial.name) kind = api::TrialKindOf(*trial.name);
  if (!kind) return std::nullopt;
  return std::string(api::TrialKindName(*kind));
}

api::Result<api::Trial> GetTrialIn(Connection& c, std::int64_t id) {
  auto head = internal::One(internal::QueryRows(
                                c, "SELECT name, start_time_unix_ms, kind FROM trials WHERE id = ?1",
                                [&](const Statement& s) {
                                  api::Trial trial;
                                  trial.id = id;
                                  if (!s.IsNull(0)) trial.name = s.Text(0);
                                  trial.start_time_unix_ms = s.OptionalInt64(1);
                                  trial.kind = KindColumn(s, 2);
                                  return trial;
                                },
                                id),
                            "trial", id);
  if (!head.ok()) return head.status();
  api::Trial trial = std::move(*head);

  auto channels = internal::QueryRows(
      c,
      "SELECT grp, name, unit, sample_rate_hz, sample_count, samples_f64le FROM trial_channels"
      " WHERE trial_id = ?1 ORDER BY grp DESC, ordinal",  // 'main' before 'emg'
      [&](const Statement& s) -> api::Result<StoredChannel> {
        auto values = UnpackFloat64Le(s.Blob(5));
        if (!values || values->size() != static_cast<std::size_t>(s.Int64(4))) {
          return internal::BadStoredValue("samples of trial " + std::to_string(id));
        }
        // Channels stored before ChannelUnit knew their suffix (accel_m_s2)
        // have an empty unit: read them with the unit their name gives.
        std::string unit = s.Text(2);
        if (unit.empty()) unit = api::ChannelUnit(s.Text(1));
        return StoredChannel{
            s.Text(0), s.Double(3), {s.Text(1), std::move(unit), std::move(*values)}};
      },
      id);
  if (!channels.ok()) return channels.status();
  auto pulses = internal::QueryRows(
      c,
      "SELECT pulse_rate_hz, pulse_width_us, pulse_count, t_s_f64le, stim_ma_f64le"
      " FROM trial_pulses WHERE trial_id = ?1",
      [&](const Statement& s) -> api::Result<api::PulseRecord> {
        auto t = UnpackFloat64Le(s.Blob(3));
        auto u = UnpackFloat64Le(s.Blob(4));
        const auto count = static_cast<std::size_t>(s.Int64(2));
        if (!t || !u || t->size() != count || u->size() != count) {
          return internal::BadStoredValue("pulses of trial " + std::to_string(id));
        }
        return api::PulseRecord{s.Double(0), s.Double(1), std::move(*t), std::move(*u)};
      },
      id);
  if (!pulses.ok()) return pulses.status();
  if (!pulses->empty()) trial.pulses = std::move(pulses->front());
  auto commands = internal::QueryRows(
      c,
      "SELECT device, pulse_rate_hz, current_step_ma, start_monotonic_ns, command_count,"
      " t_s_f64le, requested_ma_f64le, commanded_ma_f64le, single_pulse_u8"
      " FROM trial_device_commands WHERE trial_id = ?1",
      [&](const Statement& s) -> api::Result<api::DeviceCommandLog> {
        const auto count = static_cast<std::size_t>(s.Int64(4));
        auto t = UnpackFloat64Le(s.Blob(5));
        auto requested = UnpackFloat64Le(s.Blob(6));
        auto commanded = UnpackFloat64Le(s.Blob(7));
        const auto single = s.Blob(8);
        if (!t || !requested || !commanded || t->size() != count || requested->size() != count ||
            commanded->size() != count || single.size() != count) {
          return internal::BadStoredValue("device commands of trial " + std::to_string(id));
        }
        api::DeviceCommandLog log;
        log.device = s.Text(0);
        log.pulse_rate_hz = s.Double(1);
        log.current_step_ma = s.Double(2);
        log.start_monotonic_ns = s.Int64(3);
        log.t_s = std::move(*t);
        log.requested_ma = std::move(*requested);
        log.commanded_ma = std::move(*commanded);
        for (std::byte b : single) log.single_pulse.push_back(b != std::byte{0});
        return log;
      },
      id);
  if (!commands.ok()) return commands.status();
  if (!commands->empty()) trial.device_commands = std::move(commands->front());
  for (StoredChannel& stored : *channels) {
    if (stored.group == "main") {
      trial.sample_rate_hz = stored.rate_hz;
      trial.channels.push_back(std::move(stored.channel));
    } else {
      if (!trial.emg) trial.emg = api::ChannelGroup{stored.rate_hz, {}};
      trial.emg->channels.push_back(std::move(stored.channel));
    }
  }
  return trial;
}

}  // namespace

api::Result<std::int64_t> TrialRepository::Insert(const TrialOwner& owner, const api::Trial& trial,
                                                  const std::optional<TrialImport>& import) {
  if (auto s = api::ValidateTrial(trial); !s.ok()) return s;
  return db_.Write([&](Connection& c) -> api::Result<std::int64_t> {
    if (auto s = internal::RequireRow(c, "SELECT 1 FROM sessions WHERE id = ?1", owner.session_id,
                                      "session");
        !s.ok()) {
      return s;
    }
    if (owner.run_id) {
      auto run_session = internal::LookupInt64(c, "SELECT session_id FROM runs WHERE id = ?1",
                                               *owner.run_id, "run");
      if (!run_session.ok()) return run_session.status();
      if (*run_session != owner.session_id) {
        return api::Status::InvalidArgument(
            "run " + std::to_string(*owner.run_id) + " belongs to another session", "run_id");
      }
    }
    auto inserted = internal::InsertRow(
        c,
        "INSERT INTO trials (session_id, run_id, name, start_time_unix_ms, created_at_utc, kind)"
        " VALUES (?1, ?2, ?3, ?4, ?5, ?6)",
        owner.session_id, owner.run_id, trial.name, trial.start_time_unix_ms, api::FormatUtc(db_.Now()),
        StoredKind(trial));
    if (!inserted.ok()) return inserted.status();
    const std::int64_t id = *inserted;
    if (auto s = InsertChannels(c, id, "main", trial.sample_rate_hz, trial.channels); !s.ok()) {
      return s;
    }
    if (trial.emg) {
      if (auto s = InsertChannels(c, id, "emg", trial.emg->sample_rate_hz, trial.emg->channels);
          !s.ok()) {
        return s;
      }
    }
    if (trial.pulses) {
      const api::PulseRecord& p = *trial.pulses;
      if (auto s = internal::Execute(
              c,
              "INSERT INTO trial_pulses (trial_id, pulse_rate_hz, pulse_width_us, pulse_count,"
              " t_s_f64le, stim_ma_f64le) VALUES (?1, ?2, ?3, ?4, ?5, ?6)",
              id, p.pulse_rate_hz, p.pulse_width_us, static_cast<std::int64_t>(p.size()),
              PackFloat64Le(p.t_s), PackFloat64Le(p.stim_ma));
          !s.ok()) {
        return s;
      }
    }
    if (trial.device_commands) {
      const api::DeviceCommandLog& d = *trial.device_commands;
      std::vector<std::byte> single;
      for (bool b : d.single_pulse) single.push_back(b ? std::byte{1} : std::byte{0});
      if (auto s = internal::Execute(
              c,
              "INSERT INTO trial_device_commands (trial_id, device, pulse_rate_hz, current_step_ma,"
              " start_monotonic_ns, command_count, t_s_f64le, requested_ma_f64le,"
              " commanded_ma_f64le, single_pulse_u8) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9,"
              " ?10)",
              id, d.device, d.pulse_rate_hz, d.current_step_ma, d.start_monotonic_ns,
              static_cast<std::int64_t>(d.size()), PackFloat64Le(d.t_s),
              PackFloat64Le(d.requested_ma), PackFloat64Le(d.commanded_ma), single);
          !s.ok()) {
        return s;
      }
    }
    if (import) {
      if (auto s = internal::Execute(
              c,
              "INSERT INTO trial_imports (trial_id, format, source, spec_json, imported_by,"
              " original_trial_id) VALUES (?1, ?2, ?3, ?4, ?5, ?6)",
              id, import->format, import->source, import->spec_json, import->imported_by,
              import->original_trial_id);
          !s.ok()) {
        return s;
      }
    }
    return id;
  });
}

api::Result<std::map<std::int64_t, std::int64_t>> TrialRepository::ImportedOriginals(
    std::int64_t session_id) {
  return db_.Read([&](Connection& c) -> api::Result<std::map<std::int64_t, std::int64_t>> {
    auto rows = internal::QueryRows(
        c,
        "SELECT i.original_trial_id, t.id FROM trial_imports i JOIN trials t ON t.id = i.trial_id"
        " WHERE t.session_id = ?1 AND i.original_trial_id IS NOT NULL",
        [](const Statement& s) {
          return std::pair{s.Int64(0), s.Int64(1)};
        },
        session_id);
    if (!rows.ok()) return rows.status();
    return std::map<std::int64_t, std::int64_t>(rows->begin(), rows->end());
  });
}

api::Result<std::optional<TrialImport>> TrialRepository::ImportOf(std::int64_t trial_id) {
  return db_.Read([&](Connection& c) -> api::Result<std::optional<TrialImport>> {
    if (auto s = internal::RequireRow(c, "SELECT 1 FROM trials WHERE id = ?1", trial_id, "trial");
        !s.ok()) {
      return s;
    }
    auto rows = internal::QueryRows(
        c,
        "SELECT format, source, spec_json, imported_by, original_trial_id FROM trial_imports"
        " WHERE trial_id = ?1",
        [](const Statement& s) {
          return TrialImport{s.Text(0), s.Text(1), s.Text(2), s.Text(3), s.OptionalInt64(4)};
        },
        trial_id);
    if (!rows.ok()) return rows.status();
    if (rows->empty()) return std::optional<TrialImport>();
    return std::optional<TrialImport>(std::move(rows->front()));
  });
}

api::Result<api::Trial> TrialRepository::Get(std::int64_t trial_id) {
  return db_.Read([&](Connection& c) { return GetTrialIn(c, trial_id); });
}

api::Result<TrialOwner> TrialRepository::Owner(std::int64_t trial_id) {
  return db_.Read([&](Connection& c) -> api::Result<TrialOwner> {
    return internal::One(internal::QueryRows(
                             c, "SELECT session_id, run_id FROM trials WHERE id = ?1",
                             [](const Statement& s) {
                               return TrialOwner{s.Int64(0), s.OptionalInt64(1)};
                             },
                             trial_id),
                         "trial", trial_id);
  });
}

api::Result<std::vector<std::int64_t>> TrialRepository::IdsOfRun(std::int64_t run_id) {
  return db_.Read([&](Connection& c) -> api::Result<std::vector<std::int64_t>> {
    return internal::QueryRows(
        c, "SELECT id FROM trials WHERE run_id = ?1 ORDER BY id",
        [](const Statement& s) -> api::Result<std::int64_t> { return s.Int64(0); }, run_id);
  });
}

api::Result<std::vector<TrialSummary>> TrialRepository::ListForSession(std::int64_t session_id) {
  return ListForSessionPage(session_id, 0, static_cast<std::size_t>(INT64_MAX));
}

api::Result<std::vector<TrialSummary>> TrialRepository::ListForSessionPage(std::int64_t session_id,
                                                                           std::int64_t after_id,
                                                                           std::size_t limit) {
  return db_.Read([&](Connection& c) -> api::Result<std::vector<TrialSummary>> {
    if (auto s =
            internal::RequireRow(c, "SELECT 1 FROM sessions WHERE id = ?1", session_id, "session");
        !s.ok()) {
      return s;
    }
    return internal::QueryRows(
        c,
        "SELECT t.id, t.session_id, t.run_id, t.name, t.created_at_utc,"
        " (SELECT sample_count FROM trial_channels WHERE trial_id = t.id AND grp = 'main'"
        "  AND ordinal = 0),"
        " (SELECT sample_rate_hz FROM trial_channels WHERE trial_id = t.id AND grp = 'main'"
        "  AND ordinal = 0), t.kind"
        " FROM trials t WHERE t.session_id = ?1 AND t.id > ?2 ORDER BY t.id LIMIT ?3",
        [](const Statement& s) -> api::Result<TrialSummary> {
          TrialSummary t;
          t.id = s.Int64(0);
          t.session_id = s.Int64(1);
          t.run_id = s.OptionalInt64(2);
          if (!s.IsNull(3)) t.name = s.Text(3);
          const auto created = api::ParseUtc(s.Text(4));
          if (!created) return internal::BadStoredValue("trial");
          t.created_at = *created;
          t.num_samples = static_cast<std::size_t>(s.Int64(5));
          t.sample_rate_hz = s.Double(6);
          t.kind = KindColumn(s, 7);
          return t;
        },
        session_id, after_id, static_cast<std::int64_t>(std::min<std::size_t>(limit, INT64_MAX)));
  });
}

}  // namespace fesbench::storage
