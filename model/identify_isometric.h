#pragma once

/// @file
/// Isometric identification (thesis §4.1, §5.3, §6.1–6.4): contraction
/// dynamics from averaged impulse responses (Eqs. 4.1–4.4 and a
/// least-squares fit of the pole to the whole twitch) and the isometric
/// recruitment curve by the step, impulse, ramp-correlation and two
/// ramp-deconvolution methods. The trial is recorded with the knee locked;
/// its torque column is the brace torque (any constant offset is removed
/// per event from the samples just before it).

#include <array>
#include <cstddef>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

#include "model/identify_common.h"
#include "model/parameter_set.h"
#include "model/piecewise_linear.h"

namespace fesbench::model {

/// A run of non-zero stimulation samples [begin, end).
struct StimulusRun {
  std::size_t begin = 0;
  std::size_t end = 0;
  std::size_t size() const { return end - begin; }
};

/// The runs of non-zero samples of a stimulation envelope, in order.
std::vector<StimulusRun> FindStimulusRuns(std::span<const double> stim_ma);

/// Options shared by the event-based isometric methods.
struct TwitchOptions {
  std::size_t max_impulse_samples = 8;  ///< runs this short are single pulses
                                        ///< (a held pulse lasts 1/33 s ≈ 7 samples).
  double window_s = 0.9;                ///< twitch window after the pulse, s.
  std::size_t baseline_samples = 10;    ///< pre-event samples averaged as offset.
};

/// The average of the impulse responses of a trial (§4.1, §5.3.3), time 0
/// at the pulse, baseline removed. Every twitch is cut to the shortest
/// window (window_s or up to the next stimulation, whichever is first).
struct TwitchAverage {
  std::vector<double> t_s;
  std::vector<double> torque_nm;
  int count = 0;         ///< impulses averaged.
  double stim_ma = 0.0;  ///< mean pulse amplitude.
};

/// Averages the single-pulse responses of the trials.
/// @throws std::invalid_argument if a trial lacks t_s/stim_ma/torque_nm
///   columns of equal length, or no impulse with at least 5 samples of
///   window is found.
TwitchAverage AverageImpulseResponses(std::span<const TrialColumns> trials,
                                      const TwitchOptions& options = {});

/// Time of the maximum of y(t), refined by a parabola through the three
/// samples around the largest one, s.
/// @throws std::invalid_argument if fewer than 3 samples or sizes differ.
double PeakTime(std::span<const double> t_s, std::span<const double> y);

/// Pole from the twitch peak: a = (n − 1)/t_peak (Eq. 4.2 for n = 2,
/// Eq. 4.4 for n = 3).
/// @throws std::invalid_argument if order is not 2 or 3 or t_peak <= 0.
double PoleFromPeak(int order, double t_peak_s);

/// A twitch model K·t^(n−1)·e^(−a·t) fitted to a measured twitch.
struct TwitchFit {
  int order = 3;
  double pole_per_s = 0.0;
  double gain = 0.0;    ///< K, N·m·s^(1−n).
  double rms_nm = 0.0;  ///< Eq. 6.4 between fit and data.
};

/// Best gain K for a fixed pole (linear least squares) and its RMS error.
TwitchFit FitTwitchGain(std::span<const double> t_s, std::span<const double> torque_nm, int order,
                        double pole_per_s);

/// Least-squares fit of the pole (and gain) to the whole twitch: the RMS
/// of Eq. 6.4 minimised over a (gain eliminated), searched over
/// [initial/4, 4·initial] in log a.
/// @throws std::invalid_argument on order ∉ {2, 3}, initial <= 0, or sizes.
TwitchFit FitTwitchPole(std::span<const double> t_s, std::span<const double> torque_nm, int order,
                        double initial_pole_per_s);

/// Which pole estimate IdentifyContraction returns.
enum class PoleMethod { kPeak, kLeastSquares };
/// Every pole method, in declaration order.
inline constexpr std::array<PoleMethod, 2> kPoleMethods = {PoleMethod::kPeak,
                                                           PoleMethod::kLeastSquares};

/// "peak" or "least_squares".
std::string_view PoleMethodName(PoleMethod method);
/// The method called `name` (PoleMethodName's words), or nullopt.
std::optional<PoleMethod> PoleMethodFromName(std::string_view name);

/// Options of IdentifyContraction.
struct ContractionOptions {
  TwitchOptions twitch;
  int order = 3;  ///< 2 or 3, or 0 for the order with the lower LS RMS.
  PoleMethod method = PoleMethod::kPeak;
};

/// Contraction dynamics from the averaged impulse responses (§4.1, §6.2):
/// both orders by peak time and by least squares, each with its RMS fit
/// error in fit_rms ("twitch_order2_peak", "twitch_order3_peak",
/// "twitch_order2_ls", "twitch_order3_ls"), the peak time in values.
struct ContractionResult {
  ContractionParams contraction;  ///< the chosen order and method.
  TwitchFit order2_peak, order3_peak, order2_ls, order3_ls;
  double peak_time_s = 0.0;
  TwitchAverage twitch;
  IdentifyReport report;
};

/// @throws std::invalid_argument as AverageImpulseResponses, or on an order
///   other than 0, 2 or 3.
ContractionResult IdentifyContraction(std::span<const TrialColumns> trials,
                                      const ContractionOptions& options = {});

/// The five IRC methods of §4.1 (docs/MODEL.md).
enum class IrcMethod {
  kStep,                       ///< §4.1.1, §5.3.1.
  kImpulse,                    ///< §4.1.2, §5.3.2.
  kRampCorrelation,            ///< §4.1.3 Eq. 4.5.
  kRampDeconvolutionIdeal,     ///< §4.1.3 Eqs. 4.6–4.8, ideal impulse.
  kRampDeconvolutionMeasured,  ///< §4.1.3, averaged measured impulse.
};
/// Every IRC method, in declaration order.
inline constexpr std::array<IrcMethod, 5> kIrcMethods = {
    IrcMethod::kStep, IrcMethod::kImpulse, IrcMethod::kRampCorrelation,
    IrcMethod::kRampDeconvolutionIdeal, IrcMethod::kRampDeconvolutionMeasured};

/// "step", "impulse", "ramp_correlation", "ramp_deconvolution_ideal",
/// "ramp_deconvolution_measured".
std::string_view IrcMethodName(IrcMethod method);
/// The method called `name` (IrcMethodName's words), or nullopt.
std::optional<IrcMethod> IrcMethodFromName(std::string_view name);

/// Options of IdentifyIrc.
struct IrcOptions {
  TwitchOptions twitch;
  double min_burst_s = 1.0;           ///< shorter non-impulse runs are ignored.
  double step_average_s = 0.5;        ///< §5.3.1: mean of the last 0.5 s.
  int ramp_points = 41;               ///< IRC breakpoints of the ramp methods.
  double max_lag_s = 0.5;             ///< correlation lags searched, 0..max.
  double deconvolution_tail_s = 1.0;  ///< response kept after a ramp, s.
  double lowpass_hz = 10.0;           ///< deconvolution band (below the pulse rate).
  double guard = 1e-3;                ///< |H(f)| below guard·max|H| is not divided.
  /// Ideal impulse of the ideal deconvolution: order (thesis: 2) and pole;
  /// pole_per_s <= 0 takes it from the trial's impulses (Eqs. 4.2, 4.4).
  ContractionParams ideal{2, 0.0};
};

/// A normalised IRC R(u) ∈ [0, 1] and the torque it is normalised by.
struct IrcResult {
  PiecewiseLinear irc;           ///< stim_ma → activation.
  double torque_scale_nm = 0.0;  ///< torque at R = 1 (full scale).
  IdentifyReport report;
};

/// Identifies the IRC from an isometric trial by `method`. Step uses the
/// bursts (runs ≥ min_burst_s), impulse the single pulses, the ramp methods
/// the cosine ramps (runs peaking mid-run); ramp IRCs average the
/// ascending and descending legs and then the ramps (§5.3.3, Fig. 6-2).
/// A point (0 mA, 0) is added below the lowest amplitude tested.
/// @throws std::invalid_argument if the trial lacks t_s/stim_ma/torque_nm,
///   holds no event of the kind the method needs, or gives no positive
///   torque.
IrcResult IdentifyIrc(IrcMethod method, const TrialColumns& trial, const IrcOptions& options = {});

/// R(u) with its onset at the session's threshold (beyond the thesis;
/// docs/MODEL.md, "The IRC's onset at the measured threshold"): 0 at and
/// below threshold_ma, a breakpoint inserted there, the curve unchanged
/// from the first breakpoint above it. Ramp correlation's single delay
/// smears a sharp onset into a toe below the threshold (§6.1.1, Fig. 6-10:
/// "the threshold is estimated low"); the tolerance test saw no torque
/// there (§5.2.1), and a controller inverting R over the toe commands
/// amplitudes that recruit nothing. The curve is returned unchanged when
/// threshold_ma is not above its first breakpoint or no breakpoint above
/// threshold_ma is positive (a threshold that would leave no response).
/// @throws std::invalid_argument for a non-finite threshold_ma.
PiecewiseLinear WithOnsetAtThreshold(const PiecewiseLinear& irc, double threshold_ma);

/// The delay s at which Corr(u, r)(lag) = Σ u(τ)·r(τ + lag) is largest over
/// lags 0..max_lag (Eq. 4.5), summed directly at those lags and refined by a
/// parabola.
/// @throws std::invalid_argument on empty or unequal inputs or rate <= 0.
double CorrelationDelay(std::span<const double> u, std::span<const double> r, double rate_hz,
                        double max_lag_s);

/// FFT deconvolution (Eqs. 4.6–4.8): s with r = s * g (g a sampled kernel
/// whose sum is its DC gain), S = R/G where |G| ≥ guard·max|G| and the
/// frequency is below lowpass_hz (cosine taper from 0.7·lowpass_hz), 0
/// elsewhere. Zero-padded, so no wrap-around.
/// @throws std::invalid_argument on empty inputs, rate <= 0 or guard <= 0.
std::vector<double> Deconvolve(std::span<const double> r, std::span<const double> g, double rate_hz,
                               double lowpass_hz, double guard);

}  // namespace fesbench::model
