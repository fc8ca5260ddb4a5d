#pragma once

/// @file
/// The bench resource (docs/API.md, "The bench"): what the bench is and what it
/// is doing, and in simulation the virtual subject (docs/ARCHITECTURE.md), which an
/// admin may read and replace between runs. Thread-safe.

#include <cstdint>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>

#include "api/status.h"
#include "server/bench/bench.h"
#include "server/bench/swappable_bench.h"
#include "server/bench/virtual_subject.h"
#include "server/services/actor.h"
#include "server/services/run_service.h"
#include "storage/database.h"

namespace fesbench::server::services {

/// {"kind", "time_scale", "limits": {"max_stim_ma", "pulse_rate_hz",
///  "pulse_width_us", "min_angle_deg", "max_angle_deg",
///  "max_motor_torque_nm", "control_rate_hz", "sample_rate_hz",
///  "emg_rate_hz", "max_stop_impact_deg_s"}, "simulated", "estopped",
///  "owner" (controlling user or null), "run_id" (current or last run, or
///  null), "run_state", "progress" (0–1), "state": BenchStateToJson}.
struct BenchInfo {
  std::string kind;
  double time_scale = 1.0;
  BenchLimits limits;
  bool simulated = false;
  BenchState state;
};
nlohmann::json BenchInfoToJson(const BenchInfo& info);

class BenchService {
 public:
  /// @param simulated the simulated bench that `runs` uses, or nullptr for
  ///   any other bench (then the virtual subject calls answer kConflict
  ///   "not a simulated bench"). db, runs and simulated must outlive this.
  BenchService(storage::Database& db, RunService& runs, SwappableSimulatedBench* simulated);

  /// Kind, time scale, limits and current state of the bench.
  BenchInfo Info() const;

  /// The virtual subject's JSON (VirtualSubjectToJson). kPermissionDenied
  /// unless admin; kConflict "not a simulated bench".
  api::Result<nlohmann::json> GetVirtualSubject(const Actor& actor) const;
  /// Replaces the virtual subject between runs. The body is either a full
  /// subject (VirtualSubjectFromJson) or a draw {"draw_seed": N,
  /// "family": F}, N a non-negative integer, F "thesis" (default:
  /// DrawVirtualSubject(N)), "analytic" (DrawAnalyticSubject(N)) or
  /// "plateau" (DrawPlateauSubject(N)).
  /// kPermissionDenied unless admin; kConflict "not a simulated bench" or
  /// while a run holds the bench; kInvalidArgument naming the field (a
  /// missing, non-integer or negative draw_seed, an unknown family, a key
  /// beside draw_seed and family, VirtualSubjectFromJson's errors). Audited. Returns the stored
  /// subject's JSON (defaults filled in).
  api::Result<nlohmann::json> PutVirtualSubject(const Actor& actor, const nlohmann::json& json);

 private:
  // Audits `summary` and swaps the subject in inside the bench's idle window.
  api::Result<nlohmann::json> ReplaceVirtualSubject(const Actor& actor, VirtualSubject subject,
                                                    const std::string& summary);

  storage::Database& db_;
  RunService& runs_;
  SwappableSimulatedBench* simulated_;
};

}  // namespace fesbench::server::services
