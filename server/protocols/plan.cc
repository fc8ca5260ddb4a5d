#include "server/protocols/plan.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <sstream>
#include <stdexcept>
#include <tuple>

#include "model/stimulus_generators.h"
#include "model/trajectory.h"
#include "server/protocols/model_gate.h"
#include "server/protocols/tracking_plan.h"

namespace fesbench::server::protocols {
namespace {

std::int64_t Ticks(double s) {
  return static_cast<std::int64_t>(std::llround(s * kTicksPerSecond));
}

model::GeneratorParams Pick(const ParameterValues& v, std::initializer_list<const char*> names) {
  model::GeneratorParams out;
  for (const char* n : names) {
    if (const auto it = v.find(n); it != v.end()) out[n] = it->second;
  }
  return out;
}

class Builder {
 public:
  explicit Builder(Plan& plan) : plan_(plan) {}

  int AddTrial(std::string name, MotorMode mode, bool setpoint = false) {
    plan_.trials.push_back({std::move(name), mode, setpoint});
    return static_cast<int>(plan_.trials.size()) - 1;
  }

  void Prepare(std::string label, MotorMode mode, double angle_deg, double settle_s,
               bool move_from_current = false) {
    Step s;
    s.phase = StepPhase::kPrepare;
    s.label = std::move(label);
    s.ticks = Ticks(settle_s);
    s.motor_mode = mode;
    s.setpoint_deg = angle_deg;
    s.move_from_current = move_from_current;
    Push(std::move(s));
  }

  /// The 50-sample offset that starts a trial (§5.3).
  void Offset(int trial, MotorMode mode, double angle_deg) {
    Step s;
    s.phase = StepPhase::kOffset;
    s.label = "offset";
    s.ticks = kOffsetSamples;
    s.motor_mode = mode;
    s.setpoint_deg = angle_deg;
    s.trial = trial;
    Push(std::move(s));
  }

  void Rest(std::string label, double rest_s, double min_rest_s, int trial, MotorMode mode,
            double angle_deg) {
    Step s;
    s.phase = StepPhase::kRest;
    s.label = std::move(label);
    s.ticks = Ticks(std::max(rest_s, min_rest_s));
    s.motor_mode = mode;
    s.setpoint_deg = angle_deg;
    s.trial = trial;
    s.min_rest_s = min_rest_s;
    Push(std::move(s));
  }

  /// A recorded stimulation envelope: the offset lead, then its runs of
  /// stimulation (kStimulate) and of zero (kRest, whose last 50 ms before
  /// the next stimulation is a fresh torque offset, kOffset).
  void EnvelopeTrial(int trial, const model::SampledSignal& envelope, MotorMode mode,
                     double angle_deg, double min_rest_s) {
    Offset(trial, mode, angle_deg);
    auto env = std::make_shared<const model::SampledSignal>(envelope);
    const std::vector<double>& v = env->values;
    std::size_t i = 0;
    while (i < v.size()) {
      const bool on = v[i] > 0.0;
      std::size_t j = i;
      while (j < v.size() && (v[j] > 0.0) == on) ++j;
      const std::int64_t begin = static_cast<std::int64_t>(i) * kTicksPerSample;
      const std::int64_t len = static_cast<std::int64_t>(j - i) * kTicksPerSample;
      const auto piece = [&](StepPhase phase, std::int64_t from, std::int64_t ticks) {
        if (ticks <= 0) return;
        Step s;
        s.phase = phase;
        s.label = phase == StepPhase::kStimulate ? "stimulate"
                  : phase == StepPhase::kOffset  ? "offset"
                                                 : "rest";
        s.ticks = ticks;
        s.motor_mode = mode;
        s.setpoint_deg = angle_deg;
        s.envelope = env;
        s.stim_offset_ticks = from;
        s.trial = trial;
        if (phase == StepPhase::kRest) s.min_rest_s = std::min(min_rest_s, ticks / 1000.0);
        Push(std::move(s));
      };
      if (on) {
        piece(StepPhase::kStimulate, begin, len);
      } else if (j < v.size() && len >= 2 * kOffsetSamples) {
        piece(StepPhase::kRest, begin, len - kOffsetSamples);
        piece(StepPhase::kOffset, begin + len - kOffsetSamples, kOffsetSamples);
      } else {
        piece(StepPhase::kRest, begin, len);
      }
      i = j;
    }
  }

  void Move(std::string label, std::shared_ptr<const model::Trajectory> trajectory, int trial) {
    Step s;
    s.phase = StepPhase::kMove;
    s.label = std::move(label);
    s.ticks = Ticks(trajectory->duration_s());
    s.motor_mode = MotorMode::kPosition;
    s.setpoint_deg = trajectory->At(trajectory->duration_s()).angle_deg;
    s.trajectory = std::move(trajectory);
    s.trial = trial;
    Push(std::move(s));
  }

  void MoveTo(std::string label, double angle_deg, double move_s, int trial) {
    Step s;
    s.phase = StepPhase::kMove;
    s.label = std::move(label);
    s.ticks = Ticks(move_s);
    s.motor_mode = MotorMode::kPosition;
    s.setpoint_deg = angle_deg;
    s.move_from_current = true;
    s.trial = trial;
    Push(std::move(s));
  }

  void Push(Step s) {
    if (s.ticks > 0) plan_.steps.push_back(std::move(s));
  }

 private:
  Plan& plan_;
};

model::SampledSignal Stimulus(const char* generator, const model::GeneratorParams& params) {
  return model::MakeStimulus(generator, params);
}

void BuildTolerance(const ParameterValues& v, Plan& plan, Builder& b) {
  const double lock = v.at("lock_angle_deg");
  plan.max_stim_ma = v.at("ceiling_ma");
  plan.tolerance = ToleranceSettings{v.at("threshold_torque_nm"), v.at("min_torque_at_max_nm")};
  if (!(v.at("ceiling_ma") > v.at("start_ma"))) {
    throw std::invalid_argument("ceiling_ma: must be above start_ma");
  }
  b.Prepare("lock", MotorMode::kLocked, lock, v.at("settle_s"));
  const int t = b.AddTrial("tolerance_test", MotorMode::kLocked);
  b.Offset(t, MotorMode::kLocked, lock);
  Step s;
  s.phase = StepPhase::kStimulate;
  s.label = "raise amplitude";
  s.ticks = Ticks((v.at("ceiling_ma") - v.at("start_ma")) / v.at("rate_ma_per_s"));
  s.motor_mode = MotorMode::kLocked;
  s.setpoint_deg = lock;
  s.tolerance_ramp = true;
  s.ramp_start_ma = v.at("start_ma");
  s.ramp_ma_per_s = v.at("rate_ma_per_s");
  s.trial = t;
  b.Push(std::move(s));
  b.Rest("relax", 1.0, 0.0, t, MotorMode::kLocked, lock);
}

void BuildIsometric(const std::string& name, const ParameterValues& v, double min_rest_s,
                    Builder& b) {
  const double lock = v.at("lock_angle_deg");
  b.Prepare("lock", MotorMode::kLocked, lock, v.at("settle_s"));
  model::SampledSignal env;
  if (name == "isometric_ramp_irc") {
    env =
        Stimulus("isometric_ramp_irc",
                 Pick(v, {"threshold_ma", "max_ma", "conditioning_s", "conditioning_fraction",
                          "impulses", "ramps", "below_threshold_ma", "ramp_duration_s", "rest_s"}));
  } else if (name == "isometric_step_irc") {
    env = Stimulus("step_bursts",
                   Pick(v, {"threshold_ma", "max_ma", "levels", "burst_s", "ramp_s", "rest_s"}));
  } else if (name == "isometric_impulse_irc") {
    env =
        Stimulus("impulse_series",
                 Pick(v, {"threshold_ma", "max_ma", "count", "below_threshold_ma", "interval_s"}));
  } else {
    env = Stimulus("plateau_profile", Pick(v, {"threshold_ma", "max_ma", "above_threshold_ma",
                                               "lead_s", "ramp_s", "hold_s", "tail_s"}));
  }
  const int t = b.AddTrial(name, MotorMode::kLocked);
  b.EnvelopeTrial(t, env, MotorMode::kLocked, lock, min_rest_s);
}

void BuildSequential(const ParameterValues& v, double min_rest_s, Builder& b) {
  const double ref = v.at("reference_deg");
  auto positions = std::make_shared<model::PiecewisePolynomialTrajectory>(
      model::PassivePositions({ref, v.at("max_angle_deg"), v.at("min_angle_deg"),
                               static_cast<int>(v.at("positions")), v.at("hold_s"), v.at("move_s"),
                               10.0})
          .trajectory);
  model::PassiveVelocitiesOptions pv;
  pv.reference_deg = ref;
  pv.min_deg = v.at("min_angle_deg");
  pv.speeds = static_cast<int>(v.at("speeds"));
  pv.max_speed_deg_s = v.at("max_speed_deg_s");
  pv.pause_s = std::max(v.at("pause_s"), min_rest_s);
  auto velocities = std::make_shared<model::PiecewisePolynomialTrajectory>(
      model::PassiveVelocities(pv).trajectory);
  const int tp = b.AddTrial("passive_positions", MotorMode::kPosition, true);
  b.Prepare("move to reference", MotorMode::kPosition, ref, v.at("settle_s"), true);
  b.Offset(tp, MotorMode::kPosition, ref);
  b.Move("positions", positions, tp);
  const int tv = b.AddTrial("passive_velocities", MotorMode::kPosition, true);
  b.Prepare("move to reference", MotorMode::kPosition, ref, v.at("settle_s"), true);
  b.Offset(tv, MotorMode::kPosition, ref);
  b.Move("velocities", velocities, tv);
}

void BuildSimultaneous(const ParameterValues& v, Builder& b) {
  if (v.at("min_angle_deg") > 90.0 || v.at("max_angle_deg") < 90.0) {
    // §5.4.2: the reference torque is measured at 90° of flexion.
    throw std::invalid_argument("min_angle_deg..max_angle_deg must include the 90° reference");
  }
  const int n = static_cast<int>(v.at("trajectories"));
  for (int k = 0; k < n; ++k) {
    model::SumOfSinesOptions o;
    o.min_deg = v.at("min_angle_deg");
    o.max_deg = v.at("max_angle_deg");
    o.max_velocity_deg_s = v.at("max_velocity_deg_s");
    o.duration_s = v.at("duration_s");
    o.seed = static_cast<std::uint64_t>(v.at("seed")) + static_cast<std::uint64_t>(k);
    auto traj = std::make_shared<model::SumOfSinesTrajectory>(o);
    const int t =
        b.AddTrial("passive_simultaneous_" + std::to_string(k + 1), MotorMode::kPosition, true);
    b.Prepare("move to reference", MotorMode::kPosition, 90.0, v.at("settle_s"), true);
    b.Offset(t, MotorMode::kPosition, 90.0);
    b.MoveTo("move to start", traj->centre_deg(), v.at("settle_s"), t);
    b.Move("sum of sines", traj, t);
  }
}

model::SampledSignal RandomBinary(bool dense, double amplitude_ma, double duration_s, double seed) {
  return Stimulus(dense ? "random_binary_dense" : "random_binary_sparse",
                  {{"amplitude_ma", amplitude_ma}, {"duration_s", duration_s}, {"seed", seed}});
}

void BuildFreeSwing(const std::string& name, const ParameterValues& v, double min_rest_s,
                    Builder& b) {
  b.Prepare("decouple", MotorMode::kDecoupled, 90.0, v.at("settle_s"));
  const double amp = v.at("amplitude_ma");
  if (name == "free_swing_passive") {
    const int t = b.AddTrial(name, MotorMode::kDecoupled);
    b.EnvelopeTrial(t, RandomBinary(false, amp, v.at("duration_s"), v.at("seed")),
                    MotorMode::kDecoupled, 90.0, 0.0);
    return;
  }
  const int t1 = b.AddTrial("active_random_binary_rb1", MotorMode::kDecoupled);
  b.EnvelopeTrial(t1, RandomBinary(true, amp, v.at("duration_s"), v.at("rb1_seed")),
                  MotorMode::kDecoupled, 90.0, 0.0);
  b.Rest("rest between trains", v.at("rest_s"), min_rest_s, -1, MotorMode::kDecoupled, 90.0);
  const int t2 = b.AddTrial("active_random_binary_rb2", MotorMode::kDecoupled);
  b.EnvelopeTrial(t2, RandomBinary(true, amp, v.at("duration_s"), v.at("rb2_seed")),
                  MotorMode::kDecoupled, 90.0, 0.0);
}

// The pendulum test (MODEL.md, passive-only identification): each swing
// the motor takes the relaxed knee to the release angle and holds it, then
// lets go; the swing is recorded from the release, with no stimulation.
void BuildPendulum(const ParameterValues& v, Builder& b) {
  const double angle = v.at("release_angle_deg");
  const auto releases = static_cast<int>(v.at("release_count"));
  for (int k = 1; k <= releases; ++k) {
    b.Prepare("move to the release angle", MotorMode::kPosition, angle, v.at("settle_s"), true);
    b.Rest("hold", v.at("release_hold_s"), 0.0, -1, MotorMode::kPosition, angle);
    const int t = b.AddTrial("pendulum_" + std::to_string(k), MotorMode::kDecoupled);
    b.Rest("free swing", v.at("release_swing_s"), 0.0, t, MotorMode::kDecoupled, angle);
  }
}

void BuildPrediction(const std::string& name, const ParameterValues& v, Builder& b) {
  b.Prepare("decouple", MotorMode::kDecoupled, 90.0, v.at("settle_s"));
  model::SampledSignal env;
  if (name == "prediction_step") {
    env =
        Stimulus("prediction_step",
                 Pick(v, {"threshold_ma", "max_ma", "level_fraction", "onset_s", "on_s", "off_s"}));
  } else if (name == "prediction_ramp") {
    env = Stimulus("prediction_ramp", Pick(v, {"max_ma", "up_s", "down_s"}));
  } else if (name == "prediction_sine") {
    env = Stimulus("prediction_sine",
                   Pick(v, {"threshold_ma", "max_ma", "above_threshold_ma", "tail_s"}));
  } else {
    env =
        RandomBinary(v.at("dense") != 0.0, v.at("amplitude_ma"), v.at("duration_s"), v.at("seed"));
  }
  const int t = b.AddTrial(name, MotorMode::kDecoupled);
  b.EnvelopeTrial(t, env, MotorMode::kDecoupled, 90.0, 0.0);
}

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

// §7.4.1 over the whole range: the isometric ramp trial (IRC, pole); two
// releases of the knee near each end of the range of motion (free swings,
// §4.2.3: τ_pta and τ_ptv with known J over the whole range); an ascending
// amplitude search on the decoupled leg that stops when the knee reaches full
// extension (§5.4.3, "the amplitude that just reaches full extension"; its
// slow sweep of the range under stimulation and the fall after it are active
// and passive free-swing data too); then a dense random-binary free-swing
// trial at that amplitude (AdaptiveAmplitude).
void BuildRapid(const ParameterValues& v, double min_rest_s, const SubjectContext& subject,
                Plan& plan, Builder& b) {
  const double lock = v.at("lock_angle_deg");
  b.Prepare("lock", MotorMode::kLocked, lock, v.at("settle_s"));
  const int ramp = b.AddTrial("rapid_isometric_ramp_irc", MotorMode::kLocked);
  b.EnvelopeTrial(ramp,
                  Stimulus("isometric_ramp_irc",
                           Pick(v, {"threshold_ma", "max_ma", "conditioning_s", "impulses", "ramps",
                                    "below_threshold_ma", "ramp_duration_s", "rest_s"})),
                  MotorMode::kLocked, lock, min_rest_s);
  const double rom = subject.max_angle_deg - subject.min_angle_deg;
  const double margin = v.at("release_margin_fraction") * rom;
  const double lo = subject.min_angle_deg + margin, hi = subject.max_angle_deg - margin;
  if (!(hi > lo)) throw std::invalid_argument("release_margin_fraction: leaves no range of motion");
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
  if (!(max_ma > thr)) throw std::invalid_argument("max_ma: must be above threshold_ma");
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
      s.end_below_angle_deg = subject.min_angle_deg + v.at("extension_target_fraction") * rom;
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
  plan.rapid = RapidSettings{ramp, swings.front(), active, swings, releases};
  plan.adaptive_amplitude = AdaptiveAmplitude{
      ramp, v.at("rb_torque_nm"), amp, thr, max_ma, {active}, v.at("rb_min_top_fraction")};
}

}  // namespace

std::int64_t Plan::total_ticks() const {
  std::int64_t n = 0;
  for (const Step& s : steps) n += s.ticks;
  return n;
}

// The tracking target of the resolved values (docs/PROTOCOLS.md, `tracking`): a sine starting at
// its middle, holds cycling through lo + (½, 0, ¾, ¼)·(hi − lo), or a ramp
// lo → hi → lo.
model::KneeTarget TrackingTarget(const ParameterValues& v, const std::vector<double>& uploaded,
                                 std::string& name) {
  const double lo = v.at("lo_deg"), hi = v.at("hi_deg"), duration = v.at("duration_s");
  switch (static_cast<int>(v.at("target"))) {
    case 3:
      name = "uploaded";
      return model::SampledTarget(uploaded, 200.0);
    case 1: {
      name = "holds";
      const double hold = v.at("hold_s"), move = v.at("move_s");
      const auto count = static_cast<std::size_t>(
          std::max(2.0, std::floor((duration + move) / (hold + move))));
      // Steps of different sizes and both directions inside [lo, hi].
      const double cycle[] = {0.5, 0.0, 0.75, 0.25};
      std::vector<double> angles;
      for (std::size_t i = 0; i < count; ++i) angles.push_back(lo + cycle[i % 4] * (hi - lo));
      // The last hold lasts until duration_s: the target lasts what was asked.
      model::KneeTarget target = model::HoldsTarget(angles, hold, move);
      const auto samples = static_cast<std::size_t>(std::floor(duration * target.rate_hz + 1e-9)) + 1;
      while (target.angle_deg.size() < samples) {
        target.angle_deg.push_back(target.angle_deg.back());
        target.velocity_deg_s.push_back(0.0);
        target.accel_deg_s2.push_back(0.0);
      }
      return target;
    }
    case 2: {
      name = "ramp";
      const auto n = static_cast<std::size_t>(std::llround(duration * 200.0)) + 1;
      std::vector<double> angle(n);
      for (std::size_t i = 0; i < n; ++i) {
        const double x = static_cast<double>(i) / static_cast<double>(n - 1);  // 0..1
        angle[i] = lo + (hi - lo) * (1.0 - std::abs(2.0 * x - 1.0));
      }
      return model::SampledTarget(std::move(angle), 200.0);
    }
    default:
      name = "sine";
      return model::SineTarget(lo, hi, v.at("frequency_hz"), duration);
  }
}

// The longest run of samples in which the set says the target cannot be
// followed: [begin, end). Samples whose activation or amplitude the inverse
// held at its top count; so do those held at zero (the target asks for
// flexion, which the quadriceps cannot give) where the target lies beyond
// the knee's rest angle — there the knee cannot be held at all, while
// elsewhere it only falls behind for a moment.
std::pair<std::size_t, std::size_t> LongestUnreachable(const model::Feedforward& ff,
                                                       const model::KneeTarget& target,
                                                       double max_ma, double rest_deg) {
  const auto out = [&](std::size_t i) {
    if (!ff.saturated[i]) return false;
    if (ff.activation[i] >= 1.0 || ff.amplitude_ma[i] >= max_ma) return true;
    return target.angle_deg[i] > rest_deg;
  };
  std::pair<std::size_t, std::size_t> best{0, 0};
  for (std::size_t i = 0; i < ff.saturated.size();) {
    if (!out(i)) {
      ++i;
      continue;
    }
    std::size_t j = i;
    while (j < ff.saturated.size() && out(j)) ++j;
    if (j - i > best.second - best.first) best = {i, j};
    i = j;
  }
  return best;
}

api::Status BuildTracking(const ParameterValues& resolved, const SubjectContext& subject,
                          const std::vector<double>& uploaded, const ParameterValues* given,
                          Plan& plan, Builder& b) {
  ParameterValues v = resolved;
  // Only the model-based controllers need the leg's set; pid uses none when
  // its gains are given (docs/PROTOCOLS.md, tracking).
  const auto kind = static_cast<model::ControllerKind>(static_cast<int>(v.at("controller")));
  const bool model_based = kind != model::ControllerKind::kPid;
  const bool pid_gains_given =
      v.at("kp_ma_per_deg") > 0.0 || v.at("ki_ma_per_deg_s") > 0.0 || v.at("kd_ma_s_per_deg") > 0.0;
  if (!subject.parameter_set && (model_based || !pid_gains_given)) {
    if (model_based) return api::Status::FailedPrecondition(NoApprovedSetMessage("tracking"));
    return api::Status::FailedPrecondition(
        NoApprovedSetMessage("tracking with pid's gains tuned from the set") +
        "; or give pid's gains (kp_ma_per_deg, ki_ma_per_deg_s, kd_ma_s_per_deg)");
  }
  const bool upload = static_cast<int>(v.at("target")) == 3;
  if (!upload && !(v.at("lo_deg") < v.at("hi_deg"))) {
    return api::Status::InvalidArgument("must be above lo_deg", "parameters.hi_deg");
  }
  if (upload != !uploaded.empty()) {
    return upload ? api::Status::InvalidArgument(
                        "an uploaded target needs the request's target_samples (t_s, angle_deg)",
                        "target_samples")
                  : api::Status::InvalidArgument(
                        "target_samples is only read with parameters.target = uploaded",
                        "target_samples");
  }
  for (std::size_t i = 0; i < uploaded.size(); ++i) {
    if (!(uploaded[i] >= subject.min_angle_deg && uploaded[i] <= subject.max_angle_deg)) {
      std::ostringstream why;
      why << "the target leaves the range of motion [" << subject.min_angle_deg << ", "
          << subject.max_angle_deg << "] deg at t = " << static_cast<double>(i) / 200.0 << " s ("
          << uploaded[i] << "°)";
      return api::Status::InvalidArgument(why.str(), "target_samples.angle_deg");
    }
  }
  TrackingSettings t;
  t.params = subject.parameter_set;
  if (t.params) {
    t.reachable_extension_deg = model::ReachableExtensionDeg(*t.params, v.at("max_ma"));
  }
  // The default target fits the leg: its extended end no further than the
  // set says the maximum holds the knee with a fifth of the muscle to spare
  // (kDefaultTargetActivationFraction). A lo_deg the client gave stays; the
  // gate below judges it for the controllers that invert the set.
  if (t.params && !upload && given != nullptr && !given->contains("lo_deg")) {
    const double fitted = std::ceil(
        model::ReachableExtensionDeg(*t.params, v.at("max_ma"), kDefaultTargetActivationFraction));
    const double lo =
        std::max(v.at("lo_deg"), std::min(fitted, v.at("hi_deg") - kMinFittedSpanDeg));
    if (lo > v.at("lo_deg")) {
      v["lo_deg"] = lo;
      plan.parameters["lo_deg"] = lo;  // the run records the target used
    }
  }
  t.target = TrackingTarget(v, uploaded, t.target_name);
  t.lead_in_s = v.at("lead_in_s");
  t.max_rate_ma_per_s = v.at("max_rate_ma_per_s");
  t.max_saturation_s = v.at("max_saturation_s");
  t.options.kind = kind;
  t.options.threshold_ma = std::min(v.at("threshold_ma"), v.at("max_ma"));
  t.options.max_amplitude_ma = v.at("max_ma");
  t.options.forgetting = v.at("forgetting");
  // The amplitude PID's gains (pid) or the torque PID's (around the model).
  const bool amplitude = t.options.kind == model::ControllerKind::kPid;
  const double kp = v.at(amplitude ? "kp_ma_per_deg" : "kp_nm_per_deg");
  const double ki = v.at(amplitude ? "ki_ma_per_deg_s" : "ki_nm_per_deg_s");
  const double kd = v.at(amplitude ? "kd_ma_s_per_deg" : "kd_nm_s_per_deg");
  if (kp > 0.0 || ki > 0.0 || kd > 0.0) t.options.gains = model::Pid::Gains{kp, ki, kd, 0.02};
  // The slew limit: given, or derived from the set's loop (model::DefaultSlewLimit:
  // no faster than the loop can use, so it adds no lag where the margin is set).
  if (t.max_rate_ma_per_s <= 0.0) {
    t.max_rate_ma_per_s = t.params
                              ? std::round(model::DefaultSlewLimit(*t.params, t.target, t.options))
                              : kModelFreeSlewLimitMaPerS;
    plan.parameters["max_rate_ma_per_s"] = t.max_rate_ma_per_s;
  } else if (t.max_rate_ma_per_s < model::kMinSlewLimitMaPerS) {
    return api::Status::InvalidArgument("must be 0 (derived from the set) or 5–5000 mA/s",
                                        "parameters.max_rate_ma_per_s");
  }
  // The model gate of tracking, for the controllers that invert the set: its
  // inverse along the target must not stay saturated longer than the
  // controller would be allowed to. pid uses no model, so the set's limits
  // do not refuse it: below it the interlock holds the amplitude to the
  // session's max tolerated and the saturation stop ends the run
  // (docs/PROTOCOLS.md, tracking; docs/SAFETY.md).
  if (model_based) {
    model::InverseOptions inverse;
    inverse.max_amplitude_ma = t.options.max_amplitude_ma;
    const model::Feedforward ff = model::InvertModel(*t.params, t.target, inverse);
    const double rest_deg = FreeSwingStartAngleDeg(*t.params);
    const auto [from, to] = LongestUnreachable(ff, t.target, inverse.max_amplitude_ma, rest_deg);
    const double span_s = static_cast<double>(to - from) / t.target.rate_hz;
    if (span_s > t.max_saturation_s) {
      const bool too_much =
          ff.activation[from] >= 1.0 || ff.amplitude_ma[from] >= inverse.max_amplitude_ma;
      std::ostringstream why;
      why << "the parameter set";
      if (subject.parameter_set_id) why << " #" << *subject.parameter_set_id;
      why << " predicts the target cannot be followed: from t = " << ff.t_s[from] << " s (target "
          << t.target.angle_deg[from] << "°) for " << span_s << " s it needs ";
      if (too_much) {
        why << "more than the maximum " << inverse.max_amplitude_ma
            << " mA gives; the set predicts the maximum holds the knee no further extended than "
            << *t.reachable_extension_deg << "°";
      } else {
        why << "the knee held beyond its rest angle " << rest_deg
            << "° (flexion, which the quadriceps cannot give)";
      }
      why << " (longer than max_saturation_s = " << t.max_saturation_s << " s); pid, which "
             "uses no model, is not refused";
      return api::Status::FailedPrecondition(why.str());
    }
    // A target whose extended end lies past where the maximum holds the
    // knee at all: each dip past it may be shorter than max_saturation_s (a
    // sine's extended end), but the controller strains at the maximum there
    // every cycle and cannot reach it.
    const double reach = *t.reachable_extension_deg;
    const auto most_extended =
        std::min_element(t.target.angle_deg.begin(), t.target.angle_deg.end());
    if (*most_extended < reach - kReachToleranceDeg) {
      std::ostringstream why;
      why << "the parameter set";
      if (subject.parameter_set_id) why << " #" << *subject.parameter_set_id;
      why << " predicts the target cannot be followed: its most extended angle " << *most_extended
          << "° (t = "
          << static_cast<double>(most_extended - t.target.angle_deg.begin()) / t.target.rate_hz
          << " s) lies beyond the " << reach << "° the maximum " << t.options.max_amplitude_ma
          << " mA holds the knee at; give lo_deg at or above it, or leave lo_deg out (the "
             "default target fits the leg); pid, which uses no model, is not refused";
      return api::Status::FailedPrecondition(why.str());
    }
  }
  b.Prepare("decouple", MotorMode::kDecoupled, 90.0, v.at("settle_s"));
  const int trial = b.AddTrial("tracking_" + t.target_name, MotorMode::kDecoupled);
  Step s;
  s.phase = StepPhase::kStimulate;
  s.label = "track";
  s.ticks = Ticks(t.lead_in_s + t.target.duration_s());
  s.motor_mode = MotorMode::kDecoupled;
  s.trial = trial;
  s.closed_loop = true;
  b.Push(std::move(s));
  plan.tracking = std::make_shared<const TrackingSettings>(std::move(t));
  // The run records the set it inverts (0 resolved to the leg's approved set).
  if (subject.parameter_set_id) {
    plan.parameters["parameter_set_id"] = static_cast<double>(*subject.parameter_set_id);
  }
  return api::Status::Ok();
}

api::Status BuildDailyCheck(const ParameterValues& v, double min_rest_s,
                            const SubjectContext& subject, Plan& plan, Builder& b) {
  if (!subject.parameter_set) {
    return api::Status::FailedPrecondition(NoApprovedSetMessage("daily_check"));
  }
  const double lock = v.at("lock_angle_deg");
  b.Prepare("lock", MotorMode::kLocked, lock, v.at("settle_s"));
  const int ramp = b.AddTrial("daily_check_ramp_irc", MotorMode::kLocked);
  model::GeneratorParams g = Pick(v, {"threshold_ma", "max_ma", "impulses", "below_threshold_ma",
                                      "ramp_duration_s", "rest_s"});
  g["conditioning_s"] = 0.0;
  g["ramps"] = 1.0;
  b.EnvelopeTrial(ramp, Stimulus("isometric_ramp_irc", g), MotorMode::kLocked, lock, min_rest_s);
  b.Prepare("decouple", MotorMode::kDecoupled, lock, v.at("swing_settle_s"));
  const int swing = b.AddTrial("daily_check_swing", MotorMode::kDecoupled);
  b.EnvelopeTrial(swing, RandomBinary(true, v.at("amplitude_ma"), v.at("swing_s"), v.at("seed")),
                  MotorMode::kDecoupled, lock, 0.0);
  plan.daily_check = DailyCheckSettings{ramp, swing, lock};
  return api::Status::Ok();
}

api::Result<Plan> BuildPlan(const ProtocolDescription& protocol, const ParameterValues& values,
                            const SubjectContext& subject,
                            const std::vector<double>& uploaded_target,
                            const ParameterValues* given) {
  Plan plan;
  plan.protocol = protocol.name;
  plan.protocol_version = protocol.version;
  plan.kind = protocol.kind;
  plan.parameters = values;
  plan.max_stim_ma = subject.max_tolerated_ma;
  Builder b(plan);
  const std::string& name = protocol.name;
  try {
    if (name == "tolerance_test") {
      BuildTolerance(values, plan, b);
    } else if (name.starts_with("isometric_")) {
      BuildIsometric(name, values, protocol.min_rest_s, b);
    } else if (name == "passive_sequential") {
      BuildSequential(values, protocol.min_rest_s, b);
    } else if (name == "passive_simultaneous") {
      BuildSimultaneous(values, b);
    } else if (name == "free_swing_passive" || name == "active_random_binary") {
      BuildFreeSwing(name, values, protocol.min_rest_s, b);
    } else if (name.starts_with("prediction_")) {
      BuildPrediction(name, values, b);
    } else if (name == "pendulum_test") {
      BuildPendulum(values, b);
    } else if (name == "rapid_parameterisation") {
      BuildRapid(values, protocol.min_rest_s, subject, plan, b);
    } else if (name == "daily_check") {
      if (api::Status st = BuildDailyCheck(values, protocol.min_rest_s, subject, plan, b); !st.ok())
        return st;
    } else if (name == "tracking") {
      if (api::Status st = BuildTracking(values, subject, uploaded_target, given, plan, b);
          !st.ok())
        return st;
    } else {
      return api::Status::NotFound("no plan for protocol " + name);
    }
  } catch (const std::out_of_range& e) {
    return api::Status::InvalidArgument(std::string("parameters not resolved: ") + e.what(),
                                        "parameters");
  } catch (const std::invalid_argument& e) {
    return api::Status::InvalidArgument(e.what(), "parameters");
  }
  return plan;
}

api::Result<Plan> MakePlan(std::string_view protocol, const ParameterValues& values,
                           const SubjectContext& subject,
                           const std::vector<double>& uploaded_target) {
  const ProtocolDescription* p = FindProtocol(protocol);
  if (p == nullptr) return api::Status::NotFound("unknown protocol " + std::string(protocol));
  api::Result<ParameterValues> resolved = ResolveParameters(*p, values, subject);
  if (!resolved.ok()) return resolved.status();
  return BuildPlan(*p, *resolved, subject, uploaded_target, &values);
}

model::SampledSignal TrialEnvelope(const Plan& plan, int trial) {
  model::SampledSignal out;
  out.rate_hz = 200.0;
  for (const Step& s : plan.steps) {
    if (s.trial != trial) continue;
    const std::int64_t samples = s.ticks / kTicksPerSample;
    for (std::int64_t k = 0; k < samples; ++k) {
      double u = 0.0;
      if (s.envelope) {
        const std::int64_t idx = (s.stim_offset_ticks + k * kTicksPerSample) / kTicksPerSample;
        if (idx >= 0 && idx < static_cast<std::int64_t>(s.envelope->values.size())) {
          u = s.envelope->values[static_cast<std::size_t>(idx)];
        }
      }
      out.values.push_back(u);
    }
  }
  return out;
}

}  // namespace fesbench::server::protocols
