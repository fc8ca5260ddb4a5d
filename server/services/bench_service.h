#pragma once

/// @file
/// The bench resource (DESIGN.md §8 `bench`): what the bench is and what it
/// is doing, and in simulation the virtual subject (DESIGN.md §6), which an
/// admin may read and replace between runs. Thread-safe.

#include <cstdint>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>

#include "api/status.h"
#include "server/bench/bench.h"
#include "server/bench/simulated_bench.h"
#include "server/bench/virtual_subject.h"
#include "server/services/actor.h"
#include "server/services/run_service.h"
#include "storage/database.h"

namespace fesbench::server::services {

/// A Bench that forwards to a SimulatedBench whose virtual subject can be
/// replaced (a new SimulatedBench with the same options is built). Give it to
/// the RunService as its bench and to the BenchService to replace the
/// subject; BenchService does so only while no run holds the bench.
/// Hardware e-stop calls may come from any thread at any time and never
/// wait for the control loop; a latched hardware e-stop carries over to the
/// new subject's bench. Bench time restarts at 0 with a new subject.
class SwappableSimulatedBench final : public Bench {
 public:
  /// @throws std::invalid_argument if the subject fails ValidateVirtualSubject.
  SwappableSimulatedBench(VirtualSubject subject, SimulatedBenchOptions options = {});
  /// Non-throwing construction: kInvalidArgument naming the field.
  static api::Result<std::unique_ptr<SwappableSimulatedBench>> Create(
      VirtualSubject subject, SimulatedBenchOptions options = {});

  std::string_view kind() const override { return "sim"; }
  const BenchLimits& limits() const override { return options_.limits; }
  void SetStimAmplitude(double stim_ma) override;
  void TriggerPulse(double stim_ma) override;
  void RestartPulseClock() override;
  std::vector<model::Pulse> DrainDeliveredPulses() override;
  void SetMotorMode(MotorMode mode) override;
  void SetMotorSetpoint(double angle_deg) override;
  double Now_s() const override;
  void AdvanceTo(double t_s) override;
  SensorFrame ReadSensors() override;
  std::vector<double> DrainEmg_mv() override;
  void HardwareEStop() override;
  void ClearHardwareEStop() override;
  bool HardwareEStopped() const override;

  /// The current virtual subject (a copy).
  VirtualSubject subject() const;
  double time_scale() const { return options_.time_scale; }
  /// Replaces the virtual subject. Only while no run uses the bench (the
  /// caller's duty: BenchService goes through RunService::WithIdleBench).
  /// kInvalidArgument naming the field for an invalid subject.
  api::Status ReplaceSubject(VirtualSubject subject);
  /// The current SimulatedBench (for tests: truth, delivered pulses).
  std::shared_ptr<SimulatedBench> current() const;

 private:
  SimulatedBenchOptions options_;
  mutable std::mutex mu_;  // guards bench_ (the pointer, not the bench)
  std::shared_ptr<SimulatedBench> bench_;
};

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
  /// DrawVirtualSubject(N)) or "analytic" (DrawAnalyticSubject(N)).
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
