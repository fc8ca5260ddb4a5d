#include "server/protocols/protocol.h"

// The protocol catalog (docs/PROTOCOLS.md): every protocol the engine runs, its
// parameters with their units, defaults, limits and scaling, and the thesis
// section behind it.

namespace fesbench::server::protocols {
namespace {

// A parameter's default and inclusive limits, in its unit.
struct Range {
  double value = 0.0;
  double min = 0.0;
  double max = 0.0;
};

// A real-valued parameter (its default as `scaling` says).
ParameterSpec Number(std::string name, std::string description, Range range,
                     Scaling scaling = Scaling::kNone) {
  return {.name = std::move(name),
          .description = std::move(description),
          .default_value = range.value,
          .min_value = range.min,
          .max_value = range.max,
          .scaling = scaling};
}
// A whole number (counts, seeds).
ParameterSpec Count(std::string name, std::string description, Range range) {
  ParameterSpec p = Number(std::move(name), std::move(description), range);
  p.integer = true;
  return p;
}
// A choice among names: the index of the default name, 0 … n − 1.
ParameterSpec Choice(std::string name, std::string description, int default_index,
                     std::vector<std::string> choices) {
  ParameterSpec p = Count(std::move(name), std::move(description),
                          {.value = static_cast<double>(default_index),
                           .min = 0.0,
                           .max = static_cast<double>(choices.size()) - 1.0});
  p.choices = std::move(choices);
  return p;
}
// A rest period (never shorter than the protocol's min_rest_s).
ParameterSpec Rest(std::string name, std::string description, Range range) {
  ParameterSpec p = Number(std::move(name), std::move(description), range);
  p.is_rest = true;
  return p;
}

// Parameters shared by several protocols (Appendix F: the clinician sets
// the maximum to the subject's tolerance and the minimum from threshold).
ParameterSpec ThresholdMa() {
  return Number("threshold_ma", "subject's stimulation threshold for torque, mA",
                {.value = 20.0, .min = 0.0, .max = 100.0}, Scaling::kThreshold);
}
ParameterSpec MaxMa() {
  return Number("max_ma", "maximum stimulation (the subject's max tolerated), mA",
                {.value = 45.0, .min = 1.0, .max = 100.0}, Scaling::kMaxTolerated);
}
ParameterSpec LockAngleDeg() {
  return Number("lock_angle_deg", "knee angle the brace is locked at, deg",
                {.value = 90.0, .min = 10.0, .max = 110.0});
}
ParameterSpec SettleS(double default_s, const char* what) {
  return Number("settle_s", what, {.value = default_s, .min = 0.2, .max = 30.0});
}
ParameterSpec AmplitudeMa(double fraction) {
  return Number("amplitude_ma",
                "random-binary ON amplitude (the lowest level giving full extension, §5.4.3); "
                "default a fraction of threshold→max",
                {.value = fraction, .min = 0.0, .max = 100.0}, Scaling::kStimRange);
}

std::vector<ProtocolDescription> MakeCatalog() {
  std::vector<ProtocolDescription> c;

  c.push_back(
      {.name = "tolerance_test",
       .version = 2,
       .title = "Stimulation tolerance test",
       .description =
           "Knee locked at 90°; the amplitude rises slowly from start_ma at rate_ma_per_s "
           "until the clinician stops, the subject signals the limit (a hand-held switch; the "
           "simulated subject does at its own max tolerated amplitude) or ceiling_ma. Records "
           "the threshold (first torque above the offset's noise band) and the max tolerated "
           "amplitude (where it was stopped). Appendix F part II.K, §5.2.1.",
       .bench_mode = BenchMode::kLocked,
       .kind = ProtocolKind::kTolerance,
       .min_rest_s = 0.0,
       .parameters = {
           LockAngleDeg(), SettleS(1.5, "time to move to and lock the angle, s"),
           Number("start_ma", "amplitude at the start of the ramp, mA",
                  {.value = 0.0, .min = 0.0, .max = 100.0}),
           Number("rate_ma_per_s", "amplitude rise rate, mA/s",
                  {.value = 0.5, .min = 0.05, .max = 5.0}),
           Number("ceiling_ma",
                  "amplitude where the ramp ends if not stopped, mA: the session's max tolerated "
                  "amplitude; 60 mA for a session without one. Above a recorded max only with an "
                  "explicit, audited ceiling_reason",
                  {.value = 60.0, .min = 1.0, .max = 100.0}, Scaling::kToleranceCeiling),
           Number("threshold_torque_nm", "torque above the offset taken as a response, N·m",
                  {.value = 0.5, .min = 0.05, .max = 10.0}),
           Number("min_torque_at_max_nm", "torque the subject must produce at max (warning), N·m",
                  {.value = 6.0, .min = 0.0, .max = 60.0})}});

  c.push_back(
      {.name = "isometric_ramp_irc",
       .version = 1,
       .title = "Isometric ramp IRC",
       .description =
           "Knee locked at 90°: a 3 s conditioning burst at 75 % of the range, 2 impulses at "
           "max, 2 cosine ramps (2 s up, 2 s down) from threshold − 5 mA to max, 1 s rest "
           "between, 200 Hz (§5.3.3, Fig. 5-7, Appendix F part II).",
       .bench_mode = BenchMode::kLocked,
       .kind = ProtocolKind::kIsometric,
       .min_rest_s = 1.0,
       .parameters = {
           LockAngleDeg(), SettleS(1.5, "time to move to and lock the angle, s"), ThresholdMa(),
           MaxMa(),
           Number("conditioning_s", "conditioning burst length, s",
                  {.value = 3.0, .min = 0.0, .max = 10.0}),
           Number("conditioning_fraction", "conditioning level, fraction of threshold→max",
                  {.value = 0.75, .min = 0.0, .max = 1.0}),
           Count("impulses", "number of impulses at max", {.value = 2.0, .min = 0.0, .max = 20.0}),
           Count("ramps", "number of cosine ramps", {.value = 2.0, .min = 1.0, .max = 10.0}),
           Number("below_threshold_ma", "ramp start below threshold, mA",
                  {.value = 5.0, .min = 0.0, .max = 50.0}),
           Number("ramp_duration_s", "whole ramp (half up, half down), s",
                  {.value = 4.0, .min = 0.5, .max = 30.0}),
           Rest("rest_s", "zero stimulation after each element, s",
                {.value = 1.0, .min = 1.0, .max = 60.0})}});

  c.push_back(
      {.name = "isometric_step_irc",
       .version = 1,
       .title = "Isometric step IRC",
       .description =
           "Knee locked at 90°: 10 levels threshold→max, each a 3 s burst (0.5 s ramp, "
           "2.5 s hold) followed by 30 s rest; the mean of the last 0.5 s is the level's "
           "torque (§5.3.1, Appendix F part III).",
       .bench_mode = BenchMode::kLocked,
       .kind = ProtocolKind::kIsometric,
       .min_rest_s = 10.0,
       .parameters = {
           LockAngleDeg(), SettleS(1.5, "time to move to and lock the angle, s"), ThresholdMa(),
           MaxMa(),
           Count("levels", "number of amplitudes", {.value = 10.0, .min = 2.0, .max = 50.0}),
           Number("burst_s", "burst length incl. ramp, s", {.value = 3.0, .min = 0.5, .max = 20.0}),
           Number("ramp_s", "linear ramp at burst start, s",
                  {.value = 0.5, .min = 0.0, .max = 10.0}),
           Rest("rest_s", "relaxation after each burst, s",
                {.value = 30.0, .min = 10.0, .max = 300.0})}});

  c.push_back(
      {.name = "isometric_impulse_irc",
       .version = 1,
       .title = "Isometric impulse IRC",
       .description =
           "Knee locked at 90°: 30 single pulses from below threshold to max, 1 s apart; "
           "the peak torque after each is the level's response (§5.3.2).",
       .bench_mode = BenchMode::kLocked,
       .kind = ProtocolKind::kIsometric,
       .min_rest_s = 0.5,
       .parameters = {
           LockAngleDeg(), SettleS(1.5, "time to move to and lock the angle, s"), ThresholdMa(),
           MaxMa(), Count("count", "number of pulses", {.value = 30.0, .min = 2.0, .max = 200.0}),
           Number("below_threshold_ma", "first pulse below threshold, mA",
                  {.value = 5.0, .min = 0.0, .max = 50.0}),
           Rest("interval_s", "time between pulses, s", {.value = 1.0, .min = 0.5, .max = 10.0})}});

  c.push_back(
      {.name = "isometric_prediction",
       .version = 1,
       .title = "Isometric torque prediction",
       .description =
           "Knee locked at 90°: the 11 s plateau profile of Fig. 5-8 (levels at threshold "
           "+ 5 mA and 25/50/75/100 % of the range), 200 Hz (§5.3.4, Appendix F part IV).",
       .bench_mode = BenchMode::kLocked,
       .kind = ProtocolKind::kIsometric,
       .min_rest_s = 0.0,
       .parameters = {LockAngleDeg(), SettleS(1.5, "time to move to and lock the angle, s"),
                      ThresholdMa(), MaxMa(),
                      Number("above_threshold_ma", "lowest plateau above threshold, mA",
                             {.value = 5.0, .min = 0.0, .max = 50.0}),
                      Number("lead_s", "zero stimulation before the first ramp, s",
                             {.value = 0.5, .min = 0.0, .max = 10.0}),
                      Number("ramp_s", "linear ramp between plateaus, s",
                             {.value = 0.25, .min = 0.005, .max = 5.0}),
                      Number("hold_s", "plateau hold, s", {.value = 0.75, .min = 0.0, .max = 10.0}),
                      Number("tail_s", "zero stimulation at the end, s",
                             {.value = 1.25, .min = 0.0, .max = 10.0})}});

  c.push_back(
      {.name = "passive_sequential",
       .version = 1,
       .title = "Sequential passive identification",
       .description =
           "Motor: 20 positions from max_angle_deg to full extension and back, each held "
           "10 s (50-sample means); then 8 speeds × 2 directions of 2 s moves with 10 s "
           "pauses, the last 1 s used (§5.4.1).",
       .bench_mode = BenchMode::kMotor,
       .kind = ProtocolKind::kPassive,
       .min_rest_s = 2.0,
       .parameters = {
           Number("min_angle_deg", "full extension for the subject, deg",
                  {.value = 30.0, .min = 10.0, .max = 110.0}, Scaling::kRangeMin),
           Number("max_angle_deg", "first (largest flexion) angle, deg",
                  {.value = 110.0, .min = 10.0, .max = 110.0}, Scaling::kRangeMax),
           Number("reference_deg", "reference angle (offset torque), deg",
                  {.value = 90.0, .min = 10.0, .max = 110.0}),
           Count("positions", "angles per pass", {.value = 20.0, .min = 2.0, .max = 100.0}),
           Number("hold_s", "hold at each angle, s", {.value = 10.0, .min = 0.5, .max = 120.0}),
           Number("move_s", "move between angles, s", {.value = 1.0, .min = 0.1, .max = 10.0}),
           Count("speeds", "number of speeds", {.value = 8.0, .min = 1.0, .max = 30.0}),
           Number("max_speed_deg_s", "fastest speed, deg/s",
                  {.value = 30.0, .min = 1.0, .max = 200.0}),
           Rest("pause_s", "pause before each constant-velocity move, s",
                {.value = 10.0, .min = 2.0, .max = 120.0}),
           SettleS(2.0, "move to the reference angle before each part, s")}});

  c.push_back(
      {.name = "passive_simultaneous",
       .version = 1,
       .title = "Simultaneous passive identification",
       .description =
           "Motor: two 10 s pseudo-random sum-of-six-sines trajectories scaled to the "
           "subject's range, set-points at 1 kHz, 200 Hz sampling; reference torque at 90° "
           "before each (§4.2.2, §5.4.2, Fig. 5-9).",
       .bench_mode = BenchMode::kMotor,
       .kind = ProtocolKind::kPassive,
       .min_rest_s = 0.0,
       .parameters = {
           Number("min_angle_deg", "lower angle of the trajectories, deg",
                  {.value = 30.0, .min = 10.0, .max = 110.0}, Scaling::kRangeMin),
           Number("max_angle_deg", "upper angle of the trajectories, deg",
                  {.value = 100.0, .min = 10.0, .max = 110.0}, Scaling::kRangeMax),
           Number("max_velocity_deg_s", "velocity limit, deg/s",
                  {.value = 200.0, .min = 10.0, .max = 400.0}),
           Number("duration_s", "length of each trajectory, s",
                  {.value = 10.0, .min = 2.5, .max = 60.0}),
           Count("trajectories", "number of trajectories", {.value = 2.0, .min = 1.0, .max = 10.0}),
           Count("seed", "seed of the first trajectory (then seed + 1, …)",
                 {.value = 1.0, .min = 0.0, .max = 4294967295.0}),
           SettleS(2.0, "each move to the reference or start angle, s")}});

  c.push_back(
      {.name = "free_swing_passive",
       .version = 1,
       .title = "Free-swing passive identification",
       .description =
           "Decoupled: a 10 s sparse random-binary train at the amplitude that just reaches "
           "full extension; position and acceleration at 200 Hz (§5.4.3, Fig. 5-10).",
       .bench_mode = BenchMode::kDecoupled,
       .kind = ProtocolKind::kFreeSwing,
       .min_rest_s = 0.0,
       .parameters = {
           ThresholdMa(), MaxMa(), AmplitudeMa(0.6),
           Number("duration_s", "train length, s", {.value = 10.0, .min = 3.0, .max = 120.0}),
           Count("seed", "random seed of the train",
                 {.value = 1.0, .min = 0.0, .max = 4294967295.0}),
           SettleS(2.0, "swing after decoupling before recording, s")}});

  c.push_back(
      {.name = "pendulum_test",
       .version = 1,
       .title = "Pendulum test",
       .description =
           "Motor, then free: the relaxed knee is taken to release_angle_deg, held "
           "release_hold_s and let go; it swings to rest without stimulation for "
           "release_swing_s; release_count times: the Wartenberg pendulum test, beyond the "
           "thesis (τ_pta and τ_ptv by method passive, Eq. 4.35 with J given or from the "
           "anthropometrics, §4.2.3).",
       .bench_mode = BenchMode::kMixed,
       .kind = ProtocolKind::kPassive,
       .min_rest_s = 0.0,
       .parameters = {
           Number("release_angle_deg", "knee angle the shank is let go at, deg",
                  {.value = 10.0, .min = 10.0, .max = 110.0}, Scaling::kRangeMin),
           Number("release_hold_s", "hold before each release, s",
                  {.value = 1.0, .min = 0.2, .max = 10.0}),
           Number("release_swing_s", "free swing recorded after each release, s",
                  {.value = 8.0, .min = 2.0, .max = 60.0}),
           Count("release_count", "number of releases", {.value = 2.0, .min = 1.0, .max = 10.0}),
           SettleS(2.0, "move to the release angle, s")}});

  c.push_back(
      {.name = "active_random_binary",
       .version = 1,
       .title = "Active identification (RB1, RB2)",
       .description =
           "Decoupled: two denser 10 s random-binary trains (RB1, RB2) with a rest between "
           "(§5.4.4, Fig. 5-11).",
       .bench_mode = BenchMode::kDecoupled,
       .kind = ProtocolKind::kFreeSwing,
       .min_rest_s = 2.0,
       .parameters = {
           ThresholdMa(), MaxMa(), AmplitudeMa(0.6),
           Number("duration_s", "length of each train, s",
                  {.value = 10.0, .min = 2.0, .max = 120.0}),
           Count("rb1_seed", "seed of RB1", {.value = 1.0, .min = 0.0, .max = 4294967295.0}),
           Count("rb2_seed", "seed of RB2", {.value = 2.0, .min = 0.0, .max = 4294967295.0}),
           Rest("rest_s", "rest between the trains, s", {.value = 10.0, .min = 2.0, .max = 300.0}),
           SettleS(2.0, "swing after decoupling before recording, s")}});

  c.push_back(
      {.name = "prediction_step",
       .version = 1,
       .title = "Knee angle prediction: step",
       .description = "Decoupled: step at 75 % of the threshold→max range from 0.5 s for 3 s, then "
                      "1.5 s without stimulation (§5.4.5, Fig. 5-12).",
       .bench_mode = BenchMode::kDecoupled,
       .kind = ProtocolKind::kPrediction,
       .min_rest_s = 0.0,
       .parameters = {ThresholdMa(), MaxMa(),
                      Number("level_fraction", "level as fraction of threshold→max",
                             {.value = 0.75, .min = 0.0, .max = 1.0}),
                      Number("onset_s", "zero stimulation before the step, s",
                             {.value = 0.5, .min = 0.0, .max = 10.0}),
                      Number("on_s", "step length, s", {.value = 3.0, .min = 0.1, .max = 30.0}),
                      Number("off_s", "zero stimulation after the step, s",
                             {.value = 1.5, .min = 0.0, .max = 30.0}),
                      SettleS(2.0, "swing after decoupling before recording, s")}});

  c.push_back(
      {.name = "prediction_ramp",
       .version = 1,
       .title = "Knee angle prediction: ramp",
       .description = "Decoupled: amplitude 0→max in 5 s and back to 0 in 5 s (§5.4.5).",
       .bench_mode = BenchMode::kDecoupled,
       .kind = ProtocolKind::kPrediction,
       .min_rest_s = 0.0,
       .parameters = {
           MaxMa(), Number("up_s", "ramp-up time, s", {.value = 5.0, .min = 0.1, .max = 60.0}),
           Number("down_s", "ramp-down time, s", {.value = 5.0, .min = 0.1, .max = 60.0}),
           SettleS(2.0, "swing after decoupling before recording, s")}});

  c.push_back({.name = "prediction_sine",
               .version = 1,
               .title = "Knee angle prediction: swept sine",
               .description =
                   "Decoupled: cosine cycles of period 5, 2 and 1 s between threshold + 5 mA and "
                   "max, then 1 s without stimulation (§5.4.5).",
               .bench_mode = BenchMode::kDecoupled,
               .kind = ProtocolKind::kPrediction,
               .min_rest_s = 0.0,
               .parameters = {ThresholdMa(), MaxMa(),
                              Number("above_threshold_ma", "lower level above threshold, mA",
                                     {.value = 5.0, .min = 0.0, .max = 50.0}),
                              Number("tail_s", "zero stimulation at the end, s",
                                     {.value = 1.0, .min = 0.0, .max = 10.0}),
                              SettleS(2.0, "swing after decoupling before recording, s")}});

  c.push_back(
      {.name = "prediction_random_binary",
       .version = 1,
       .title = "Knee angle prediction: random binary",
       .description = "Decoupled: a random-binary train like the active identification's (§5.4.5: "
                      "\"the random binary stimulation patterns … were also used\").",
       .bench_mode = BenchMode::kDecoupled,
       .kind = ProtocolKind::kPrediction,
       .min_rest_s = 0.0,
       .parameters = {
           ThresholdMa(), MaxMa(), AmplitudeMa(0.6),
           Number("duration_s", "train length, s", {.value = 10.0, .min = 2.0, .max = 120.0}),
           Count("seed", "random seed of the train",
                 {.value = 3.0, .min = 0.0, .max = 4294967295.0}),
           Count("dense", "1 = dense (active) train, 0 = sparse (passive) train",
                 {.value = 1.0, .min = 0.0, .max = 1.0}),
           SettleS(2.0, "swing after decoupling before recording, s")}});

  c.push_back(
      {.name = "daily_check",
       .version = 1,
       .title = "Daily check of the model",
       .description =
           "A short check of today's leg against its stored parameter set: knee locked, 2 "
           "impulses and one 4 s cosine ramp (pole, IRC by ramp correlation, full-scale torque), "
           "then a 4 s random-binary free swing that validates the outcome. Threshold, slope, "
           "full-scale torque and pole are compared with bounds learned from the leg's own "
           "history of sets; only what moved is re-fitted (a new version of the set), a moved "
           "pole calls for a full rapid run (§7.4.3).",
       .bench_mode = BenchMode::kMixed,
       .kind = ProtocolKind::kDailyCheck,
       .min_rest_s = 1.0,
       .parameters = {
           LockAngleDeg(), SettleS(0.8, "time to move to and lock the angle, s"), ThresholdMa(),
           MaxMa(),
           Count("impulses", "number of impulses at max", {.value = 2.0, .min = 1.0, .max = 20.0}),
           Number("below_threshold_ma", "ramp start below threshold, mA",
                  {.value = 5.0, .min = 0.0, .max = 50.0}),
           Number("ramp_duration_s", "whole ramp (half up, half down), s",
                  {.value = 4.0, .min = 0.5, .max = 30.0}),
           Rest("rest_s", "zero stimulation after each isometric element, s",
                {.value = 1.0, .min = 1.0, .max = 60.0}),
           AmplitudeMa(0.6),
           Number("swing_s", "random-binary free swing that validates the outcome, s",
                  {.value = 4.0, .min = 2.0, .max = 30.0}),
           Count("seed", "random seed of the swing's train",
                 {.value = 5.0, .min = 0.0, .max = 4294967295.0}),
           Number("swing_settle_s", "swing after decoupling before the train, s",
                  {.value = 1.0, .min = 0.2, .max = 30.0})}});

  c.push_back(
      {.name = "tracking",
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
       .parameters = {
           ThresholdMa(),
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
           Number("duration_s", "length of the target after the lead-in, s",
                  {.value = 30.0, .min = 2.0, .max = 600.0}),
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
           SettleS(2.0, "swing after decoupling before the lead-in, s")}});

  c.push_back(
      {.name = "rapid_parameterisation",
       .version = 2,
       .title = "Rapid parameterisation",
       .description =
           "The < 30 s routine of §7.4.1 over the whole range of motion: a 7 s isometric ramp "
           "IRC trial (2 impulses, one 4 s cosine ramp) → contraction pole and IRC by ramp "
           "correlation; the motor takes the knee near full flexion and near full extension "
           "and releases it twice (free swings through the range, §4.2.3; the held torque and "
           "the start of each swing, until the knee has travelled 15°, measure J); a ≤ 3 s ascending "
           "amplitude search on the decoupled leg that stops at full extension (§5.4.3); a 10 s "
           "dense random-binary free-swing trial at the amplitude found → τ_pta and τ_ptv with "
           "known inertia from the passive samples of every swing → the active curves "
           "(Eq. 4.40); ends with a complete parameter set (§7.4.1).",
       .bench_mode = BenchMode::kMixed,
       .kind = ProtocolKind::kRapid,
       .min_rest_s = 1.0,
       .parameters = {
           LockAngleDeg(),
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
           Number("duration_s", "length of the random-binary trial, s",
                  {.value = 10.0, .min = 3.0, .max = 60.0}),
           Count("active_seed", "seed of the dense random-binary train and its levels",
                 {.value = 2.0, .min = 0.0, .max = 4294967295.0}),
           Number(
               "inertia_kgm2",
               "limb inertia about the knee if known, kg·m²; 0 = from a prior parameter set or the "
               "subject's weight and shank length (Eq. 4.13)",
               {.value = 0.0, .min = 0.0, .max = 5.0})}});
  return c;
}

}  // namespace

const std::vector<ProtocolDescription>& ProtocolCatalog() {
  static const std::vector<ProtocolDescription> catalog = MakeCatalog();
  return catalog;
}

}  // namespace fesbench::server::protocols
