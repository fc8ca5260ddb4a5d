#include "storage/parameter_sets.h"

#include <algorithm>
#include <nlohmann/json.hpp>
#include <set>

#include "api/parameter_set_json.h"
#include "storage/row_helpers.h"

#ifndef FESBENCH_VERSION
#define FESBENCH_VERSION "unknown"
#endif

namespace fesbench::storage {
namespace {

constexpr std::string_view kSummaryColumns =
    "id, subject_id, leg_id, version, model, irc_method, passive_method, active_method,"
    " software_version, supersedes_id, created_at_utc, run_id";

api::Result<ParameterSetSummary> ReadSummary(const Statement& s) {
  ParameterSetSummary summary;
  summary.id = s.Int64(0);
  summary.subject_id = s.Int64(1);
  summary.leg_id = s.Int64(2);
  summary.version = static_cast<int>(s.Int64(3));
  summary.model = s.Text(4);
  summary.irc_method = s.Text(5);
  summary.passive_method = s.Text(6);
  summary.active_method = s.Text(7);
  summary.software_version = s.Text(8);
  summary.supersedes_id = s.OptionalInt64(9);
  const auto created = api::ParseUtc(s.Text(10));
  if (!created) return internal::BadStoredValue("parameter set");
  summary.created_at = *created;
  summary.run_id = s.OptionalInt64(11);
  return summary;
}

api::Result<StoredParameterSet> GetIn(Connection& c, std::int64_t id) {
  auto head = internal::One(
      internal::QueryRows(
          c,
          "SELECT " + std::string(kSummaryColumns) +
              ", params_json FROM parameter_sets WHERE id = ?1",
          [](const Statement& s) -> api::Result<std::pair<ParameterSetSummary, std::string>> {
            auto summary = ReadSummary(s);
            if (!summary.ok()) return summary.status();
            return std::pair{std::move(*summary), s.Text(12)};
          },
          id),
      "parameter set", id);
  if (!head.ok()) return head.status();
  auto& [summary, json_text] = *head;
  const nlohmann::json json = nlohmann::json::parse(json_text, nullptr,
                                                    /*allow_exceptions=*/false);
  if (json.is_discarded()) return internal::BadStoredValue("parameter set JSON");
  auto params = api::ParameterSetFromJson(json);
  if (!params.ok()) {
    return api::Status::DataLoss("stored parameter set " + std::to_string(id) +
                                 " no longer validates: " + params.status().ToString());
  }
  auto trial_ids = internal::QueryRows(
      c, "SELECT trial_id FROM parameter_set_trials WHERE parameter_set_id = ?1 ORDER BY trial_id",
      [](const Statement& s) { return s.Int64(0); }, id);
  if (!trial_ids.ok()) return trial_ids.status();
  return StoredParameterSet{std::move(summary), std::move(*params), std::move(*trial_ids)};
}

// Checks that trial `trial_id` exists and belongs to `subject_id`.
api::Status CheckTrial(Connection& c, std::int64_t trial_id, std::int64_t subject_id,
                       const std::string& field) {
  auto owner = internal::LookupInt64(
      c, "SELECT s.subject_id FROM trials t JOIN sessions s ON s.id = t.session_id WHERE t.id = ?1",
      trial_id, "trial");
  if (!owner.ok()) return internal::WithField(owner.status(), field);
  if (*owner != subject_id) {
    return api::Status::InvalidArgument(
        "trial " + std::to_string(trial_id) + " belongs to another subject", field);
  }
  return api::Status::Ok();
}

}  // namespace

std::string_view StorageSoftwareVersion() { return "fesbench " FESBENCH_VERSION; }

api::Result<ParameterSetSummary> ParameterSetRepository::Insert(const NewParameterSet& set) {
  model::ParameterSet params = set.params;
  if (params.provenance.software_version.empty()) {
    params.provenance.software_version = std::string(StorageSoftwareVersion());
  }
  const nlohmann::json json = api::ParameterSetToJson(params);
  // Validate through the wire form: what is stored is what clients can read.
  if (auto parsed = api::ParameterSetFromJson(json); !parsed.ok()) return parsed.status();
  std::string json_text;
  try {
    json_text = json.dump();
  } catch (const nlohmann::json::type_error&) {
    return api::Status::InvalidArgument("text fields must be valid UTF-8", "provenance");
  }
  std::set<std::int64_t> trial_ids(params.provenance.trial_ids.begin(),
                                   params.provenance.trial_ids.end());
  if (params.provenance.active_trial_id) trial_ids.insert(*params.provenance.active_trial_id);

  return db_.Write([&](Connection& c) -> api::Result<ParameterSetSummary> {
    if (auto s = internal::RequireRow(c, "SELECT 1 FROM subjects WHERE id = ?1", set.subject_id,
                                      "subject");
        !s.ok()) {
      return s;
    }
    if (auto s = internal::RequireLegOfSubject(c, set.leg_id, set.subject_id); !s.ok()) return s;
    for (std::size_t i = 0; i < params.provenance.trial_ids.size(); ++i) {
      if (auto s = CheckTrial(c, params.provenance.trial_ids[i], set.subject_id,
                              "provenance.trial_ids[" + std::to_string(i) + "]");
          !s.ok()) {
        return s;
      }
    }
    if (params.provenance.active_trial_id) {
      if (auto s = CheckTrial(c, *params.provenance.active_trial_id, set.subject_id,
                              "provenance.active_trial_id");
          !s.ok()) {
        return s;
      }
    }
    if (set.supersedes_id) {
      auto old = internal::One(internal::QueryRows(
                                   c, "SELECT subject_id, leg_id FROM parameter_sets WHERE id = ?1",
                                   [](const Statement& s) {
                                     return std::pair{s.Int64(0), s.Int64(1)};
                                   },
                                   *set.supersedes_id),
                               "parameter set", *set.supersedes_id);
      if (!old.ok()) return internal::WithField(old.status(), "supersedes_id");
      if (old->first != set.subject_id || old->second != set.leg_id) {
        return api::Status::InvalidArgument(
            "a set can only supersede one of the same subject and leg", "supersedes_id");
      }
    }
    auto next = internal::QueryRows(
        c,
        "SELECT COALESCE(MAX(version), 0) + 1 FROM parameter_sets WHERE subject_id = ?1"
        " AND leg_id = ?2",
        [](const Statement& s) { return s.Int64(0); }, set.subject_id, set.leg_id);
    if (!next.ok()) return next.status();
    const std::int64_t version = next->front();

    const api::UtcTime created_at = set.created_at.value_or(db_.Now());
    auto inserted = internal::InsertRow(
        c,
        "INSERT INTO parameter_sets (subject_id, leg_id, version, model, irc_method,"
        " passive_method, active_method, software_version, supersedes_id, created_at_utc,"
        " params_json, run_id) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12)",
        set.subject_id, set.leg_id, version, model::ModelKindName(params.model),
        params.provenance.irc_method, params.provenance.passive_method,
        params.provenance.active_method, params.provenance.software_version, set.supersedes_id,
        api::FormatUtc(created_at), json_text, set.run_id);
    if (!inserted.ok()) return inserted.status();
    const std::int64_t id = *inserted;
    for (std::int64_t trial_id : trial_ids) {
      if (auto s = internal::Execute(
              c, "INSERT INTO parameter_set_trials (parameter_set_id, trial_id) VALUES (?1, ?2)",
              id, trial_id);
          !s.ok()) {
        return s;
      }
    }
    if (auto s = db_.NotifyParameterSetStored({id, set.subject_id, set.leg_id}); !s.ok()) {
      return s;
    }
    ParameterSetSummary summary;
    summary.id = id;
    summary.subject_id = set.subject_id;
    summary.leg_id = set.leg_id;
    summary.version = static_cast<int>(version);
    summary.model = std::string(model::ModelKindName(params.model));
    summary.irc_method = params.provenance.irc_method;
    summary.passive_method = params.provenance.passive_method;
    summary.active_method = params.provenance.active_method;
    summary.software_version = params.provenance.software_version;
    summary.supersedes_id = set.supersedes_id;
    summary.created_at = created_at;
    summary.run_id = set.run_id;
    return summary;
  });
}

api::Result<std::vector<std::int64_t>> ParameterSetRepository::IdsForSession(
    std::int64_t session_id) {
  return db_.Read([&](Connection& c) -> api::Result<std::vector<std::int64_t>> {
    if (auto s =
            internal::RequireRow(c, "SELECT 1 FROM sessions WHERE id = ?1", session_id, "session");
        !s.ok()) {
      return s;
    }
    return internal::QueryRows(
        c,
        "SELECT DISTINCT p.parameter_set_id FROM parameter_set_trials p"
        " JOIN trials t ON t.id = p.trial_id WHERE t.session_id = ?1 ORDER BY 1",
        [](const Statement& s) -> api::Result<std::int64_t> { return s.Int64(0); }, session_id);
  });
}

api::Result<StoredParameterSet> ParameterSetRepository::Get(std::int64_t id) {
  return db_.Read([&](Connection& c) { return GetIn(c, id); });
}

api::Result<std::vector<ParameterSetSummary>> ParameterSetRepository::History(
    const HistoryQuery& query) {
  // Fixed SQL fragments per filter (values are always bound), so each shape
  // is a cached statement that range-scans (subject_id, created_at_utc).
  std::string sql = "SELECT " + std::string(kSummaryColumns) +
                    " FROM parameter_sets WHERE subject_id = ?1"
                    " AND created_at_utc >= ?2 AND created_at_utc < ?3";
  if (query.leg_id) sql += " AND leg_id = ?4";
  if (query.method) sql += " AND ?5 IN (irc_method, passive_method, active_method)";
  sql += " ORDER BY created_at_utc, id LIMIT ?6";
  const std::string from = query.from ? api::FormatUtc(*query.from) : std::string();
  const std::string to = query.to ? api::FormatUtc(*query.to) : std::string("~");  // '~' > any digit
  return db_.Read([&](Connection& c) -> api::Result<std::vector<ParameterSetSummary>> {
    if (auto s = internal::RequireRow(c, "SELECT 1 FROM subjects WHERE id = ?1", query.subject_id,
                                      "subject");
        !s.ok()) {
      return s;
    }
    auto statement = c.Prepare(sql);
    if (!statement.ok()) return statement.status();
    statement->Bind(1, query.subject_id)
        .Bind(2, from)
        .Bind(3, to)
        .Bind(6, static_cast<std::int64_t>(query.limit));
    if (query.leg_id) statement->Bind(4, *query.leg_id);
    if (query.method) statement->Bind(5, *query.method);
    return internal::ReadAll(*statement, ReadSummary);
  });
}

api::Result<std::vector<ParameterSetSummary>> ParameterSetRepository::List(
    const ParameterSetListQuery& query) {
  // As History: fixed fragments per filter, every value bound.
  std::string sql = "SELECT " + std::string(kSummaryColumns) + " FROM parameter_sets WHERE id > ?1";
  if (query.subject_id) sql += " AND subject_id = ?2";
  if (query.subject_id && query.leg_id) sql += " AND leg_id = ?3";
  if (query.method) sql += " AND ?4 IN (irc_method, passive_method, active_method)";
  if (query.from) sql += " AND created_at_utc >= ?5";
  if (query.to) sql += " AND created_at_utc < ?6";
  sql += " ORDER BY id LIMIT ?7";
  return db_.Read([&](Connection& c) -> api::Result<std::vector<ParameterSetSummary>> {
    if (query.subject_id) {
      if (auto s = internal::RequireRow(c, "SELECT 1 FROM subjects WHERE id = ?1",
                                        *query.subject_id, "subject");
          !s.ok()) {
        return s;
      }
    }
    auto statement = c.Prepare(sql);
    if (!statement.ok()) return statement.status();
    statement->Bind(1, query.after_id).Bind(7, static_cast<std::int64_t>(query.limit));
    if (query.subject_id) statement->Bind(2, *query.subject_id);
    if (query.subject_id && query.leg_id) statement->Bind(3, *query.leg_id);
    if (query.method) statement->Bind(4, *query.method);
    if (query.from) statement->Bind(5, api::FormatUtc(*query.from));
    if (query.to) statement->Bind(6, api::FormatUtc(*query.to));
    return internal::ReadAll(*statement, ReadSummary);
  });
}

api::Result<StoredParameterSet> ParameterSetRepository::Latest(std::int64_t subject_id,
                                                               std::int64_t leg_id) {
  return db_.Read([&](Connection& c) -> api::Result<StoredParameterSet> {
    auto latest = internal::QueryRows(
        c,
        "SELECT id FROM parameter_sets WHERE subject_id = ?1 AND leg_id = ?2"
        " ORDER BY version DESC LIMIT 1",
        [](const Statement& s) { return s.Int64(0); }, subject_id, leg_id);
    if (!latest.ok()) return latest.status();
    if (latest->empty()) {
      return api::Status::NotFound("no parameter set for subject " + std::to_string(subject_id) +
                                   ", leg " + std::to_string(leg_id));
    }
    return GetIn(c, latest->front());
  });
}

namespace {

constexpr std::string_view kApprovalColumns =
    "a.id, a.parameter_set_id, a.leg_id, a.approved_by_user_id, a.approved_by, a.run_id, a.note,"
    " a.approved_at_utc,"
    " CASE WHEN a.id = (SELECT MAX(b.id) FROM parameter_set_approvals b"
    " WHERE b.leg_id = a.leg_id) THEN 1 ELSE 0 END";

api::Result<Approval> ReadApproval(const Statement& s) {
  Approval a;
  a.id = s.Int64(0);
  a.parameter_set_id = s.Int64(1);
  a.leg_id = s.Int64(2);
  a.approved_by_user_id = s.OptionalInt64(3);
  a.approved_by = s.Text(4);
  a.run_id = s.OptionalInt64(5);
  a.note = s.Text(6);
  const auto at = api::ParseUtc(s.Text(7));
  if (!at) return internal::BadStoredValue("parameter set approval");
  a.approved_at = *at;
  a.current = s.Int64(8) != 0;
  return a;
}

api::Result<std::optional<Approval>> NewestApproval(Connection& c, std::string_view column,
                                                    std::int64_t id) {
  auto rows = internal::QueryRows(c,
                                  "SELECT " + std::string(kApprovalColumns) +
                                      " FROM parameter_set_approvals a WHERE a." +
                                      std::string(column) + " = ?1 ORDER BY a.id DESC LIMIT 1",
                                  ReadApproval, id);
  if (!rows.ok()) return rows.status();
  if (rows->empty()) return std::optional<Approval>();
  return std::optional<Approval>(std::move(rows->front()));
}

}  // namespace

api::Result<Approval> ParameterSetRepository::Approve(const NewApproval& approval) {
  if (approval.note.empty() || approval.note.size() > 500) {
    return api::Status::InvalidArgument("must be 1–500 bytes", "note");
  }
  if (approval.approved_by.empty()) {
    return api::Status::InvalidArgument("must name who approves", "approved_by");
  }
  return db_.Write([&](Connection& c) -> api::Result<Approval> {
    auto leg = internal::LookupInt64(c, "SELECT leg_id FROM parameter_sets WHERE id = ?1",
                                     approval.parameter_set_id, "parameter set");
    if (!leg.ok()) return leg.status();
    // A passive-only set (model::IsPassiveOnly: IRC and active methods
    // "none") has no model of the stimulated muscle; the approved set gates
    // and drives stimulation (docs/SAFETY.md).
    auto passive_only = internal::LookupInt64(
        c,
        "SELECT CASE WHEN irc_method = 'none' OR active_method = 'none' THEN 1 ELSE 0 END"
        " FROM parameter_sets WHERE id = ?1",
        approval.parameter_set_id, "parameter set");
    if (!passive_only.ok()) return passive_only.status();
    if (*passive_only == 1) {
      return api::Status::FailedPrecondition(
          "parameter set " + std::to_string(approval.parameter_set_id) +
          " is passive only (identified from unstimulated swings: no IRC or active curves); the "
          "approved set gates and drives stimulation, so it needs a set identified from "
          "stimulated trials (method thesis or rapid)");
    }
    if (approval.run_id) {
      if (auto s =
              internal::RequireRow(c, "SELECT 1 FROM runs WHERE id = ?1", *approval.run_id, "run");
          !s.ok()) {
        return s;
      }
    }
    auto current = NewestApproval(c, "leg_id", *leg);
    if (!current.ok()) return current.status();
    if (*current && (*current)->parameter_set_id == approval.parameter_set_id) {
      return api::Status::FailedPrecondition(
          "parameter set " + std::to_string(approval.parameter_set_id) +
          " already is its leg's approved set (approved by " + (*current)->approved_by + " at " +
          api::FormatUtc((*current)->approved_at) + ")");
    }
    const api::UtcTime at = approval.approved_at.value_or(db_.Now());
    auto id = internal::InsertRow(
        c,
        "INSERT INTO parameter_set_approvals (parameter_set_id, leg_id, approved_by_user_id,"
        " approved_by, run_id, note, approved_at_utc) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7)",
        approval.parameter_set_id, *leg, approval.approved_by_user_id, approval.approved_by,
        approval.run_id, approval.note, api::FormatUtc(at));
    if (!id.ok()) return id.status();
    db_.ApprovalsChanged();
    // The DDS topic learns of the approval as of the set approved, after the
    // commit (the SSE stream of stored sets leaves approvals out).
    auto subject = internal::LookupInt64(c, "SELECT subject_id FROM parameter_sets WHERE id = ?1",
                                         approval.parameter_set_id, "parameter set");
    if (!subject.ok()) return subject.status();
    if (auto s = db_.NotifyParameterSetStored({approval.parameter_set_id, *subject, *leg, true});
        !s.ok()) {
      return s;
    }
    Approval stored;
    stored.id = *id;
    stored.parameter_set_id = approval.parameter_set_id;
    stored.leg_id = *leg;
    stored.approved_by_user_id = approval.approved_by_user_id;
    stored.approved_by = approval.approved_by;
    stored.run_id = approval.run_id;
    stored.note = approval.note;
    stored.approved_at = at;
    stored.current = true;
    return stored;
  });
}

api::Result<std::optional<Approval>> ParameterSetRepository::LegApproval(std::int64_t leg_id) {
  return db_.Read([&](Connection& c) { return NewestApproval(c, "leg_id", leg_id); });
}

api::Result<StoredParameterSet> ParameterSetRepository::Approved(std::int64_t leg_id) {
  return db_.Read([&](Connection& c) -> api::Result<StoredParameterSet> {
    auto approval = NewestApproval(c, "leg_id", leg_id);
    if (!approval.ok()) return approval.status();
    if (!*approval) {
      return api::Status::NotFound("no parameter set is approved for leg " +
                                   std::to_string(leg_id));
    }
    return GetIn(c, (*approval)->parameter_set_id);
  });
}

api::Result<std::vector<Approval>> ParameterSetRepository::LatestApprovals(
    const std::vector<std::int64_t>& set_ids) {
  return db_.Read([&](Connection& c) -> api::Result<std::vector<Approval>> {
    std::vector<Approval> out;
    for (std::int64_t id : set_ids) {
      auto approval = NewestApproval(c, "parameter_set_id", id);
      if (!approval.ok()) return approval.status();
      if (*approval) out.push_back(std::move(**approval));
    }
    return out;
  });
}

api::Result<std::vector<Approval>> ParameterSetRepository::Approvals(
    std::int64_t parameter_set_id) {
  return db_.Read([&](Connection& c) -> api::Result<std::vector<Approval>> {
    if (auto s = internal::RequireRow(c, "SELECT 1 FROM parameter_sets WHERE id = ?1",
                                      parameter_set_id, "parameter set");
        !s.ok()) {
      return s;
    }
    return internal::QueryRows(c,
                               "SELECT " + std::string(kApprovalColumns) +
                                   " FROM parameter_set_approvals a WHERE a.parameter_set_id = ?1"
                                   " ORDER BY a.id",
                               ReadApproval, parameter_set_id);
  });
}

api::Result<std::vector<std::int64_t>> ParameterSetRepository::ApprovedHistory(std::int64_t leg_id,
                                                                               std::size_t limit) {
  return db_.Read([&](Connection& c) {
    return internal::QueryRows(
        c,
        "SELECT parameter_set_id FROM parameter_set_approvals WHERE leg_id = ?1"
        " GROUP BY parameter_set_id ORDER BY MAX(id) DESC LIMIT ?2",
        [](const Statement& s) { return s.Int64(0); }, leg_id, static_cast<std::int64_t>(limit));
  });
}

api::Result<std::optional<std::int64_t>> ParameterSetRepository::IdForRun(std::int64_t run_id) {
  return db_.Read([&](Connection& c) -> api::Result<std::optional<std::int64_t>> {
    auto ids = internal::QueryRows(
        c, "SELECT id FROM parameter_sets WHERE run_id = ?1 ORDER BY id DESC LIMIT 1",
        [](const Statement& s) { return s.Int64(0); }, run_id);
    if (!ids.ok()) return ids.status();
    if (ids->empty()) return std::optional<std::int64_t>();
    return std::optional<std::int64_t>(ids->front());
  });
}

api::Result<std::string> ParameterSetRepository::ExportJson(std::int64_t id) {
  return db_.Read([&](Connection& c) -> api::Result<std::string> {
    auto text = internal::One(internal::QueryRows(
                                  c, "SELECT params_json FROM parameter_sets WHERE id = ?1",
                                  [](const Statement& s) { return s.Text(0); }, id),
                              "parameter set", id);
    if (!text.ok()) return text.status();
    const nlohmann::json json = nlohmann::json::parse(*text, nullptr, false);
    if (json.is_discarded()) return internal::BadStoredValue("parameter set JSON");
    return json.dump(2) + "\n";
  });
}

}  // namespace fesbench::storage
