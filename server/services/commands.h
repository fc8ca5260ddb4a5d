#pragma once

/// @file
/// Bench commands from a token-carrying transport other than HTTP (DDS,
/// docs/API.md, "DDS"): authenticate the bearer token against storage, check the
/// role exactly as the HTTP routes do (e-stop: any signed-in user; start,
/// cancel, heartbeat: clinician or admin), then call the same RunService
/// methods HTTP calls, so the safety interlocks, the run/e-stop audit
/// entries and the refusals are one code path. A refusal of a signed-in
/// user is audited like HTTP's (outcome "<code>"). A command with a token
/// that fails (unknown, revoked, expired) is audited too, as actor
/// "<transport> client" with outcome "unauthenticated" (never the token):
/// the first `kFailedSignInBurst` of a burst one by one, then at most one
/// row per second carrying how many more failed meanwhile, so a flood cannot
/// fill the audit log. Failed tokens are never slowed down here: a DDS
/// command carries no client address to single out, and a valid e-stop
/// must never wait behind someone else's failures (with DDS Security only
/// the lab's operator identities can send commands at all). Thread-safe.

#include <chrono>
#include <cstdint>
#include <mutex>
#include <string>
#include <string_view>

#include "api/status.h"
#include "server/services/run_service.h"
#include "storage/database.h"
#include "storage/users.h"

namespace fesbench::server::services {

class CommandService {
 public:
  /// Failed sign-ins audited one by one before rows are rate-limited
  /// (the bucket refills one row per second).
  static constexpr double kFailedSignInBurst = 30.0;

  /// @param transport names the source in audit entries and e-stops ("dds").
  CommandService(storage::Database& db, RunService& runs, std::string transport);

  /// E-stop (any role). kUnauthenticated for a bad, revoked or expired token.
  api::Status EStop(std::string_view token);
  /// Starts a protocol; errors as RunService::Start plus kUnauthenticated,
  /// and kPermissionDenied for analysts.
  api::Result<RunView> StartRun(std::string_view token, std::int64_t session_id,
                                const std::string& protocol,
                                const protocols::ParameterValues& parameters);
  /// Cancels the run in progress; errors as RunService::Cancel plus kUnauthenticated.
  api::Status CancelRun(std::string_view token, std::int64_t run_id);
  /// The controlling user's heartbeat; errors as RunService::Heartbeat plus kUnauthenticated.
  api::Status Heartbeat(std::string_view token, std::int64_t run_id);

 private:
  /// The token's user; kUnauthenticated (audited, see above) otherwise.
  api::Result<Actor> Authenticate(std::string_view token, const std::string& action,
                                  const std::string& target);
  void AuditFailedSignIn(const std::string& action, const std::string& target);
  void AuditRefusal(const Actor& actor, const std::string& action, const std::string& target,
                    const std::string& summary, const api::Status& status);

  storage::Database& db_;
  RunService& runs_;
  std::string transport_;
  std::mutex failed_mu_;
  double failed_rows_ = kFailedSignInBurst;  // audit rows left in the bucket
  std::chrono::steady_clock::time_point failed_at_ = std::chrono::steady_clock::now();
  std::uint64_t failed_unaudited_ = 0;  // failures since the last audited row
};

}  // namespace fesbench::server::services
