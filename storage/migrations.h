#pragma once

/// @file
/// The schema as numbered migrations compiled into the library. Migration N
/// moves a database from schema version N − 1 to N; each runs in one
/// transaction that also records it in `schema_migrations` and sets
/// PRAGMA user_version = N, so a crash leaves the database at N − 1 or N.

#include <functional>
#include <string>
#include <vector>

#include "api/status.h"
#include "storage/connection.h"

namespace fesbench::storage {

struct Migration {
  int version;       ///< 1, 2, …, consecutive.
  std::string name;  ///< short description, recorded in schema_migrations.
  std::string sql;   ///< the DDL, fixed text (no caller values).
  /// Rows the DDL's new columns take from what older software derived,
  /// written in the same transaction after `sql` (none when empty).
  std::function<api::Status(Connection&)> backfill = {};
  std::string sql_after = {};  ///< DDL after the backfill (e.g. restoring a trigger).
};

/// Migration 19's backfill: the outcome of each run that ended before runs
/// stored one (run_events.outcome_json), as the software of schema 18
/// showed it (storage/outcome_backfill.cc).
api::Status BackfillRunOutcomes(Connection& connection);

/// Every migration, in order. Tables are append-only: each migration also
/// installs triggers that refuse UPDATE and DELETE on the tables it creates.
const std::vector<Migration>& AllMigrations();

/// The same schema for PostgreSQL: one migration numbered 11 (the schema of
/// SQLite migrations 1–11 in PostgreSQL's dialect), then the later ones with
/// the same numbers as in SQLite, so a schema version means the same in both.
const std::vector<Migration>& PostgresMigrations();

/// The schema version this software writes (the last migration's number).
int LatestSchemaVersion();

}  // namespace fesbench::storage
