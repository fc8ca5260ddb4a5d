#pragma once

/// @file
/// Protocols as data (docs/PROTOCOLS.md; thesis §5.3–§5.4, §7.4.1, Appendix F):
/// a named, versioned description with typed parameters (units in their
/// names, thesis defaults, limits) that the server lists
/// (GET /api/v1/protocols) and validates client values against. Each
/// protocol is a class (protocol_registry.h, one file each under catalog/)
/// that gives its description, builds its plan (plan.h) and names the trials
/// it records; the engine that runs the steps is runner.h.

#include <cstdint>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "api/protocol_info.h"
#include "api/run.h"
#include "api/run_start.h"
#include "api/status.h"
#include "model/identify_common.h"
#include "model/parameter_set.h"
#include "server/bench/bench.h"

namespace fesbench::server::protocols {

/// How a parameter's default and limits follow the subject (Appendix F:
/// "Set Maximum Stimulation to Subject maximum tolerance", "Set Minimum
/// Stimulation to 5 mA below threshold"; §5.4.2 "scaled to cover the
/// angular range of the individual subject").
enum class Scaling {
  kNone,          ///< default_value as is.
  kThreshold,     ///< default = the session's threshold, mA.
  kMaxTolerated,  ///< default = the session's max tolerated amplitude, mA.
  /// default = threshold + default_value·(max tolerated − threshold), mA
  /// (default_value is the fraction of the range).
  kStimRange,
  kRangeMin,  ///< default = the subject's range-of-motion minimum, deg.
  kRangeMax,  ///< default = the subject's range-of-motion maximum, deg.
  /// The tolerance test's ceiling: default = the session's recorded max
  /// tolerated amplitude; default_value (mA) when the session has none yet.
  /// Above the recorded max only with SubjectContext::ceiling_above_max.
  kToleranceCeiling,
};

/// "none", "threshold", "max_tolerated", "stim_range", "range_min", "range_max",
/// "tolerance_ceiling".
std::string_view ScalingName(Scaling scaling);

/// One protocol parameter. The name ends in its unit (`_ma`, `_s`, `_deg`,
/// `_deg_s`, `_nm`, `_ma_per_s`); unitless names are counts, fractions or
/// seeds.
struct ParameterSpec {
  std::string name;
  std::string description;
  double default_value = 0.0;  ///< see Scaling; for kStimRange a fraction.
  double min_value = 0.0;      ///< inclusive, in the parameter's unit.
  double max_value = 0.0;      ///< inclusive.
  bool integer = false;
  Scaling scaling = Scaling::kNone;
  /// A rest period: values below the protocol's min_rest_s are refused
  /// (docs/SAFETY.md: rest periods cannot be shortened below the minimum).
  bool is_rest = false;
  /// A choice among names: the value is the index of the chosen name
  /// (clients may send the name; GET /protocols lists them).
  std::vector<std::string> choices = {};
  /// The protocol's own words for the parameter where the shared label
  /// (PresentationOf) would mislead, e.g. tracking's duration_s is the
  /// target's length, not a train's; empty: the shared label.
  std::string label = {};
};

/// What the runner does with the bench during a protocol.
enum class BenchMode {
  kLocked,     ///< knee locked (isometric), 90° by default.
  kMotor,      ///< motor moves the knee on a trajectory.
  kDecoupled,  ///< free swing.
  kMixed,      ///< several of the above in sequence (rapid_parameterisation).
};
std::string_view BenchModeName(BenchMode mode);

/// Protocol families (model-gated stimulation applies to kPrediction).
enum class ProtocolKind {
  kTolerance,
  kIsometric,
  kPassive,
  kFreeSwing,
  kPrediction,
  kRapid,
  kTracking,  ///< closed-loop stimulation to follow a target angle (`tracking`).
  kDailyCheck,  ///< today's leg against its stored set (`daily_check`).
};

/// A protocol description: pure data.
struct ProtocolDescription {
  std::string name;  ///< e.g. "isometric_ramp_irc".
  int version = 1;
  std::string title;
  std::string description;  ///< what it does and the thesis section.
  BenchMode bench_mode = BenchMode::kLocked;
  ProtocolKind kind = ProtocolKind::kIsometric;
  double min_rest_s = 0.0;  ///< shortest allowed rest period, s.
  std::vector<ParameterSpec> parameters;
  /// It measures the max tolerated amplitude (api::ProtocolInfo): its
  /// ceiling_ma follows the tolerance ceiling rules (ResolveParameters).
  bool measures_max_tolerated = false;
  /// Its run follows a target knee angle (api::ProtocolInfo).
  bool follows_target = false;
  /// A session with recorded limits offers it first (api::ProtocolInfo).
  bool offered_first = false;

  const ParameterSpec* FindParameter(std::string_view name) const;
};

/// Every protocol of docs/PROTOCOLS.md, in catalogue order: the
/// descriptions of the registered protocol classes (protocol_registry.h).
const std::vector<ProtocolDescription>& ProtocolCatalog();
/// The protocol called name, or nullptr.
const ProtocolDescription* FindProtocol(std::string_view name);

/// The session and subject a run is scaled to (docs/ARCHITECTURE.md, storage: sessions).
struct SubjectContext {
  double threshold_ma = 20.0;      ///< lowest amplitude giving torque.
  double max_tolerated_ma = 45.0;  ///< highest amplitude the subject accepts.
  /// True when max_tolerated_ma is the session's recorded value; false for a
  /// session without one yet (first session of a new subject), where
  /// max_tolerated_ma is the stimulator's range and only tolerance_test,
  /// which measures it, may run.
  bool max_tolerated_recorded = true;
  /// A clinician's explicit decision to let a tolerance test's ceiling_ma go
  /// above the recorded max tolerated amplitude (up to the stimulator's
  /// limit); the reason, never empty when set, is audited with the run.
  std::optional<std::string> ceiling_above_max;
  double min_angle_deg = 10.0;     ///< subject's range of motion.
  double max_angle_deg = 110.0;
  /// Limb inertia known from elsewhere (a slow accurate method, §7.4.1, or a
  /// prior parameter set), kg·m². Unset: Eq. 4.13 from body_mass_kg and
  /// leg_length_m.
  std::optional<double> inertia_kgm2;
  std::optional<double> body_mass_kg;
  std::optional<double> leg_length_m;  ///< femoral condyle to medial malleolus, m.
  /// The leg's approved parameter set, if a clinician approved one
  /// (docs/SAFETY.md): gates prediction protocols (model-gated
  /// stimulation), is what tracking inverts and daily_check compares with,
  /// and supplies the inertia for the rapid fit.
  std::optional<model::ParameterSet> parameter_set;
  /// True when the leg has stored sets but none is approved: the model gate
  /// then refuses instead of letting stimulation run ungated.
  bool sets_await_approval = false;
  /// Its stored id, when it has one (named in the model gate's messages).
  std::optional<std::int64_t> parameter_set_id;
  /// The leg's sets a clinician approved, newest approval first (at most
  /// 20): daily_check learns its drift bounds from their spread (§7.6.4).
  std::vector<model::ParameterSet> history;
  /// The isometric ramp trial the current set's IRC came from (its rapid
  /// or daily-check ramp), when stored: daily_check compares today's ramp
  /// with it, measurement with measurement.
  std::optional<model::TrialColumns> base_ramp_trial;
};

/// A tracking run's uploaded target trajectory, as sent (POST
/// /sessions/{id}/runs "target_samples"): strictly increasing t_s, deg.
using TargetSamples = api::TargetSamples;

/// Why a protocol that needs the leg's approved set cannot run, and how to
/// approve one: "<what> needs the leg's approved parameter set: no set is
/// approved for the leg; …".
std::string NoApprovedSetMessage(std::string_view what);

/// Checks a context: finite values, 0 ≤ threshold < max tolerated ≤ 100 mA,
/// 0 ≤ min angle < max angle ≤ 180°; kInvalidArgument naming the field.
api::Status ValidateSubject(const SubjectContext& subject);

/// Parameter values by name.
using ParameterValues = api::ParameterValues;

/// The value a parameter takes by default for this subject.
double DefaultFor(const ParameterSpec& spec, const SubjectContext& subject);

/// Fills in defaults and validates client values. kInvalidArgument with
/// field "parameters.<name>" for an unknown name, a non-finite, non-integer
/// or out-of-range value, a stimulation parameter above the session's max
/// tolerated amplitude, an angle outside the subject's range of motion, or
/// a rest below the protocol's minimum ("rest below minimum"). The tolerance
/// test's ceiling_ma defaults to the recorded max tolerated amplitude
/// (60 mA without one); above a recorded max it needs
/// subject.ceiling_above_max, and start_ma must lie below the ceiling
/// (field "parameters.start_ma"). kInvalidArgument field "ceiling_reason"
/// for a ceiling_above_max that authorises nothing.
api::Result<ParameterValues> ResolveParameters(const ProtocolDescription& protocol,
                                               const ParameterValues& values,
                                               const SubjectContext& subject);

/// `request` with each choice it gives by name ("target": "uploaded") turned
/// into its index among the protocol's choices, in `parameters` (`choices`
/// is then empty): kNotFound naming "protocol" for a protocol not in the
/// catalogue, kInvalidArgument naming "parameters.<name>" for a name that is
/// not a choice parameter's or not one of its choices.
api::Result<api::StartRunRequest> ResolveChoiceNames(api::StartRunRequest request);

/// How a parameter reads to a clinician (docs/PROTOCOLS.md, "Parameters"): label, unit and
/// whether the web form folds it away, by parameter name.
struct ParameterPresentation {
  std::string label;     ///< clinician words, e.g. "Random-binary amplitude".
  std::string unit;      ///< "mA", "s", "deg", "1" (fractions and counts), …
  bool advanced = true;  ///< collapsed by default in the web form.
};
/// The presentation of `name` (every catalog parameter has one; an unknown
/// name gets its own name as label, Unit-from-suffix and advanced).
ParameterPresentation PresentationOf(std::string_view name);
/// The presentation of a protocol's parameter: PresentationOf its name, with
/// the protocol's own label where it has one (ParameterSpec::label).
ParameterPresentation PresentationOf(const ParameterSpec& spec);
/// The thesis section a protocol implements, e.g. "§7.4.1" (the last
/// section its description cites), or "".
std::string ThesisSection(const ProtocolDescription& protocol);
/// True if the protocol delivers stimulation (every kind but kPassive).
bool Stimulates(const ProtocolDescription& protocol);

/// A description as it is listed (GET /api/v1/protocols/{name},
/// api::ProtocolInfo). A default derived from the session (threshold,
/// max tolerated, range-scaled amplitudes, range of motion) is resolved for
/// `session` in the parameter's own unit; without a session (or, for
/// stimulation values, a session without recorded limits) it is unset and
/// the default rule says how it is derived. Fixed defaults have no rule.
api::ProtocolInfo ProtocolInfoOf(const ProtocolDescription& protocol,
                                 const SubjectContext* session = nullptr,
                                 bool session_has_limits = false);
/// api::ProtocolInfoToJson of ProtocolInfoOf.
nlohmann::json ProtocolToJson(const ProtocolDescription& protocol,
                              const SubjectContext* session = nullptr,
                              bool session_has_limits = false);
/// {"protocols": [...]} of the whole catalog (defaults as ProtocolToJson).
nlohmann::json CatalogToJson(const SubjectContext* session = nullptr,
                             bool session_has_limits = false);

}  // namespace fesbench::server::protocols
