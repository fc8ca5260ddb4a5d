#include "model/identify_isometric.h"

#include <algorithm>
#include <cmath>
#include <complex>
#include <limits>
#include <numbers>
#include <numeric>
#include <stdexcept>
#include <string>
#include <unsupported/Eigen/FFT>

#include "model/grid_golden_search.h"

namespace fesbench::model {
namespace {

constexpr std::size_t kMinTwitchSamples = 5;

std::size_t CheckIsometricTrial(const char* what, const TrialColumns& trial) {
  const std::size_t n = trial.size();
  if (n < 2) throw std::invalid_argument(std::string(what) + ": trial has fewer than 2 samples");
  RequireColumn(what, "t_s", trial.t_s, n);
  RequireColumn(what, "stim_ma", trial.stim_ma, n);
  RequireColumn(what, "torque_nm", trial.torque_nm, n);
  return n;
}

double Baseline(const TrialColumns& trial, std::size_t begin, std::size_t count) {
  if (begin == 0) return trial.torque_nm[0];
  const std::size_t b0 = begin - std::min(count, begin);
  double s = 0.0;
  for (std::size_t i = b0; i < begin; ++i) s += trial.torque_nm[i];
  return s / static_cast<double>(begin - b0);
}

// Ramp-shaped run: stimulation peaks in the middle half (a cosine ramp),
// unlike a step burst (peak reached early) or a constant burst.
bool IsRamp(const TrialColumns& trial, const StimulusRun& run) {
  const auto first = trial.stim_ma.begin() + static_cast<std::ptrdiff_t>(run.begin);
  const auto last = trial.stim_ma.begin() + static_cast<std::ptrdiff_t>(run.end);
  const auto [mn, mx] = std::minmax_element(first, last);
  if (*mx - *mn < 1e-6 * std::max(1.0, *mx)) return false;
  const double frac = static_cast<double>(mx - first) / static_cast<double>(run.size());
  return frac > 0.25 && frac < 0.75;
}

double RunDuration(const TrialColumns& trial, const StimulusRun& run) {
  return trial.t_s[run.end - 1] - trial.t_s[run.begin];
}

// Sorts (x, y) by x and averages ordinates of equal abscissae.
void SortMerge(std::vector<double>& x, std::vector<double>& y) {
  std::vector<std::size_t> idx(x.size());
  std::iota(idx.begin(), idx.end(), 0);
  std::stable_sort(idx.begin(), idx.end(), [&](auto a, auto b) { return x[a] < x[b]; });
  std::vector<double> xo, yo;
  for (std::size_t k = 0; k < idx.size();) {
    std::size_t j = k;
    double sy = 0.0;
    while (j < idx.size() && x[idx[j]] - x[idx[k]] <= 1e-9 * std::max(1.0, std::abs(x[idx[k]]))) {
      sy += y[idx[j]];
      ++j;
    }
    xo.push_back(x[idx[k]]);
    yo.push_back(sy / static_cast<double>(j - k));
    k = j;
  }
  x = std::move(xo);
  y = std::move(yo);
}

double InterpolateHeld(const std::vector<double>& x, const std::vector<double>& y, double q) {
  if (x.size() == 1 || q <= x.front()) return y.front();
  if (q >= x.back()) return y.back();
  const auto it = std::upper_bound(x.begin(), x.end(), q);
  const std::size_t hi = static_cast<std::size_t>(it - x.begin());
  const double w = (q - x[hi - 1]) / (x[hi] - x[hi - 1]);
  return (1.0 - w) * y[hi - 1] + w * y[hi];
}

// Normalises points (u, torque) into an IRC in [0, 1] (§6.1), adding
// (0, 0) below the lowest amplitude.
IrcResult NormaliseIrc(std::vector<double> u, std::vector<double> torque, const char* what) {
  SortMerge(u, torque);
  if (u.front() > 0.0) {
    u.insert(u.begin(), 0.0);
    torque.insert(torque.begin(), 0.0);
  }
  const double full = *std::max_element(torque.begin(), torque.end());
  if (!(full > 0.0)) throw std::invalid_argument(std::string(what) + ": no positive torque");
  for (double& v : torque) v = std::clamp(v / full, 0.0, 1.0);
  IrcResult out;
  out.irc = PiecewiseLinear(std::move(u), std::move(torque));
  out.torque_scale_nm = full;
  return out;
}

// Cross-plot of one ramp against its input (§4.1.3, Fig. 6-2): the
// ascending and descending legs, each interpolated on the grid, averaged.
std::vector<double> AverageLegs(std::span<const double> u, std::span<const double> s,
                                const std::vector<double>& grid) {
  const std::size_t peak =
      static_cast<std::size_t>(std::max_element(u.begin(), u.end()) - u.begin());
  std::vector<double> out(grid.size(), 0.0);
  for (int leg = 0; leg < 2; ++leg) {
    const std::size_t b = leg == 0 ? 0 : peak, e = leg == 0 ? peak + 1 : u.size();
    std::vector<double> x(u.begin() + static_cast<std::ptrdiff_t>(b),
                          u.begin() + static_cast<std::ptrdiff_t>(e));
    std::vector<double> y(s.begin() + static_cast<std::ptrdiff_t>(b),
                          s.begin() + static_cast<std::ptrdiff_t>(e));
    SortMerge(x, y);
    for (std::size_t g = 0; g < grid.size(); ++g) out[g] += 0.5 * InterpolateHeld(x, y, grid[g]);
  }
  return out;
}

double IdealKernelValue(const ContractionParams& c, double t) {
  // Unit-area h_n(t) = aⁿ t^(n−1) e^(−at)/(n−1)! (Eqs. 4.1, 4.3).
  const double a = c.pole_per_s;
  const double tn = c.order == 2 ? t : t * t;
  const double fact = c.order == 2 ? 1.0 : 2.0;
  return std::pow(a, c.order) * tn * std::exp(-a * t) / fact;
}

}  // namespace

std::vector<StimulusRun> FindStimulusRuns(std::span<const double> stim_ma) {
  std::vector<StimulusRun> runs;
  for (std::size_t i = 0; i < stim_ma.size();) {
    if (!(stim_ma[i] > 0.0)) {
      ++i;
      continue;
    }
    std::size_t j = i;
    while (j < stim_ma.size() && stim_ma[j] > 0.0) ++j;
    runs.push_back({i, j});
    i = j;
  }
  return runs;
}

TwitchAverage AverageImpulseResponses(std::span<const TrialColumns> trials,
                                      const TwitchOptions& options) {
  struct Piece {
    const TrialColumns* trial;
    std::size_t begin, length;
    double baseline, stim;
  };
  std::vector<Piece> pieces;
  for (const TrialColumns& trial : trials) {
    const std::size_t n = CheckIsometricTrial("AverageImpulseResponses", trial);
    const auto runs = FindStimulusRuns(trial.stim_ma);
    for (std::size_t k = 0; k < runs.size(); ++k) {
      if (runs[k].size() > options.max_impulse_samples) continue;
      const std::size_t limit = k + 1 < runs.size() ? runs[k + 1].begin : n;
      std::size_t end = runs[k].begin;
      while (end < limit && trial.t_s[end] - trial.t_s[runs[k].begin] <= options.window_s + 1e-9) {
        ++end;
      }
      const std::size_t len = end - runs[k].begin;
      if (len < kMinTwitchSamples) continue;
      const double stim =
          *std::max_element(trial.stim_ma.begin() + static_cast<std::ptrdiff_t>(runs[k].begin),
                            trial.stim_ma.begin() + static_cast<std::ptrdiff_t>(runs[k].end));
      pieces.push_back({&trial, runs[k].begin, len,
                        Baseline(trial, runs[k].begin, options.baseline_samples), stim});
    }
  }
  if (pieces.empty()) throw std::invalid_argument("AverageImpulseResponses: no impulse found");
  std::size_t len = pieces.front().length;
  for (const Piece& p : pieces) len = std::min(len, p.length);
  TwitchAverage avg;
  avg.t_s.resize(len);
  avg.torque_nm.assign(len, 0.0);
  for (const Piece& p : pieces) {
    for (std::size_t i = 0; i < len; ++i) {
      avg.torque_nm[i] += p.trial->torque_nm[p.begin + i] - p.baseline;
    }
    avg.stim_ma += p.stim;
  }
  const double cnt = static_cast<double>(pieces.size());
  for (std::size_t i = 0; i < len; ++i) {
    avg.torque_nm[i] /= cnt;
    avg.t_s[i] = pieces.front().trial->t_s[pieces.front().begin + i] -
                 pieces.front().trial->t_s[pieces.front().begin];
  }
  avg.count = static_cast<int>(pieces.size());
  avg.stim_ma /= cnt;
  return avg;
}

double PeakTime(std::span<const double> t_s, std::span<const double> y) {
  if (t_s.size() < 3 || y.size() != t_s.size()) {
    throw std::invalid_argument("PeakTime: need >= 3 samples of equal-length t and y");
  }
  const std::size_t k = static_cast<std::size_t>(std::max_element(y.begin(), y.end()) - y.begin());
  if (k == 0 || k + 1 == y.size()) return t_s[k];
  // Parabola through (k−1, k, k+1); uniform spacing assumed locally.
  const double ym = y[k - 1], y0 = y[k], yp = y[k + 1];
  const double denom = ym - 2.0 * y0 + yp;
  if (!(denom < 0.0)) return t_s[k];
  const double off = 0.5 * (ym - yp) / denom;
  const double h = 0.5 * (t_s[k + 1] - t_s[k - 1]);
  return t_s[k] + off * h;
}

double PoleFromPeak(int order, double t_peak_s) {
  if (order != 2 && order != 3) throw std::invalid_argument("PoleFromPeak: order must be 2 or 3");
  if (!(t_peak_s > 0.0)) throw std::invalid_argument("PoleFromPeak: peak time must be positive");
  return static_cast<double>(order - 1) / t_peak_s;  // Eqs. 4.2, 4.4
}

TwitchFit FitTwitchGain(std::span<const double> t_s, std::span<const double> torque_nm, int order,
                        double pole_per_s) {
  if (order != 2 && order != 3) throw std::invalid_argument("FitTwitchGain: order must be 2 or 3");
  if (t_s.size() != torque_nm.size() || t_s.empty()) {
    throw std::invalid_argument("FitTwitchGain: t and torque must be non-empty, equal length");
  }
  double py = 0.0, pp = 0.0;
  std::vector<double> phi(t_s.size());
  for (std::size_t i = 0; i < t_s.size(); ++i) {
    const double t = t_s[i];
    phi[i] = (order == 2 ? t : t * t) * std::exp(-pole_per_s * t);  // Eqs. 4.1, 4.3
    py += phi[i] * torque_nm[i];
    pp += phi[i] * phi[i];
  }
  TwitchFit fit;
  fit.order = order;
  fit.pole_per_s = pole_per_s;
  fit.gain = pp > 0.0 ? py / pp : 0.0;
  double ss = 0.0;
  for (std::size_t i = 0; i < t_s.size(); ++i) {
    const double e = fit.gain * phi[i] - torque_nm[i];
    ss += e * e;
  }
  fit.rms_nm = std::sqrt(ss / static_cast<double>(t_s.size()));  // Eq. 6.4
  return fit;
}

TwitchFit FitTwitchPole(std::span<const double> t_s, std::span<const double> torque_nm, int order,
                        double initial_pole_per_s) {
  if (!(initial_pole_per_s > 0.0)) {
    throw std::invalid_argument("FitTwitchPole: initial pole must be positive");
  }
  if (order != 2 && order != 3) throw std::invalid_argument("FitTwitchPole: order must be 2 or 3");
  if (t_s.size() != torque_nm.size() || t_s.empty()) {
    throw std::invalid_argument("FitTwitchPole: t and torque must be non-empty, equal length");
  }
  // FitTwitchGain's rms for each pole the search tries (Eqs. 4.1, 4.3,
  // 6.4), the basis in one workspace and e^(−a·t_i) without an exp per
  // sample: e^(−a·t_i) = e^(−a·t_{i−1})·e^(−a·dt)·e^(−a·(δ_i − dt)), δ_i =
  // t_i − t_{i−1}, dt their mean, the last factor 1 − a·(δ_i − dt) where
  // |a·(δ_i − dt)| ≤ 1e-8 (uniform sampling up to rounding; what is left
  // out is below 5e-17), exp itself elsewhere and every 16th sample (the
  // products' rounding stays below ~5e-15 relative).
  const std::size_t n = t_s.size();
  const double dt = n > 1 ? (t_s.back() - t_s.front()) / static_cast<double>(n - 1) : 0.0;
  std::vector<double> power(n), phi(n);
  for (std::size_t i = 0; i < n; ++i) power[i] = order == 2 ? t_s[i] : t_s[i] * t_s[i];
  const auto cost = [&](double log_a) {
    const double a = std::exp(log_a), step = std::exp(-a * dt);
    double e = 0.0, py = 0.0, pp = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      const double off = i > 0 ? a * ((t_s[i] - t_s[i - 1]) - dt) : 0.0;
      e = i % 16 == 0 || !(std::abs(off) <= 1e-8) ? std::exp(-a * t_s[i])
                                                  : e * (step * (1.0 - off));
      phi[i] = power[i] * e;
      py += phi[i] * torque_nm[i];
      pp += phi[i] * phi[i];
    }
    const double gain = pp > 0.0 ? py / pp : 0.0;
    double ss = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      const double r = gain * phi[i] - torque_nm[i];
      ss += r * r;
    }
    return std::sqrt(ss / static_cast<double>(n));
  };
  const double lo = std::log(initial_pole_per_s / 4.0), hi = std::log(initial_pole_per_s * 4.0);
  const GridGoldenResult search = GridGoldenSearch(cost, lo, hi, 24, 40);
  const double x = search.golden.cost < search.grid.cost ? search.golden.x : search.grid.x;
  return FitTwitchGain(t_s, torque_nm, order, std::exp(x));
}

ContractionResult IdentifyContraction(std::span<const TrialColumns> trials,
                                      const ContractionOptions& options) {
  if (options.order != 0 && options.order != 2 && options.order != 3) {
    throw std::invalid_argument("IdentifyContraction: order must be 0 (best), 2 or 3");
  }
  ContractionResult res;
  res.twitch = AverageImpulseResponses(trials, options.twitch);
  const auto& t = res.twitch.t_s;
  const auto& y = res.twitch.torque_nm;
  res.peak_time_s = PeakTime(t, y);
  if (!(res.peak_time_s > 0.0)) {
    throw std::invalid_argument("IdentifyContraction: the twitch peaks at the pulse");
  }
  res.order2_peak = FitTwitchGain(t, y, 2, PoleFromPeak(2, res.peak_time_s));
  res.order3_peak = FitTwitchGain(t, y, 3, PoleFromPeak(3, res.peak_time_s));
  res.order2_ls = FitTwitchPole(t, y, 2, res.order2_peak.pole_per_s);
  res.order3_ls = FitTwitchPole(t, y, 3, res.order3_peak.pole_per_s);
  int order = options.order;
  if (order == 0) order = res.order2_ls.rms_nm < res.order3_ls.rms_nm ? 2 : 3;
  const TwitchFit& chosen = options.method == PoleMethod::kPeak
                                ? (order == 2 ? res.order2_peak : res.order3_peak)
                                : (order == 2 ? res.order2_ls : res.order3_ls);
  res.contraction = {order, chosen.pole_per_s};
  res.report.fit_rms["twitch_order2_peak"] = res.order2_peak.rms_nm;
  res.report.fit_rms["twitch_order3_peak"] = res.order3_peak.rms_nm;
  res.report.fit_rms["twitch_order2_ls"] = res.order2_ls.rms_nm;
  res.report.fit_rms["twitch_order3_ls"] = res.order3_ls.rms_nm;
  res.report.values["twitch_peak_time_s"] = res.peak_time_s;
  res.report.values["twitch_count"] = res.twitch.count;
  res.report.values["pole_order2_peak_per_s"] = res.order2_peak.pole_per_s;
  res.report.values["pole_order3_peak_per_s"] = res.order3_peak.pole_per_s;
  res.report.values["pole_order2_ls_per_s"] = res.order2_ls.pole_per_s;
  res.report.values["pole_order3_ls_per_s"] = res.order3_ls.pole_per_s;
  return res;
}

std::string_view IrcMethodName(IrcMethod method) {
  switch (method) {
    case IrcMethod::kStep:
      return "step";
    case IrcMethod::kImpulse:
      return "impulse";
    case IrcMethod::kRampCorrelation:
      return "ramp_correlation";
    case IrcMethod::kRampDeconvolutionIdeal:
      return "ramp_deconvolution_ideal";
    case IrcMethod::kRampDeconvolutionMeasured:
      return "ramp_deconvolution_measured";
  }
  return "unknown";
}

std::string_view PoleMethodName(PoleMethod method) {
  return method == PoleMethod::kLeastSquares ? "least_squares" : "peak";
}

std::optional<PoleMethod> PoleMethodFromName(std::string_view name) {
  for (PoleMethod m : kPoleMethods) {
    if (PoleMethodName(m) == name) return m;
  }
  return std::nullopt;
}

std::optional<IrcMethod> IrcMethodFromName(std::string_view name) {
  for (IrcMethod m : kIrcMethods) {
    if (IrcMethodName(m) == name) return m;
  }
  return std::nullopt;
}

double CorrelationDelay(std::span<const double> u, std::span<const double> r, double rate_hz,
                        double max_lag_s) {
  if (u.empty() || u.size() != r.size() || !(rate_hz > 0.0) || !(max_lag_s >= 0.0)) {
    throw std::invalid_argument("CorrelationDelay: need equal non-empty signals, rate > 0");
  }
  const std::size_t n = u.size();
  const std::size_t max_lag =
      std::min<std::size_t>(n - 1, static_cast<std::size_t>(std::floor(max_lag_s * rate_hz)));
  // corr[lag] = Σ u(τ)·r(τ + lag) (Eq. 4.5) at the lags searched only,
  // summed directly: one pass over u with every lag's sum in τ order (a
  // stimulation is zero over much of the window and adds nothing there).
  std::vector<double> corr(max_lag + 1, 0.0);
  for (std::size_t t = 0; t < n; ++t) {
    const double ut = u[t];
    if (ut == 0.0) continue;
    const std::size_t lags = std::min(max_lag, n - 1 - t);
    for (std::size_t k = 0; k <= lags; ++k) corr[k] += ut * r[t + k];
  }
  std::size_t best = 0;
  for (std::size_t k = 1; k <= max_lag; ++k) {
    if (corr[k] > corr[best]) best = k;
  }
  double lag = static_cast<double>(best);
  if (best > 0 && best < max_lag) {
    const double ym = corr[best - 1], y0 = corr[best], yp = corr[best + 1];
    const double denom = ym - 2.0 * y0 + yp;
    if (denom < 0.0) lag += 0.5 * (ym - yp) / denom;
  }
  return lag / rate_hz;
}

std::vector<double> Deconvolve(std::span<const double> r, std::span<const double> g, double rate_hz,
                               double lowpass_hz, double guard) {
  if (r.empty() || g.empty() || !(rate_hz > 0.0) || !(guard > 0.0) || !(lowpass_hz > 0.0)) {
    throw std::invalid_argument("Deconvolve: need non-empty signals, rate, lowpass, guard > 0");
  }
  std::size_t nfft = 1;
  while (nfft < r.size() + g.size()) nfft *= 2;
  std::vector<double> rb(nfft, 0.0), gb(nfft, 0.0);
  std::copy(r.begin(), r.end(), rb.begin());
  std::copy(g.begin(), g.end(), gb.begin());
  Eigen::FFT<double> fft;
  std::vector<std::complex<double>> rf, gf;
  fft.fwd(rf, rb);  // Eq. 4.7
  fft.fwd(gf, gb);
  double gmax = 0.0;
  for (const auto& v : gf) gmax = std::max(gmax, std::abs(v));
  const double df = rate_hz / static_cast<double>(nfft);
  for (std::size_t k = 0; k < nfft; ++k) {
    const double f = df * static_cast<double>(std::min(k, nfft - k));
    double taper = 1.0;
    if (f >= lowpass_hz) {
      taper = 0.0;
    } else if (f > 0.7 * lowpass_hz) {
      taper =
          0.5 * (1.0 + std::cos(std::numbers::pi * (f - 0.7 * lowpass_hz) / (0.3 * lowpass_hz)));
    }
    // Eq. 4.8, guarded: no division by a near-zero |G|.
    rf[k] = (std::abs(gf[k]) >= guard * gmax && taper > 0.0) ? taper * rf[k] / gf[k]
                                                             : std::complex<double>(0.0, 0.0);
  }
  std::vector<double> s;
  fft.inv(s, rf);
  s.resize(r.size());
  return s;
}

PiecewiseLinear WithOnsetAtThreshold(const PiecewiseLinear& irc, double threshold_ma) {
  if (!std::isfinite(threshold_ma)) {
    throw std::invalid_argument("WithOnsetAtThreshold: threshold_ma must be finite");
  }
  const std::vector<double>& x = irc.x();
  const std::vector<double>& y = irc.y();
  const auto above = std::upper_bound(x.begin(), x.end(), threshold_ma);
  const std::size_t first_above = static_cast<std::size_t>(above - x.begin());
  const bool responds_above =
      std::any_of(y.begin() + static_cast<std::ptrdiff_t>(first_above), y.end(),
                  [](double v) { return v > 0.0; });
  if (first_above == 0 || !responds_above) return irc;
  std::vector<double> xo(x.begin(), x.begin() + static_cast<std::ptrdiff_t>(first_above));
  std::vector<double> yo(first_above, 0.0);
  if (xo.back() < threshold_ma) {
    xo.push_back(threshold_ma);
    yo.push_back(0.0);
  }
  xo.insert(xo.end(), above, x.end());
  yo.insert(yo.end(), y.begin() + static_cast<std::ptrdiff_t>(first_above), y.end());
  return PiecewiseLinear(std::move(xo), std::move(yo));
}

IrcResult IdentifyIrc(IrcMethod method, const TrialColumns& trial, const IrcOptions& options) {
  const char* what = "IdentifyIrc";
  const std::size_t n = CheckIsometricTrial(what, trial);
  const double rate = trial.SampleRateHz();
  const auto runs = FindStimulusRuns(trial.stim_ma);
  std::vector<double> u, torque;
  IdentifyReport report;

  if (method == IrcMethod::kStep) {
    for (const StimulusRun& run : runs) {  // §4.1.1, §5.3.1
      if (run.size() <= options.twitch.max_impulse_samples ||
          RunDuration(trial, run) < options.min_burst_s || IsRamp(trial, run)) {
        continue;
      }
      const double t_end = trial.t_s[run.end - 1];
      double su = 0.0, st = 0.0;
      int cnt = 0;
      for (std::size_t i = run.begin; i < run.end; ++i) {
        if (trial.t_s[i] > t_end - options.step_average_s) {
          su += trial.stim_ma[i];
          st += trial.torque_nm[i];
          ++cnt;
        }
      }
      u.push_back(su / cnt);
      torque.push_back(st / cnt - Baseline(trial, run.begin, options.twitch.baseline_samples));
    }
    if (u.empty()) throw std::invalid_argument("IdentifyIrc(step): no stimulation burst found");
  } else if (method == IrcMethod::kImpulse) {
    for (std::size_t k = 0; k < runs.size(); ++k) {  // §4.1.2, §5.3.2
      const StimulusRun& run = runs[k];
      if (run.size() > options.twitch.max_impulse_samples) continue;
      const std::size_t limit = k + 1 < runs.size() ? runs[k + 1].begin : n;
      const double base = Baseline(trial, run.begin, options.twitch.baseline_samples);
      double peak = -std::numeric_limits<double>::infinity();
      for (std::size_t i = run.begin;
           i < limit && trial.t_s[i] - trial.t_s[run.begin] <= options.twitch.window_s; ++i) {
        peak = std::max(peak, trial.torque_nm[i] - base);
      }
      u.push_back(*std::max_element(trial.stim_ma.begin() + static_cast<std::ptrdiff_t>(run.begin),
                                    trial.stim_ma.begin() + static_cast<std::ptrdiff_t>(run.end)));
      torque.push_back(peak);
    }
    if (u.empty()) throw std::invalid_argument("IdentifyIrc(impulse): no single pulse found");
  } else {
    std::vector<std::size_t> ramps;
    for (std::size_t k = 0; k < runs.size(); ++k) {
      if (RunDuration(trial, runs[k]) >= options.min_burst_s && IsRamp(trial, runs[k])) {
        ramps.push_back(k);
      }
    }
    if (ramps.empty()) throw std::invalid_argument("IdentifyIrc(ramp): no cosine ramp found");
    if (options.ramp_points < 2) throw std::invalid_argument("IdentifyIrc: ramp_points < 2");

    // Kernel of the deconvolution methods (unit DC gain).
    std::vector<double> kernel;
    if (method != IrcMethod::kRampCorrelation) {
      if (method == IrcMethod::kRampDeconvolutionMeasured) {
        const TwitchAverage tw = AverageImpulseResponses(std::span(&trial, 1), options.twitch);
        kernel = tw.torque_nm;
        report.values["impulses_averaged"] = tw.count;
      } else {
        ContractionParams ideal = options.ideal;
        if (ideal.order != 2 && ideal.order != 3) {
          throw std::invalid_argument("IdentifyIrc: ideal impulse order must be 2 or 3");
        }
        if (!(ideal.pole_per_s > 0.0)) {
          const TwitchAverage tw = AverageImpulseResponses(std::span(&trial, 1), options.twitch);
          ideal.pole_per_s = PoleFromPeak(ideal.order, PeakTime(tw.t_s, tw.torque_nm));
        }
        report.values["ideal_pole_per_s"] = ideal.pole_per_s;
        report.values["ideal_order"] = ideal.order;
        const std::size_t len =
            static_cast<std::size_t>(std::ceil(12.0 / ideal.pole_per_s * rate)) + 1;
        for (std::size_t i = 0; i < len; ++i) {
          kernel.push_back(IdealKernelValue(ideal, static_cast<double>(i) / rate));
        }
      }
      const double sum = std::accumulate(kernel.begin(), kernel.end(), 0.0);
      if (!(sum > 0.0)) throw std::invalid_argument("IdentifyIrc: impulse response has no area");
      for (double& v : kernel) v /= sum;
    }

    double u_lo = std::numeric_limits<double>::infinity(), u_hi = 0.0;
    for (std::size_t k : ramps) {
      for (std::size_t i = runs[k].begin; i < runs[k].end; ++i) {
        u_lo = std::min(u_lo, trial.stim_ma[i]);
        u_hi = std::max(u_hi, trial.stim_ma[i]);
      }
    }
    std::vector<double> grid(static_cast<std::size_t>(options.ramp_points));
    for (std::size_t g = 0; g < grid.size(); ++g) {
      grid[g] =
          u_lo + (u_hi - u_lo) * static_cast<double>(g) / static_cast<double>(grid.size() - 1);
    }
    std::vector<double> acc(grid.size(), 0.0);
    double delay_sum = 0.0;
    for (std::size_t idx = 0; idx < ramps.size(); ++idx) {
      const std::size_t k = ramps[idx];
      const StimulusRun& run = runs[k];
      const std::size_t limit = k + 1 < runs.size() ? runs[k + 1].begin : n;
      const double base = Baseline(trial, run.begin, options.twitch.baseline_samples);
      const double tail_s =
          method == IrcMethod::kRampCorrelation ? options.max_lag_s : options.deconvolution_tail_s;
      const std::size_t end =
          std::min(limit, run.end + static_cast<std::size_t>(std::ceil(tail_s * rate)));
      std::vector<double> useg(end - run.begin, 0.0), rseg(end - run.begin);
      for (std::size_t i = run.begin; i < end; ++i) {
        if (i < run.end) useg[i - run.begin] = trial.stim_ma[i];
        rseg[i - run.begin] = trial.torque_nm[i] - base;
      }
      std::vector<double> s(run.size());
      if (method == IrcMethod::kRampCorrelation) {
        // Eq. 4.5: delay at maximum correlation; shift and cross-plot.
        const double delay = CorrelationDelay(useg, rseg, rate, options.max_lag_s);
        delay_sum += delay;
        for (std::size_t i = 0; i < run.size(); ++i) {
          const double pos = static_cast<double>(i) + delay * rate;
          const std::size_t i0 = std::min(static_cast<std::size_t>(pos), rseg.size() - 1);
          const std::size_t i1 = std::min(i0 + 1, rseg.size() - 1);
          const double w = std::clamp(pos - static_cast<double>(i0), 0.0, 1.0);
          s[i] = (1.0 - w) * rseg[i0] + w * rseg[i1];
        }
      } else {
        const auto dec = Deconvolve(rseg, kernel, rate, options.lowpass_hz, options.guard);
        std::copy(dec.begin(), dec.begin() + static_cast<std::ptrdiff_t>(run.size()), s.begin());
      }
      const auto legs = AverageLegs(std::span(useg).first(run.size()), s, grid);
      for (std::size_t g = 0; g < grid.size(); ++g)
        acc[g] += legs[g] / static_cast<double>(ramps.size());
    }
    if (method == IrcMethod::kRampCorrelation) {
      report.values["correlation_delay_s"] = delay_sum / static_cast<double>(ramps.size());
    }
    report.values["ramps_averaged"] = static_cast<double>(ramps.size());
    u = grid;
    torque = acc;
  }
  IrcResult out = NormaliseIrc(std::move(u), std::move(torque), what);
  out.report.Merge(report);
  out.report.values["irc_points"] = static_cast<double>(out.irc.size());
  out.report.values["irc_torque_scale_nm"] = out.torque_scale_nm;
  return out;
}

}  // namespace fesbench::model
