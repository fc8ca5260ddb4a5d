#include "server/services/commands.h"

#include <algorithm>
#include <iostream>

#include "storage/audit_log.h"

namespace fesbench::server::services {

namespace {
const api::Status kBadToken{api::ErrorCode::kUnauthenticated, "a valid bearer token is required"};
}  // namespace

CommandService::CommandService(storage::Database& db, RunService& runs, std::string transport)
    : db_(db), runs_(runs), transport_(std::move(transport)) {}

api::Result<Actor> CommandService::Authenticate(std::string_view token, const std::string& action,
                                                const std::string& target) {
  if (token.empty() || token.size() > 256) {
    AuditFailedSignIn(action, target);
    return kBadToken;
  }
  storage::UserRepository users(db_);
  auto user = users.Authenticate(token);
  if (!user.ok()) {
    if (user.status().code() != api::ErrorCode::kUnauthenticated) return user.status();
    AuditFailedSignIn(action, target);
    return kBadToken;
  }
  return Actor{user->id, user->name, user->role};
}

void CommandService::AuditFailedSignIn(const std::string& action, const std::string& target) {
  std::uint64_t unaudited = 0;
  {
    std::lock_guard lock(failed_mu_);
    const auto now = std::chrono::steady_clock::now();
    failed_rows_ = std::min(kFailedSignInBurst,
                            failed_rows_ + std::chrono::duration<double>(now - failed_at_).count());
    failed_at_ = now;
    if (failed_rows_ < 1.0) {
      ++failed_unaudited_;
      return;
    }
    failed_rows_ -= 1.0;
    unaudited = failed_unaudited_;
    failed_unaudited_ = 0;
  }
  storage::NewAuditEntry e;
  e.actor = transport_ + " client";
  e.action = transport_ + " " + action;
  e.target = target;
  e.request_summary = unaudited == 0 ? "failed sign-in"
                                     : "failed sign-in (" + std::to_string(unaudited) +
                                           " more failed since the last row)";
  e.outcome = std::string(api::ErrorCodeName(api::ErrorCode::kUnauthenticated));
  auto appended = storage::AuditLog(db_).Append(e);
  if (!appended.ok()) {
    std::cerr << "fesbench-server: audit log: " << appended.status().ToString() << std::endl;
  }
}

void CommandService::AuditRefusal(const Actor& actor, const std::string& action,
                                  const std::string& target, const std::string& summary,
                                  const api::Status& status) {
  const api::Status appended = AppendAudit(db_, actor, transport_ + " " + action, target, summary,
                                           std::string(api::ErrorCodeName(status.code())));
  if (!appended.ok()) {
    std::cerr << "fesbench-server: audit log: " << appended.ToString() << std::endl;
  }
}

api::Status CommandService::EStop(std::string_view token) {
  auto actor = Authenticate(token, "estop", "bench");
  if (!actor.ok()) return actor.status();
  // As POST /api/v1/bench/estop: any signed-in user (Permission::kEStop).
  if (api::Status allowed = Require(*actor, Permission::kEStop); !allowed.ok()) {
    AuditRefusal(*actor, "estop", "bench", "e-stop", allowed);
    return allowed;
  }
  api::Status st = runs_.EStop(*actor, transport_);
  if (!st.ok()) AuditRefusal(*actor, "estop", "bench", "e-stop", st);
  return st;
}

api::Result<RunView> CommandService::StartRun(std::string_view token, std::int64_t session_id,
                                              const std::string& protocol,
                                              const protocols::ParameterValues& parameters) {
  const std::string target = "sessions/" + std::to_string(session_id);
  auto actor = Authenticate(token, "start_run", target);
  if (!actor.ok()) return actor.status();
  const std::string summary = "start " + protocol.substr(0, 64);
  if (api::Status allowed = Require(*actor, Permission::kOperateBench); !allowed.ok()) {
    AuditRefusal(*actor, "start_run", target, summary, allowed);
    return allowed;
  }
  auto view = runs_.Start(*actor, session_id, protocol, parameters);
  if (!view.ok()) AuditRefusal(*actor, "start_run", target, summary, view.status());
  return view;
}

api::Status CommandService::CancelRun(std::string_view token, std::int64_t run_id) {
  const std::string target = "runs/" + std::to_string(run_id);
  auto actor = Authenticate(token, "cancel_run", target);
  if (!actor.ok()) return actor.status();
  if (api::Status allowed = Require(*actor, Permission::kOperateBench); !allowed.ok()) {
    AuditRefusal(*actor, "cancel_run", target, "cancel", allowed);
    return allowed;
  }
  api::Status st = runs_.Cancel(*actor, run_id);
  if (!st.ok()) AuditRefusal(*actor, "cancel_run", target, "cancel", st);
  return st;
}

api::Status CommandService::Heartbeat(std::string_view token, std::int64_t run_id) {
  const std::string target = "runs/" + std::to_string(run_id);
  auto actor = Authenticate(token, "heartbeat", target);
  if (!actor.ok()) return actor.status();
  if (api::Status allowed = Require(*actor, Permission::kOperateBench); !allowed.ok()) {
    AuditRefusal(*actor, "heartbeat", target, "heartbeat", allowed);
    return allowed;
  }
  // A heartbeat changes nothing: neither it nor its failure is audited (as HTTP).
  return runs_.Heartbeat(*actor, run_id);
}

}  // namespace fesbench::server::services
