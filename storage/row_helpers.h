#pragma once

/// @file
/// Small helpers shared by the repositories (internal to storage/).

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>
#include <vector>

#include "api/status.h"
#include "storage/connection.h"

namespace fesbench::storage::internal {

/// kDataLoss for a stored value this software cannot read back.
inline api::Status BadStoredValue(std::string_view what) {
  return api::Status::DataLoss("stored " + std::string(what) + " cannot be read back");
}

/// Binds one value at `index`: anything Statement::Bind takes, and byte
/// vectors as BLOBs.
template <typename T>
void BindValue(Statement& s, int index, const T& value) {
  s.Bind(index, value);
}
inline void BindValue(Statement& s, int index, const std::vector<std::byte>& blob) {
  s.BindBlob(index, blob);
}

/// Binds `values` to ?1, ?2, ... in order.
template <typename... Values>
void BindAll(Statement& s, const Values&... values) {
  int index = 0;
  (BindValue(s, ++index, values), ...);
}

/// True when `sql`, with `values` bound to ?1, ?2, ..., returns a row.
template <typename... Values>
api::Result<bool> RowExists(Connection& c, std::string_view sql, const Values&... values) {
  auto statement = c.Prepare(sql);
  if (!statement.ok()) return statement.status();
  BindAll(*statement, values...);
  return statement->Step();
}

/// kNotFound "<what> <id> not found" unless `sql` (one `?1` parameter bound
/// to `id`) returns a row.
inline api::Status RequireRow(Connection& c, std::string_view sql, std::int64_t id,
                              std::string_view what) {
  auto exists = RowExists(c, sql, id);
  if (!exists.ok()) return exists.status();
  if (!*exists)
    return api::Status::NotFound(std::string(what) + " " + std::to_string(id) + " not found");
  return api::Status::Ok();
}

template <typename T>
struct RowType {
  using type = T;
};
template <typename T>
struct RowType<api::Result<T>> {
  using type = T;
};
/// What `read` yields for one row, without an api::Result around it.
template <typename Read>
using RowOf = typename RowType<std::invoke_result_t<Read&, const Statement&>>::type;

/// Steps `statement` (prepared and bound) to the end and maps every row with
/// `read`, which returns the row's value or an api::Result of it (the first
/// failure is returned).
template <typename Read>
api::Result<std::vector<RowOf<Read>>> ReadAll(Statement& statement, Read&& read) {
  std::vector<RowOf<Read>> rows;
  while (true) {
    auto more = statement.Step();
    if (!more.ok()) return more.status();
    if (!*more) break;
    if constexpr (std::is_same_v<RowOf<Read>, std::invoke_result_t<Read&, const Statement&>>) {
      rows.push_back(read(std::as_const(statement)));
    } else {
      auto row = read(std::as_const(statement));
      if (!row.ok()) return row.status();
      rows.push_back(std::move(*row));
    }
  }
  return rows;
}

/// Prepares `sql`, binds `values` to ?1, ?2, ... and maps every row with
/// `read` (see ReadAll).
template <typename Read, typename... Values>
api::Result<std::vector<RowOf<Read>>> QueryRows(Connection& c, std::string_view sql, Read&& read,
                                                const Values&... values) {
  auto statement = c.Prepare(sql);
  if (!statement.ok()) return statement.status();
  BindAll(*statement, values...);
  return ReadAll(*statement, std::forward<Read>(read));
}

/// The first of `rows`, or kNotFound "<what> <id> not found" when there is none.
template <typename T>
api::Result<T> One(api::Result<std::vector<T>> rows, std::string_view what, std::int64_t id) {
  if (!rows.ok()) return rows.status();
  if (rows->empty()) {
    return api::Status::NotFound(std::string(what) + " " + std::to_string(id) + " not found");
  }
  return std::move(rows->front());
}

/// `status` with its field set to `field` (ok stays ok).
inline api::Status WithField(api::Status status, std::string field) {
  if (status.ok()) return status;
  return api::Status(status.code(), status.message(), std::move(field));
}

/// Prepares `sql` (an INSERT or other statement without rows), binds
/// `values` to ?1, ?2, ... and runs it.
template <typename... Values>
api::Status Execute(Connection& c, std::string_view sql, const Values&... values) {
  auto statement = c.Prepare(sql);
  if (!statement.ok()) return statement.status();
  BindAll(*statement, values...);
  return statement->Run();
}

/// Execute for an INSERT into a table with an `id` column: the id of the
/// new row (RETURNING, which both engines understand).
template <typename... Values>
api::Result<std::int64_t> InsertRow(Connection& c, std::string_view sql, const Values&... values) {
  auto statement = c.Prepare(std::string(sql) + " RETURNING id");
  if (!statement.ok()) return statement.status();
  BindAll(*statement, values...);
  auto row = statement->Step();
  if (!row.ok()) return row.status();
  if (!*row) return api::Status::Internal("an INSERT returned no id");
  const std::int64_t id = statement->Int64(0);
  if (auto s = statement->Run(); !s.ok()) return s;
  return id;
}

/// The integer in the first column of the row `sql` returns with ?1 = `id`
/// (e.g. the owner of a row); kNotFound "<what> <id> not found" when none.
inline api::Result<std::int64_t> LookupInt64(Connection& c, std::string_view sql, std::int64_t id,
                                             std::string_view what) {
  return One(QueryRows(
                 c, sql, [](const Statement& s) { return s.Int64(0); }, id),
             what, id);
}

/// Checks that leg `leg_id` exists (kNotFound) and belongs to `subject_id`
/// (kInvalidArgument on field "leg_id").
inline api::Status RequireLegOfSubject(Connection& c, std::int64_t leg_id,
                                       std::int64_t subject_id) {
  auto owner = LookupInt64(c, "SELECT subject_id FROM legs WHERE id = ?1", leg_id, "leg");
  if (!owner.ok()) return owner.status();
  if (*owner != subject_id) {
    return api::Status::InvalidArgument(
        "leg " + std::to_string(leg_id) + " belongs to another subject", "leg_id");
  }
  return api::Status::Ok();
}

/// A correction of a revisioned row (subject, session): reads the row with
/// `get(c, id)`, appends through `insert_revision(revision, corrects_id)` the
/// revision after its current one, correcting it, and returns the row read
/// again. Revisions are never updated in place.
template <typename Get, typename InsertRevision>
auto AppendCorrection(Connection& c, std::int64_t id, Get&& get, InsertRevision&& insert_revision)
    -> decltype(get(c, id)) {
  auto row = get(c, id);
  if (!row.ok()) return row.status();
  if (auto s = insert_revision(row->current.revision + 1, row->current.id); !s.ok()) return s;
  return get(c, id);
}

}  // namespace fesbench::storage::internal
