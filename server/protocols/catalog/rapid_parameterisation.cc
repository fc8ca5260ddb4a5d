// The `rapid_parameterisation` protocol (docs/PROTOCOLS.md, `rapid_parameterisation`).

#include <memory>
#include <random>
#include <tuple>

#include "server/protocols/catalog/parameters.h"
#include "server/protocols/protocol_registry.h"
#include "server/protocols/rapid_identification.h"

namespace fesbench::server::protocols::catalog {
namespace {

// A dense random-binary train whose ON bursts take seeded levels
// threshold + x·(amplitude − threshold), x in [min_fraction, 1], so the active
// trial visits the amplitudes between mid-range and full extension (a second
// mt19937_64 stream of the seed).
model::SampledSignal LeveledRandomBinary(double amplitude_ma, double threshold_ma,
                                         double duration_s, double seed, double min_fraction) {
  model::SampledSignal env = RandomBinary(true, amplitude_ma, duration_s, seed);
  std::mt19937_64 rng(static_cast<std::uint64_t>(seed) ^ 0x9e3779b97f4a7c15ULL);
  double level = 1.0;
  bool was_on = false;
  for (double& u : env.values) {
    const bool on = u > 0.0;
    if (on && !was_on) {
      const double x = static_cast<double>(rng() >> 11) * 0x1.0p-53;
      level = min_fraction + (1.0 - min_fraction) * x;
    }
    if (on) u = threshold_ma + level * (amplitude_ma - threshold_ma);
    was_on = on;
  }
  return env;
}

// §7.4.1 over the whole range: the isometric ramp trial (IRC, pole); two releases of the knee near
// each end of the range of motion (free swings, §4.2.3: τ_pta and τ_ptv with known J over the
// whole range); an ascending amplitude search on the decoupled leg that stops when the knee
// reaches full extension (§5.4.3, "the amplitude that just reaches full extension"; its slow sweep
// of the range under stimulation and the fall after it are active and passive free-swing data
// too); then a dense random-binary free-swing trial at that amplitude (AdaptiveAmplitude).
class RapidParameterisation final : public Protocol {
 public:
  ProtocolDescription Describe() const override;
  std::vector<api::TrialKind> Records() const override {
    return {api::TrialKind::kRapidRamp,    api::TrialKind::kRapidHoldFlexion,
            api::TrialKind::kRapidPassive, api::TrialKind::kRapidHoldExtension,
            api::TrialKind::kRapidRelease, api::TrialKind::kRapidSearch,
            api::TrialKind::kRapidActive};
  }
  api::Status BuildSteps(const PlanInputs& in, PlanBuilder& b) const override;
  api::RunOutcome Conclude(const RunConclusionInput& in, const RunResult& r) const override;
};

ProtocolDescription RapidParameterisation::Describe() const {
  return {
      .name = "rapid_parameterisation",
      .version = 2,
      .title = "Rapid parameterisation",
      .description =
          "The < 30 s routine of §7.4.1 over the whole range of motion: a 7 s isometric ramp "
          "IRC trial (2 impulses, one 4 s cosine ramp) → contraction pole and IRC by ramp "
          "correlation; the motor takes the knee near full flexion and near full extension "
          "and releases it twice (free swings through the range, §4.2.3; the held torque and "
          "the start of each swing, until the knee has travelled 15°, measure J); a ≤ 3 s "
          "ascending "
          "amplitude search on the decoupled leg that stops at full extension (§5.4.3); a 10 s "
          "dense random-binary free-swing trial at the amplitude found → τ_pta and τ_ptv with "
          "known inertia from the passive samples of every swing → the active curves "
          "(Eq. 4.40); ends with a complete parameter set (§7.4.1).",
      .bench_mode = BenchMode::kMixed,
      .kind = ProtocolKind::kRapid,
      .min_rest_s = 1.0,
      .parameters =
          {LockAngleDeg(),
           SettleS(0.8, "time to move to and lock the angle, s"),
           ThresholdMa(),
           MaxMa(),
           Number("conditioning_s", "conditioning burst length, s",
                  {.value = 0.0, .min = 0.0, .max = 10.0}),
           Count("impulses", "number of impulses at max", {.value = 2.0, .min = 1.0, .max = 20.0}),
           Count("ramps", "number of cosine ramps", {.value = 1.0, .min = 1.0, .max = 10.0}),
           Number("below_threshold_ma", "ramp start below threshold, mA",
                  {.value = 5.0, .min = 0.0, .max = 50.0}),
           Number("ramp_duration_s", "whole ramp (half up, half down), s",
                  {.value = 4.0, .min = 0.5, .max = 30.0}),
           Rest("rest_s", "zero stimulation after each isometric element, s",
                {.value = 1.0, .min = 1.0, .max = 60.0}),
           Number("release_margin_fraction",
                  "the knee is released this fraction of the range of motion inside each end of it",
                  {.value = 0.05, .min = 0.02, .max = 0.3}),
           Number("release_move_s", "motor move to each release angle, s",
                  {.value = 0.8, .min = 0.5, .max = 10.0}),
           Number("release_hold_s",
                  "hold at the release angle before releasing (recorded: its torque measures J), s",
                  {.value = 0.2, .min = 0.05, .max = 5.0}),
           Number("release_swing_s", "free swing recorded after each release, s",
                  {.value = 1.8, .min = 1.0, .max = 20.0}),
           Number("swing_settle_s", "swing after the last release before the extension search, s",
                  {.value = 0.3, .min = 0.0, .max = 30.0}),
           Number("search_s",
                  "the extension search raises the amplitude from threshold to max in this time, s",
                  {.value = 3.0, .min = 1.0, .max = 20.0}),
           Number("fall_s", "free swing recorded after the extension search, s",
                  {.value = 0.6, .min = 0.0, .max = 10.0}),
           AmplitudeMa(0.6),
           Number("rb_torque_nm",
                  "0 (default): the random-binary amplitude is the one that just reaches full "
                  "extension "
                  "(§5.4.3), found during the run by the extension search, within the max "
                  "tolerated; > 0: the amplitude giving this isometric torque at the lock angle; "
                  "amplitude_ma is used if neither can be found, N·m",
                  {.value = 0.0, .min = 0.0, .max = 60.0}),
           Number(
               "extension_target_fraction",
               "full extension for that amplitude: this fraction of the range of motion inside its "
               "extension end",
               {.value = 0.1, .min = 0.0, .max = 0.45}),
           Number("rb_level_min_fraction",
                  "each ON burst of the random-binary train takes a seeded level between threshold "
                  "+ this "
                  "fraction of threshold→amplitude and the amplitude (1 = one level)",
                  {.value = 0.5, .min = 0.1, .max = 1.0}),
           Number("rb_min_top_fraction",
                  "the random-binary train's top level is at least threshold + this fraction of "
                  "threshold→max (the prediction inputs' levels), even above full extension",
                  {.value = 0.75, .min = 0.0, .max = 1.0}),
           WithLabel(Number("duration_s", "length of the random-binary trial, s",
                            {.value = 10.0, .min = 3.0, .max = 60.0}),
                     "Length of the random-binary trial"),
           Count("active_seed", "seed of the dense random-binary train and its levels",
                 {.value = 2.0, .min = 0.0, .max = 4294967295.0}),
           Number(
               "inertia_kgm2",
               "limb inertia about the knee if known, kg·m²; 0 = from a prior parameter set or the "
               "subject's weight and shank length (Eq. 4.13)",
               {.value = 0.0, .min = 0.0, .max = 5.0})},
      .offered_first = true};
}

api::Status RapidParameterisation::BuildSteps(const PlanInputs& in, PlanBuilder& b) const {
  const ParameterValues& v = in.values;
  const double lock = v.at("lock_angle_deg");
  b.Prepare("lock", MotorMode::kLocked, lock, v.at("settle_s"));
  const int ramp = b.AddTrial("rapid_isometric_ramp_irc", MotorMode::kLocked);
  b.EnvelopeTrial(
      ramp,
      model::MakeStimulus("isometric_ramp_irc",
                          Pick(v, {"threshold_ma", "max_ma", "conditioning_s", "impulses", "ramps",
                                   "below_threshold_ma", "ramp_duration_s", "rest_s"})),
      MotorMode::kLocked, lock, in.min_rest_s);
  const double rom = in.subject.max_angle_deg - in.subject.min_angle_deg;
  const double margin = v.at("release_margin_fraction") * rom;
  const double lo = in.subject.min_angle_deg + margin, hi = in.subject.max_angle_deg - margin;
  if (!(hi > lo)) {
    return api::Status::InvalidArgument("release_margin_fraction: leaves no range of motion",
                                        "parameters");
  }
  std::vector<int> swings;
  std::vector<std::pair<int, int>> releases;
  // The flexion release keeps the name the identification service and
  // clients know for the rapid routine's passive free swing.
  for (const auto& [name, where, angle] :
       {std::tuple{"rapid_free_swing_passive", "flexion", hi},
        std::tuple{"rapid_release_extension", "extension", lo}}) {
    b.Prepare(std::string("move to ") + where, MotorMode::kPosition, angle, v.at("release_move_s"),
              true);
    // The hold before the release is recorded: its torque is what moves the
    // knee at the release (InertiaFromReleases).
    const int h =
        b.AddTrial(std::string("rapid_release_hold_") + where, MotorMode::kPosition, true);
    b.Rest("hold", v.at("release_hold_s"), 0.0, h, MotorMode::kPosition, angle);
    const int t = b.AddTrial(name, MotorMode::kDecoupled);
    b.Rest("free swing", v.at("release_swing_s"), 0.0, t, MotorMode::kDecoupled, angle);
    swings.push_back(t);
    releases.emplace_back(h, t);
  }
  b.Prepare("swing", MotorMode::kDecoupled, lock, v.at("swing_settle_s"));
  // Ascending search: threshold → max in search_s, ended at full extension.
  const double thr = v.at("threshold_ma"), max_ma = v.at("max_ma");
  if (!(max_ma > thr)) {
    return api::Status::InvalidArgument("max_ma: must be above threshold_ma", "parameters");
  }
  const int search = b.AddTrial("rapid_extension_search", MotorMode::kDecoupled);
  {
    const double search_s = v.at("search_s");
    auto env = std::make_shared<model::SampledSignal>();
    env->rate_hz = model::kStimulusRateHz;
    const auto n = static_cast<std::size_t>(std::llround(search_s * model::kStimulusRateHz));
    for (std::size_t i = 0; i < n; ++i) {
      env->values.push_back(thr +
                            (max_ma - thr) * static_cast<double>(i + 1) / static_cast<double>(n));
    }
    Step s;
    s.phase = StepPhase::kStimulate;
    s.label = "search for full extension";
    s.ticks = static_cast<std::int64_t>(n) * kTicksPerSample;
    s.motor_mode = MotorMode::kDecoupled;
    s.setpoint_deg = lock;
    s.envelope = std::move(env);
    s.trial = search;
    if (v.at("rb_torque_nm") <= 0.0) {
      s.end_below_angle_deg = in.subject.min_angle_deg + v.at("extension_target_fraction") * rom;
    }
    b.Push(std::move(s));
    b.Rest("fall", v.at("fall_s"), 0.0, search, MotorMode::kDecoupled, lock);
  }
  swings.push_back(search);
  const double amp = v.at("amplitude_ma");
  const int active = b.AddTrial("rapid_active_random_binary", MotorMode::kDecoupled);
  b.EnvelopeTrial(active,
                  LeveledRandomBinary(amp, thr, v.at("duration_s"), v.at("active_seed"),
                                      v.at("rb_level_min_fraction")),
                  MotorMode::kDecoupled, lock, 0.0);
  b.plan().adaptive_amplitude = AdaptiveAmplitude{
      ramp, v.at("rb_torque_nm"), amp, thr, max_ma, {active}, v.at("rb_min_top_fraction")};
  // The fit needs the limb inertia (§7.4.1): refused before anything moves.
  if (api::Result<double> inertia = KnownInertia(in.subject, v); !inertia.ok()) {
    return inertia.status();
  }
  b.plan().analysis = std::make_shared<const RapidIdentification>(
      RapidSettings{ramp, swings.front(), active, swings, releases}, ExplicitInertia(v));
  return api::Status::Ok();
}

// The amplitude search's figures (AdaptiveAmplitude), when the run got that far.
api::RunOutcome RapidParameterisation::Conclude(const RunConclusionInput& /*in*/,
                                                const RunResult& r) const {
  api::RunOutcome o = ConcludeCommon(r);
  api::AmplitudeSearchOutcome a;
  a.rb_amplitude_ma = RunFigure(r, "rb_amplitude_ma");
  a.full_extension_amplitude_ma = RunFigure(r, "full_extension_amplitude_ma");
  a.full_extension_reached = RunFlag(r, "full_extension_reached");
  if (a.rb_amplitude_ma || a.full_extension_amplitude_ma || a.full_extension_reached) {
    o.amplitude_search = a;
  }
  return o;
}

}  // namespace

std::unique_ptr<const Protocol> MakeRapidParameterisation() {
  return std::make_unique<RapidParameterisation>();
}

}  // namespace fesbench::server::protocols::catalog
