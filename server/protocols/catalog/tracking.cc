// The `tracking` protocol (docs/PROTOCOLS.md, `tracking`).

#include "model/tracking.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "server/protocols/catalog/parameters.h"
#include "server/protocols/model_gate.h"
#include "server/protocols/protocol_registry.h"
#include "server/protocols/tracking_plan.h"

namespace fesbench::server::protocols::catalog {
namespace {

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
      const auto count =
          static_cast<std::size_t>(std::max(2.0, std::floor((duration + move) / (hold + move))));
      // Steps of different sizes and both directions inside [lo, hi].
      const double cycle[] = {0.5, 0.0, 0.75, 0.25};
      std::vector<double> angles;
      for (std::size_t i = 0; i < count; ++i) angles.push_back(lo + cycle[i % 4] * (hi - lo));
      // The last hold lasts until duration_s: the target lasts what was asked.
      model::KneeTarget target = model::HoldsTarget(angles, hold, move);
      const auto samples =
          static_cast<std::size_t>(std::floor(duration * target.rate_hz + 1e-9)) + 1;
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

// Closed-loop stimulation along a target knee angle (§7.6.3), refused where the set says the
// target cannot be followed.
class Tracking final : public Protocol {
 public:
  ProtocolDescription Describe() const override;
  std::vector<api::TrialKind> Records() const override { return {api::TrialKind::kTracking}; }
  api::Status BuildSteps(const PlanInputs& in, PlanBuilder& b) const override;
  api::RunOutcome Conclude(const RunConclusionInput& in, const RunResult& r) const override;
};

ProtocolDescription Tracking::Describe() const {
  return {
      .name = "tracking",
      .version = 1,
      .title = "Knee-angle tracking",
      .description =
          "Decoupled: the stimulation follows a target knee angle (a 0.2 Hz sine between two "
          "angles, holds at angles, a ramp up and down, or an uploaded trajectory) with the leg's "
          "parameter set, after a "
          "lead-in from where the knee hangs to the target's start. Controllers: pid (a PID on "
          "the angle error above the threshold), inverse_model (the inverted model as "
          "feedforward with a PID around it) and adaptive (the same with τ_scale followed "
          "online). Amplitude within the max tolerated and slew-limited; a controller saturated "
          "at the maximum longer than max_saturation_s ends the run (§7.6.3).",
      .bench_mode = BenchMode::kDecoupled,
      .kind = ProtocolKind::kTracking,
      .min_rest_s = 0.0,
      .parameters =
          {ThresholdMa(),
           MaxMa(),
           Choice("controller", "0 = pid, 1 = inverse_model, 2 = adaptive", 1,
                  {"pid", "inverse_model", "adaptive"}),
           Choice("target",
                  "0 = sine, 1 = holds, 2 = ramp, 3 = uploaded (the request's target_samples: t_s, "
                  "angle_deg)",
                  0, {"sine", "holds", "ramp", "uploaded"}),
           Number("lo_deg",
                  "lower target angle (extension side), deg (left out: 30, or with a set no "
                  "further extended than the set says the maximum holds the knee)",
                  {.value = 30.0, .min = 0.0, .max = 180.0}),
           Number("hi_deg", "upper target angle (flexion side), deg",
                  {.value = 80.0, .min = 0.0, .max = 180.0}),
           Number("frequency_hz", "sine frequency, Hz", {.value = 0.2, .min = 0.01, .max = 1.0}),
           WithLabel(Number("duration_s", "length of the target after the lead-in, s",
                            {.value = 30.0, .min = 2.0, .max = 600.0}),
                     "Length of the target (after the lead-in)"),
           Number("hold_s", "holds: time at each angle, s",
                  {.value = 4.0, .min = 0.5, .max = 60.0}),
           Number("move_s", "holds: time to move between angles, s",
                  {.value = 1.0, .min = 0.2, .max = 10.0}),
           Number("lead_in_s", "move from the hanging knee to the target's start, s",
                  {.value = 3.0, .min = 1.0, .max = 10.0}),
           Number("kp_ma_per_deg",
                  "pid: proportional gain on the amplitude, mA/deg (pid's three gains 0: tuned "
                  "from the "
                  "set)",
                  {.value = 0.0, .min = 0.0, .max = 20.0}),
           Number("ki_ma_per_deg_s", "pid: integral gain, mA/(deg·s)",
                  {.value = 0.0, .min = 0.0, .max = 50.0}),
           Number("kd_ma_s_per_deg", "pid: derivative gain, mA·s/deg",
                  {.value = 0.0, .min = 0.0, .max = 5.0}),
           Number("kp_nm_per_deg",
                  "inverse_model, adaptive: proportional gain of the PID on the torque around the "
                  "inverted model, N·m/deg (the three gains 0: tuned from the set)",
                  {.value = 0.0, .min = 0.0, .max = 20.0}),
           Number("ki_nm_per_deg_s", "inverse_model, adaptive: integral gain, N·m/(deg·s)",
                  {.value = 0.0, .min = 0.0, .max = 50.0}),
           Number("kd_nm_s_per_deg", "inverse_model, adaptive: derivative gain, N·m·s/deg",
                  {.value = 0.0, .min = 0.0, .max = 5.0}),
           Number("max_rate_ma_per_s",
                  "fastest amplitude change, mA/s (0: derived from the set's loop; 1000 for pid "
                  "without a set)",
                  {.value = 0.0, .min = 0.0, .max = 5000.0}),
           Number("max_saturation_s",
                  "the run ends if the controller asks for more than the maximum "
                  "this long, s",
                  {.value = 3.0, .min = 0.2, .max = 60.0}),
           Number("forgetting",
                  "adaptive: forgetting factor of the τ_scale estimate (per 5 ms sample)",
                  {.value = 0.999, .min = 0.9, .max = 1.0}),
           Count("parameter_set_id",
                 "the leg's parameter set to invert (0: its approved set; another must have "
                 "been approved)",
                 {.value = 0.0, .min = 0.0, .max = 9007199254740992.0}),
           SettleS(2.0, "swing after decoupling before the lead-in, s")},
      .follows_target = true};
}

api::Status Tracking::BuildSteps(const PlanInputs& in, PlanBuilder& b) const {
  ParameterValues v = in.values;
  // Only the model-based controllers need the leg's set; pid uses none when
  // its gains are given (docs/PROTOCOLS.md, tracking).
  const auto kind = static_cast<model::ControllerKind>(static_cast<int>(v.at("controller")));
  const bool model_based = kind != model::ControllerKind::kPid;
  const bool pid_gains_given =
      v.at("kp_ma_per_deg") > 0.0 || v.at("ki_ma_per_deg_s") > 0.0 || v.at("kd_ma_s_per_deg") > 0.0;
  if (!in.subject.parameter_set && (model_based || !pid_gains_given)) {
    if (model_based)
      return api::Status::FailedPrecondition(NoApprovedSetMessage(b.plan().protocol));
    return api::Status::FailedPrecondition(
        NoApprovedSetMessage("tracking with pid's gains tuned from the set") +
        "; or give pid's gains (kp_ma_per_deg, ki_ma_per_deg_s, kd_ma_s_per_deg)");
  }
  const bool upload = static_cast<int>(v.at("target")) == 3;
  if (!upload && !(v.at("lo_deg") < v.at("hi_deg"))) {
    return api::Status::InvalidArgument("must be above lo_deg", "parameters.hi_deg");
  }
  if (upload != !in.uploaded_target.empty()) {
    return upload ? api::Status::InvalidArgument(
                        "an uploaded target needs the request's target_samples (t_s, angle_deg)",
                        "target_samples")
                  : api::Status::InvalidArgument(
                        "target_samples is only read with parameters.target = uploaded",
                        "target_samples");
  }
  for (std::size_t i = 0; i < in.uploaded_target.size(); ++i) {
    if (!(in.uploaded_target[i] >= in.subject.min_angle_deg &&
          in.uploaded_target[i] <= in.subject.max_angle_deg)) {
      std::ostringstream why;
      why << "the target leaves the range of motion [" << in.subject.min_angle_deg << ", "
          << in.subject.max_angle_deg << "] deg at t = " << static_cast<double>(i) / 200.0 << " s ("
          << in.uploaded_target[i] << "°)";
      return api::Status::InvalidArgument(why.str(), "target_samples.angle_deg");
    }
  }
  TrackingSettings t;
  t.params = in.subject.parameter_set;
  if (t.params) {
    t.reachable_extension_deg = model::ReachableExtensionDeg(*t.params, v.at("max_ma"));
  }
  // The default target fits the leg: its extended end no further than the
  // set says the maximum holds the knee with a fifth of the muscle to spare
  // (kDefaultTargetActivationFraction). A lo_deg the client gave stays; the
  // gate below judges it for the controllers that invert the set.
  if (t.params && !upload && in.given != nullptr && !in.given->contains("lo_deg")) {
    const double fitted = std::ceil(
        model::ReachableExtensionDeg(*t.params, v.at("max_ma"), kDefaultTargetActivationFraction));
    const double lo =
        std::max(v.at("lo_deg"), std::min(fitted, v.at("hi_deg") - kMinFittedSpanDeg));
    if (lo > v.at("lo_deg")) {
      v["lo_deg"] = lo;
      b.plan().parameters["lo_deg"] = lo;  // the run records the target used
    }
  }
  t.target = TrackingTarget(v, in.uploaded_target, t.target_name);
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
    b.plan().parameters["max_rate_ma_per_s"] = t.max_rate_ma_per_s;
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
      if (in.subject.parameter_set_id) why << " #" << *in.subject.parameter_set_id;
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
      why << " (longer than max_saturation_s = " << t.max_saturation_s
          << " s); pid, which "
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
      if (in.subject.parameter_set_id) why << " #" << *in.subject.parameter_set_id;
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
  b.plan().tracking = std::make_shared<const TrackingSettings>(std::move(t));
  // The run records the set it inverts (0 resolved to the leg's approved set).
  if (in.subject.parameter_set_id) {
    b.plan().parameters["parameter_set_id"] = static_cast<double>(*in.subject.parameter_set_id);
  }
  return api::Status::Ok();
}

// The set it inverted (the one it names, else the leg's approved set when the run started) and
// its tracking figures.
api::RunOutcome Tracking::Conclude(const RunConclusionInput& in, const RunResult& r) const {
  api::RunOutcome o = ConcludeCommon(r);
  o.used_parameter_set_id = api::UsedParameterSetOf(in.parameters);
  if (!o.used_parameter_set_id) o.used_parameter_set_id = in.leg_parameter_set_id;
  o.tracking = api::TrackingOutcome{r.values};
  return o;
}

}  // namespace

std::unique_ptr<const Protocol> MakeTracking() { return std::make_unique<Tracking>(); }

}  // namespace fesbench::server::protocols::catalog
