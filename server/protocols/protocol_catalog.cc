#include "server/protocols/protocol.h"

// The protocol catalog (DESIGN.md §5): every protocol the engine runs, its
// parameters with their units, defaults, limits and scaling, and the thesis
// section behind it.

namespace fesbench::server::protocols {
namespace {

// Parameters shared by several protocols (Appendix F: the clinician sets
// the maximum to the subject's tolerance and the minimum from threshold).
ParameterSpec ThresholdMa() {
  return {
      "threshold_ma",     "subject's stimulation threshold for torque, mA", 20.0, 0.0, 100.0, false,
      Scaling::kThreshold};
}
ParameterSpec MaxMa() {
  return {"max_ma",
          "maximum stimulation (the subject's max tolerated), mA",
          45.0,
          1.0,
          100.0,
          false,
          Scaling::kMaxTolerated};
}
ParameterSpec LockAngleDeg() {
  return {"lock_angle_deg", "knee angle the brace is locked at, deg", 90.0, 10.0, 110.0, false};
}
ParameterSpec SettleS(double default_s, const char* what) {
  return {"settle_s", what, default_s, 0.2, 30.0, false};
}
ParameterSpec AmplitudeMa(double fraction) {
  return {"amplitude_ma",
          "random-binary ON amplitude (the lowest level giving full extension, §5.4.3); "
          "default a fraction of threshold→max",
          fraction,
          0.0,
          100.0,
          false,
          Scaling::kStimRange};
}
ParameterSpec Rest(std::string name, std::string description, double default_s, double min_s,
                   double max_s) {
  ParameterSpec p{std::move(name), std::move(description), default_s, min_s, max_s, false};
  p.is_rest = true;
  return p;
}

std::vector<ProtocolDescription> MakeCatalog() {
  std::vector<ProtocolDescription> c;

  c.push_back(
      {"tolerance_test",
       1,
       "Stimulation tolerance test",
       "Knee locked at 90°; the amplitude rises slowly from start_ma at rate_ma_per_s "
       "until the clinician stops (or ceiling_ma). Records the threshold (first torque "
       "above the offset's noise band) and the max tolerated amplitude (where it was "
       "stopped). Appendix F part II.K, §5.2.1.",
       BenchMode::kLocked,
       ProtocolKind::kTolerance,
       0.0,
       {LockAngleDeg(),
        SettleS(1.5, "time to move to and lock the angle, s"),
        {"start_ma", "amplitude at the start of the ramp, mA", 0.0, 0.0, 100.0, false},
        {"rate_ma_per_s", "amplitude rise rate, mA/s", 0.5, 0.05, 5.0, false},
        {"ceiling_ma",
         "amplitude where the ramp ends if not stopped, mA: the session's max tolerated "
         "amplitude; 60 mA for a session without one. Above a recorded max only with an "
         "explicit, audited ceiling_reason",
         60.0, 1.0, 100.0, false, Scaling::kToleranceCeiling},
        {"threshold_torque_nm", "torque above the offset taken as a response, N·m", 0.5, 0.05, 10.0,
         false},
        {"min_torque_at_max_nm", "torque the subject must produce at max (warning), N·m", 6.0, 0.0,
         60.0, false}}});

  c.push_back({"isometric_ramp_irc",
               1,
               "Isometric ramp IRC",
               "Knee locked at 90°: a 3 s conditioning burst at 75 % of the range, 2 impulses at "
               "max, 2 cosine ramps (2 s up, 2 s down) from threshold − 5 mA to max, 1 s rest "
               "between, 200 Hz (§5.3.3, Fig. 5-7, Appendix F part II).",
               BenchMode::kLocked,
               ProtocolKind::kIsometric,
               1.0,
               {LockAngleDeg(),
                SettleS(1.5, "time to move to and lock the angle, s"),
                ThresholdMa(),
                MaxMa(),
                {"conditioning_s", "conditioning burst length, s", 3.0, 0.0, 10.0, false},
                {"conditioning_fraction", "conditioning level, fraction of threshold→max", 0.75,
                 0.0, 1.0, false},
                {"impulses", "number of impulses at max", 2.0, 0.0, 20.0, true},
                {"ramps", "number of cosine ramps", 2.0, 1.0, 10.0, true},
                {"below_threshold_ma", "ramp start below threshold, mA", 5.0, 0.0, 50.0, false},
                {"ramp_duration_s", "whole ramp (half up, half down), s", 4.0, 0.5, 30.0, false},
                Rest("rest_s", "zero stimulation after each element, s", 1.0, 1.0, 60.0)}});

  c.push_back({"isometric_step_irc",
               1,
               "Isometric step IRC",
               "Knee locked at 90°: 10 levels threshold→max, each a 3 s burst (0.5 s ramp, "
               "2.5 s hold) followed by 30 s rest; the mean of the last 0.5 s is the level's "
               "torque (§5.3.1, Appendix F part III).",
               BenchMode::kLocked,
               ProtocolKind::kIsometric,
               10.0,
               {LockAngleDeg(),
                SettleS(1.5, "time to move to and lock the angle, s"),
                ThresholdMa(),
                MaxMa(),
                {"levels", "number of amplitudes", 10.0, 2.0, 50.0, true},
                {"burst_s", "burst length incl. ramp, s", 3.0, 0.5, 20.0, false},
                {"ramp_s", "linear ramp at burst start, s", 0.5, 0.0, 10.0, false},
                Rest("rest_s", "relaxation after each burst, s", 30.0, 10.0, 300.0)}});

  c.push_back({"isometric_impulse_irc",
               1,
               "Isometric impulse IRC",
               "Knee locked at 90°: 30 single pulses from below threshold to max, 1 s apart; "
               "the peak torque after each is the level's response (§5.3.2).",
               BenchMode::kLocked,
               ProtocolKind::kIsometric,
               0.5,
               {LockAngleDeg(),
                SettleS(1.5, "time to move to and lock the angle, s"),
                ThresholdMa(),
                MaxMa(),
                {"count", "number of pulses", 30.0, 2.0, 200.0, true},
                {"below_threshold_ma", "first pulse below threshold, mA", 5.0, 0.0, 50.0, false},
                Rest("interval_s", "time between pulses, s", 1.0, 0.5, 10.0)}});

  c.push_back({"isometric_prediction",
               1,
               "Isometric torque prediction",
               "Knee locked at 90°: the 11 s plateau profile of Fig. 5-8 (levels at threshold "
               "+ 5 mA and 25/50/75/100 % of the range), 200 Hz (§5.3.4, Appendix F part IV).",
               BenchMode::kLocked,
               ProtocolKind::kIsometric,
               0.0,
               {LockAngleDeg(),
                SettleS(1.5, "time to move to and lock the angle, s"),
                ThresholdMa(),
                MaxMa(),
                {"above_threshold_ma", "lowest plateau above threshold, mA", 5.0, 0.0, 50.0, false},
                {"lead_s", "zero stimulation before the first ramp, s", 0.5, 0.0, 10.0, false},
                {"ramp_s", "linear ramp between plateaus, s", 0.25, 0.005, 5.0, false},
                {"hold_s", "plateau hold, s", 0.75, 0.0, 10.0, false},
                {"tail_s", "zero stimulation at the end, s", 1.25, 0.0, 10.0, false}}});

  c.push_back({"passive_sequential",
               1,
               "Sequential passive identification",
               "Motor: 20 positions from max_angle_deg to full extension and back, each held "
               "10 s (50-sample means); then 8 speeds × 2 directions of 2 s moves with 10 s "
               "pauses, the last 1 s used (§5.4.1).",
               BenchMode::kMotor,
               ProtocolKind::kPassive,
               2.0,
               {{"min_angle_deg", "full extension for the subject, deg", 30.0, 10.0, 110.0, false,
                 Scaling::kRangeMin},
                {"max_angle_deg", "first (largest flexion) angle, deg", 110.0, 10.0, 110.0, false,
                 Scaling::kRangeMax},
                {"reference_deg", "reference angle (offset torque), deg", 90.0, 10.0, 110.0, false},
                {"positions", "angles per pass", 20.0, 2.0, 100.0, true},
                {"hold_s", "hold at each angle, s", 10.0, 0.5, 120.0, false},
                {"move_s", "move between angles, s", 1.0, 0.1, 10.0, false},
                {"speeds", "number of speeds", 8.0, 1.0, 30.0, true},
                {"max_speed_deg_s", "fastest speed, deg/s", 30.0, 1.0, 200.0, false},
                Rest("pause_s", "pause before each constant-velocity move, s", 10.0, 2.0, 120.0),
                SettleS(2.0, "move to the reference angle before each part, s")}});

  c.push_back(
      {"passive_simultaneous",
       1,
       "Simultaneous passive identification",
       "Motor: two 10 s pseudo-random sum-of-six-sines trajectories scaled to the "
       "subject's range, set-points at 1 kHz, 200 Hz sampling; reference torque at 90° "
       "before each (§4.2.2, §5.4.2, Fig. 5-9).",
       BenchMode::kMotor,
       ProtocolKind::kPassive,
       0.0,
       {{"min_angle_deg", "lower angle of the trajectories, deg", 30.0, 10.0, 110.0, false,
         Scaling::kRangeMin},
        {"max_angle_deg", "upper angle of the trajectories, deg", 100.0, 10.0, 110.0, false,
         Scaling::kRangeMax},
        {"max_velocity_deg_s", "velocity limit, deg/s", 200.0, 10.0, 400.0, false},
        {"duration_s", "length of each trajectory, s", 10.0, 2.5, 60.0, false},
        {"trajectories", "number of trajectories", 2.0, 1.0, 10.0, true},
        {"seed", "seed of the first trajectory (then seed + 1, …)", 1.0, 0.0, 4294967295.0, true},
        SettleS(2.0, "each move to the reference or start angle, s")}});

  c.push_back({"free_swing_passive",
               1,
               "Free-swing passive identification",
               "Decoupled: a 10 s sparse random-binary train at the amplitude that just reaches "
               "full extension; position and acceleration at 200 Hz (§5.4.3, Fig. 5-10).",
               BenchMode::kDecoupled,
               ProtocolKind::kFreeSwing,
               0.0,
               {ThresholdMa(),
                MaxMa(),
                AmplitudeMa(0.6),
                {"duration_s", "train length, s", 10.0, 3.0, 120.0, false},
                {"seed", "random seed of the train", 1.0, 0.0, 4294967295.0, true},
                SettleS(2.0, "swing after decoupling before recording, s")}});

  c.push_back({"active_random_binary",
               1,
               "Active identification (RB1, RB2)",
               "Decoupled: two denser 10 s random-binary trains (RB1, RB2) with a rest between "
               "(§5.4.4, Fig. 5-11).",
               BenchMode::kDecoupled,
               ProtocolKind::kFreeSwing,
               2.0,
               {ThresholdMa(),
                MaxMa(),
                AmplitudeMa(0.6),
                {"duration_s", "length of each train, s", 10.0, 2.0, 120.0, false},
                {"rb1_seed", "seed of RB1", 1.0, 0.0, 4294967295.0, true},
                {"rb2_seed", "seed of RB2", 2.0, 0.0, 4294967295.0, true},
                Rest("rest_s", "rest between the trains, s", 10.0, 2.0, 300.0),
                SettleS(2.0, "swing after decoupling before recording, s")}});

  c.push_back({"prediction_step",
               1,
               "Knee angle prediction: step",
               "Decoupled: step at 75 % of the threshold→max range from 0.5 s for 3 s, then "
               "1.5 s without stimulation (§5.4.5, Fig. 5-12).",
               BenchMode::kDecoupled,
               ProtocolKind::kPrediction,
               0.0,
               {ThresholdMa(),
                MaxMa(),
                {"level_fraction", "level as fraction of threshold→max", 0.75, 0.0, 1.0, false},
                {"onset_s", "zero stimulation before the step, s", 0.5, 0.0, 10.0, false},
                {"on_s", "step length, s", 3.0, 0.1, 30.0, false},
                {"off_s", "zero stimulation after the step, s", 1.5, 0.0, 30.0, false},
                SettleS(2.0, "swing after decoupling before recording, s")}});

  c.push_back({"prediction_ramp",
               1,
               "Knee angle prediction: ramp",
               "Decoupled: amplitude 0→max in 5 s and back to 0 in 5 s (§5.4.5).",
               BenchMode::kDecoupled,
               ProtocolKind::kPrediction,
               0.0,
               {MaxMa(),
                {"up_s", "ramp-up time, s", 5.0, 0.1, 60.0, false},
                {"down_s", "ramp-down time, s", 5.0, 0.1, 60.0, false},
                SettleS(2.0, "swing after decoupling before recording, s")}});

  c.push_back({"prediction_sine",
               1,
               "Knee angle prediction: swept sine",
               "Decoupled: cosine cycles of period 5, 2 and 1 s between threshold + 5 mA and "
               "max, then 1 s without stimulation (§5.4.5).",
               BenchMode::kDecoupled,
               ProtocolKind::kPrediction,
               0.0,
               {ThresholdMa(),
                MaxMa(),
                {"above_threshold_ma", "lower level above threshold, mA", 5.0, 0.0, 50.0, false},
                {"tail_s", "zero stimulation at the end, s", 1.0, 0.0, 10.0, false},
                SettleS(2.0, "swing after decoupling before recording, s")}});

  c.push_back(
      {"prediction_random_binary",
       1,
       "Knee angle prediction: random binary",
       "Decoupled: a random-binary train like the active identification's (§5.4.5: "
       "\"the random binary stimulation patterns … were also used\").",
       BenchMode::kDecoupled,
       ProtocolKind::kPrediction,
       0.0,
       {ThresholdMa(),
        MaxMa(),
        AmplitudeMa(0.6),
        {"duration_s", "train length, s", 10.0, 2.0, 120.0, false},
        {"seed", "random seed of the train", 3.0, 0.0, 4294967295.0, true},
        {"dense", "1 = dense (active) train, 0 = sparse (passive) train", 1.0, 0.0, 1.0, true},
        SettleS(2.0, "swing after decoupling before recording, s")}});

  c.push_back(
      {"daily_check",
       1,
       "Daily check of the model",
       "A short check of today's leg against its stored parameter set: knee locked, 2 "
       "impulses and one 4 s cosine ramp (pole, IRC by ramp correlation, full-scale torque), "
       "then a 4 s random-binary free swing that validates the outcome. Threshold, slope, "
       "full-scale torque and pole are compared with bounds learned from the leg's own "
       "history of sets; only what moved is re-fitted (a new version of the set), a moved "
       "pole calls for a full rapid run (§7.4.3).",
       BenchMode::kMixed,
       ProtocolKind::kDailyCheck,
       1.0,
       {LockAngleDeg(),
        SettleS(0.8, "time to move to and lock the angle, s"),
        ThresholdMa(),
        MaxMa(),
        {"impulses", "number of impulses at max", 2.0, 1.0, 20.0, true},
        {"below_threshold_ma", "ramp start below threshold, mA", 5.0, 0.0, 50.0, false},
        {"ramp_duration_s", "whole ramp (half up, half down), s", 4.0, 0.5, 30.0, false},
        Rest("rest_s", "zero stimulation after each isometric element, s", 1.0, 1.0, 60.0),
        AmplitudeMa(0.6),
        {"swing_s", "random-binary free swing that validates the outcome, s", 4.0, 2.0, 30.0,
         false},
        {"seed", "random seed of the swing's train", 5.0, 0.0, 4294967295.0, true},
        {"swing_settle_s", "swing after decoupling before the train, s", 1.0, 0.2, 30.0,
         false}}});

  c.push_back(
      {"tracking",
       1,
       "Knee-angle tracking",
       "Decoupled: the stimulation follows a target knee angle (a 0.2 Hz sine between two "
       "angles, holds at angles, a ramp up and down, or an uploaded trajectory) with the leg's "
       "parameter set, after a "
       "lead-in from where the knee hangs to the target's start. Controllers: pid (a PID on "
       "the angle error above the threshold), inverse_model (the inverted model as "
       "feedforward with a PID around it) and adaptive (the same with τ_scale followed "
       "online). Amplitude within the max tolerated and slew-limited; a controller saturated "
       "at the maximum longer than max_saturation_s ends the run (§7.6.3).",
       BenchMode::kDecoupled,
       ProtocolKind::kTracking,
       0.0,
       {ThresholdMa(),
        MaxMa(),
        {"controller", "0 = pid, 1 = inverse_model, 2 = adaptive", 1.0, 0.0, 2.0, true,
         Scaling::kNone, false, {"pid", "inverse_model", "adaptive"}},
        {"target",
         "0 = sine, 1 = holds, 2 = ramp, 3 = uploaded (the request's target_samples: t_s, "
         "angle_deg)",
         0.0, 0.0, 3.0, true, Scaling::kNone, false, {"sine", "holds", "ramp", "uploaded"}},
        {"lo_deg", "lower target angle (extension side), deg", 30.0, 0.0, 180.0, false},
        {"hi_deg", "upper target angle (flexion side), deg", 80.0, 0.0, 180.0, false},
        {"frequency_hz", "sine frequency, Hz", 0.2, 0.01, 1.0, false},
        {"duration_s", "length of the target after the lead-in, s", 30.0, 2.0, 600.0, false},
        {"hold_s", "holds: time at each angle, s", 4.0, 0.5, 60.0, false},
        {"move_s", "holds: time to move between angles, s", 1.0, 0.2, 10.0, false},
        {"lead_in_s", "move from the hanging knee to the target's start, s", 3.0, 1.0, 10.0,
         false},
        {"kp_ma_per_deg",
         "pid: proportional gain on the amplitude, mA/deg (pid's three gains 0: tuned from the "
         "set)",
         0.0, 0.0, 20.0, false},
        {"ki_ma_per_deg_s", "pid: integral gain, mA/(deg·s)", 0.0, 0.0, 50.0, false},
        {"kd_ma_s_per_deg", "pid: derivative gain, mA·s/deg", 0.0, 0.0, 5.0, false},
        {"kp_nm_per_deg",
         "inverse_model, adaptive: proportional gain of the PID on the torque around the "
         "inverted model, N·m/deg (the three gains 0: tuned from the set)",
         0.0, 0.0, 20.0, false},
        {"ki_nm_per_deg_s", "inverse_model, adaptive: integral gain, N·m/(deg·s)", 0.0, 0.0, 50.0,
         false},
        {"kd_nm_s_per_deg", "inverse_model, adaptive: derivative gain, N·m·s/deg", 0.0, 0.0, 5.0,
         false},
        {"max_rate_ma_per_s", "fastest amplitude change, mA/s", 1000.0, 5.0, 5000.0, false},
        {"max_saturation_s", "the run ends if the controller asks for more than the maximum "
         "this long, s", 3.0, 0.2, 60.0, false},
        {"forgetting", "adaptive: forgetting factor of the τ_scale estimate (per 5 ms sample)",
         0.999, 0.9, 1.0, false},
        {"parameter_set_id", "the leg's parameter set to invert (0: its newest)", 0.0, 0.0,
         9007199254740992.0, true},
        SettleS(2.0, "swing after decoupling before the lead-in, s")}});

  c.push_back(
      {"rapid_parameterisation",
       2,
       "Rapid parameterisation",
       "The < 30 s routine of §7.4.1 over the whole range of motion: a 7 s isometric ramp "
       "IRC trial (2 impulses, one 4 s cosine ramp) → contraction pole and IRC by ramp "
       "correlation; the motor takes the knee near full flexion and near full extension "
       "and releases it twice (free swings through the range, §4.2.3; the held torque and "
       "the first 0.16 s of each swing measure J); a ≤ 3 s ascending "
       "amplitude search on the decoupled leg that stops at full extension (§5.4.3); a 10 s "
       "dense random-binary free-swing trial at the amplitude found → τ_pta and τ_ptv with "
       "known inertia from the passive samples of every swing → the active curves "
       "(Eq. 4.40); ends with a complete parameter set (§7.4.1).",
       BenchMode::kMixed,
       ProtocolKind::kRapid,
       1.0,
       {LockAngleDeg(),
        SettleS(0.8, "time to move to and lock the angle, s"),
        ThresholdMa(),
        MaxMa(),
        {"conditioning_s", "conditioning burst length, s", 0.0, 0.0, 10.0, false},
        {"impulses", "number of impulses at max", 2.0, 1.0, 20.0, true},
        {"ramps", "number of cosine ramps", 1.0, 1.0, 10.0, true},
        {"below_threshold_ma", "ramp start below threshold, mA", 5.0, 0.0, 50.0, false},
        {"ramp_duration_s", "whole ramp (half up, half down), s", 4.0, 0.5, 30.0, false},
        Rest("rest_s", "zero stimulation after each isometric element, s", 1.0, 1.0, 60.0),
        {"release_margin_fraction",
         "the knee is released this fraction of the range of motion inside each end of it", 0.05,
         0.02, 0.3, false},
        {"release_move_s", "motor move to each release angle, s", 0.8, 0.5, 10.0, false},
        {"release_hold_s",
         "hold at the release angle before releasing (recorded: its torque measures J), s", 0.2,
         0.05, 5.0, false},
        {"release_swing_s", "free swing recorded after each release, s", 1.8, 1.0, 20.0, false},
        {"swing_settle_s", "swing after the last release before the extension search, s", 0.3, 0.0,
         30.0, false},
        {"search_s",
         "the extension search raises the amplitude from threshold to max in this time, s", 3.0,
         1.0, 20.0, false},
        {"fall_s", "free swing recorded after the extension search, s", 0.6, 0.0, 10.0, false},
        AmplitudeMa(0.6),
        {"rb_torque_nm",
         "0 (default): the random-binary amplitude is the one that just reaches full extension "
         "(§5.4.3), found during the run by the extension search, within the max "
         "tolerated; > 0: the amplitude giving this isometric torque at the lock angle; "
         "amplitude_ma is used if neither can be found, N·m",
         0.0, 0.0, 60.0, false},
        {"extension_target_fraction",
         "full extension for that amplitude: this fraction of the range of motion inside its "
         "extension end",
         0.1, 0.0, 0.45, false},
        {"rb_level_min_fraction",
         "each ON burst of the random-binary train takes a seeded level between threshold + this "
         "fraction of threshold→amplitude and the amplitude (1 = one level)",
         0.5, 0.1, 1.0, false},
        {"rb_min_top_fraction",
         "the random-binary train's top level is at least threshold + this fraction of "
         "threshold→max (the prediction inputs' levels), even above full extension",
         0.75, 0.0, 1.0, false},
        {"duration_s", "length of the random-binary trial, s", 10.0, 3.0, 60.0, false},
        {"active_seed", "seed of the dense random-binary train and its levels", 2.0, 0.0,
         4294967295.0, true},
        {"inertia_kgm2",
         "limb inertia about the knee if known, kg·m²; 0 = from a prior parameter set or the "
         "subject's weight and shank length (Eq. 4.13)",
         0.0, 0.0, 5.0, false}}});
  return c;
}

}  // namespace

const std::vector<ProtocolDescription>& ProtocolCatalog() {
  static const std::vector<ProtocolDescription> catalog = MakeCatalog();
  return catalog;
}

}  // namespace fesbench::server::protocols
