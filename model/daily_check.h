#pragma once

/// @file
/// The model kept current over time (thesis §7.4.3: "… would need to be
/// re-identified … a rapid method … so that the model can be kept up to
/// date"; §7.6.4 on the spread of parameters from day to day; §7.6.5): a
/// short isometric ramp trial measured today is compared with the leg's
/// stored set on the four quantities that move between sessions —
/// recruitment threshold and slope (electrode placement, skin), the
/// isometric full-scale torque (fatigue, training) and the contraction pole
/// (muscle state) — against bounds learned from the leg's own history of
/// sets, and only what moved is re-fitted; a moved pole changes every
/// active fit, so then a full rapid run is due.

#include <optional>
#include <span>
#include <string>
#include <vector>

#include "model/identify_common.h"
#include "model/parameter_set.h"

namespace fesbench::model {

/// What a daily check compares.
struct LegSignature {
  double threshold_ma = 0.0;  ///< u at R = 0.1 (the rising part's start).
  double slope_per_ma = 0.0;  ///< 0.8 / (u(R = 0.9) − u(R = 0.1)).
  /// Isometric torque at full recruitment at the lock angle, N·m:
  /// τ_scale·f_ata(θ_lock)·f_atv(0) for a set, the ramp-correlation IRC's
  /// torque scale for a trial (§4.1.3).
  double full_scale_nm = 0.0;
  double pole_per_s = 0.0;  ///< contraction pole a (Eq. 3.21).
};

/// The signature of a stored set at the lock angle.
/// @throws std::invalid_argument for an invalid set.
LegSignature SignatureOfSet(const ParameterSet& set, double lock_angle_deg);

/// Today's signature from an isometric ramp trial with impulses (the rapid
/// routine's first trial): pole from the averaged impulses at the set's
/// contraction order (§4.1, Eqs. 4.2/4.4), IRC and full scale by ramp
/// correlation (§4.1.3, Eq. 4.5). `irc` receives the IRC.
/// @throws std::invalid_argument as IdentifyContraction / IdentifyIrc.
LegSignature SignatureOfTrial(const TrialColumns& ramp_trial, int order, PiecewiseLinear* irc);

/// The recruitment curve of a moved electrode: `irc` shifted by shift_ma
/// and stretched by `stretch` about its threshold_ma, so
/// R'(threshold + shift + (u − threshold)·stretch) = R(u). The stored
/// curve's shape, refined on the swings of its rapid run, is kept; only
/// where and how steeply it rises follow today's ramp.
PiecewiseLinear MovedRecruitment(const PiecewiseLinear& irc, double threshold_ma, double shift_ma,
                                 double stretch);

/// How today's isometric recruitment torque T₁(u) = g·T₀(u₀ + (u − u₀ −
/// shift)/stretch) follows an earlier one T₀ (u₀ the earlier threshold):
/// the electrode moved (shift), the recruitment steepened or flattened
/// (stretch) and the muscle got stronger or weaker (gain).
struct RecruitmentMove {
  double shift_ma = 0.0;
  double stretch = 1.0;
  double gain = 1.0;
  /// RMS of T₁ − g·T₀(…) over today's tested amplitudes, as a fraction of
  /// today's largest torque: what a move does not explain.
  double misfit = 0.0;
  /// The same with the stretch held at 1 (a pure shift and gain).
  double shift_only_ma = 0.0, shift_only_gain = 1.0, shift_only_misfit = 0.0;
};

/// Fits RecruitmentMove by least squares over today's tested amplitudes
/// (0 to the last breakpoint of `today`), torque against torque, so a ramp
/// that no longer reaches saturation (the electrode moved and the
/// amplitude is capped at the max tolerated) is compared where it was
/// measured instead of normalised to a lower peak. T(u) = scale·irc(u);
/// the earlier curve is used only where it was tested (below its last
/// breakpoint) or saturated. Grid search: shift ±8 mA by 0.025 mA,
/// stretch 0.6–1.6 by 0.02, the gain in closed form at each.
/// @throws std::invalid_argument if fewer than 10 amplitudes compare.
RecruitmentMove FitRecruitmentMove(const PiecewiseLinear& before, double before_scale_nm,
                                   double before_threshold_ma, const PiecewiseLinear& today,
                                   double today_scale_nm);

/// Floors of the drift bounds; each bound is max(floor, sigmas·SD of the
/// leg's history).
struct DriftFloors {
  double threshold_ma = 1.5;
  double slope_fraction = 0.2;
  double full_scale_fraction = 0.15;
  double pole_fraction = 0.25;
  /// Largest recruitment misfit (RecruitmentMove::misfit) a re-fit may
  /// leave; beyond it the curve changed shape and a rapid run is due
  /// (measured: 0.001–0.004 on moved electrodes, 0.04 for a plateau of
  /// 8 mA in the curve, tests/server/daily_check_test.cc).
  double recruitment_misfit = 0.025;
  double sigmas = 3.0;
};

struct Drift {
  std::string name;  ///< "irc_threshold_ma", "irc_slope", "full_scale", "pole".
  double stored = 0.0, today = 0.0;
  /// today − stored (threshold, mA) or today/stored − 1 (the others).
  double change = 0.0;
  double bound = 0.0;  ///< |change| above this: moved.
  bool moved = false;
};

enum class DailyVerdict { kNoChange, kRefit, kRapidDue };
/// "no_change", "refit", "rapid_due".
std::string_view DailyVerdictName(DailyVerdict verdict);

struct DailyCheck {
  std::vector<Drift> drifts;
  DailyVerdict verdict = DailyVerdict::kNoChange;
  std::vector<std::string> refitted;    ///< "irc", "torque_scale".
  std::optional<ParameterSet> updated;  ///< kRefit: the set with what moved re-fitted.
  double recruitment_misfit = 0.0;      ///< RecruitmentMove::misfit of the move used.
  std::string summary;                  ///< for people.
};

/// Compares today's ramp trial with `stored`: with the ramp trial `stored`
/// was identified from (`base_ramp`, when known) measurement against
/// measurement, else against the set's own signature (whose full scale,
/// from the free-swing fit, need not match an isometric measurement).
/// `history`: the leg's sets
/// (the stored one may be among them) whose spread sets the bounds (fewer
/// than three: the floors alone). Verdict: the pole moved → kRapidDue;
/// else threshold or slope moved → the IRC is today's; full scale moved →
/// τ_scale scaled by today/stored; nothing moved → kNoChange.
/// @throws std::invalid_argument as SignatureOfSet / SignatureOfTrial.
DailyCheck CompareDaily(const ParameterSet& stored, const TrialColumns& ramp_trial,
                        double lock_angle_deg, std::span<const ParameterSet> history,
                        const TrialColumns* base_ramp = nullptr, const DriftFloors& floors = {});

}  // namespace fesbench::model
