#include "model/quality.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

#include "model/piecewise_linear.h"

namespace fesbench::model {
namespace {

double RmsAboutMean(std::span<const double> x, const char* which) {
  if (x.size() < 2)
    throw std::invalid_argument(std::string("CompareEmg: ") + which + " window has < 2 samples");
  double mean = 0.0;
  for (double v : x) {
    if (!std::isfinite(v)) throw std::invalid_argument("CompareEmg: non-finite EMG sample");
    mean += v;
  }
  mean /= static_cast<double>(x.size());
  double ss = 0.0;
  for (double v : x) ss += (v - mean) * (v - mean);
  return std::sqrt(ss / static_cast<double>(x.size()));
}

void CheckEdges(std::span<const double> e, const char* what) {
  if (e.size() < 2)
    throw std::invalid_argument(std::string("PhasePlaneCoverage: ") + what + " needs >= 2 edges");
  for (std::size_t i = 1; i < e.size(); ++i) {
    if (!(e[i] > e[i - 1])) {
      throw std::invalid_argument(std::string("PhasePlaneCoverage: ") + what +
                                  " not strictly increasing");
    }
  }
}

// The bin of x, edges[b] <= x < edges[b + 1] (the last bin closed), −1
// outside; found by a scan from `segment`, the last sample's bin
// (PiecewiseLinear::Basis's segment).
int Bin(std::span<const double> edges, double x, std::size_t& segment) {
  if (!(x >= edges.front()) || !(x <= edges.back())) return -1;
  return static_cast<int>(PiecewiseLinear::Basis(edges, x, segment).index_lo);
}

}  // namespace

EmgComparison CompareEmg(std::span<const double> pre, std::span<const double> post,
                         double ratio_threshold) {
  if (!(ratio_threshold > 1.0))
    throw std::invalid_argument("CompareEmg: ratio_threshold must be > 1");
  EmgComparison c;
  c.pre_rms = RmsAboutMean(pre, "pre");
  c.post_rms = RmsAboutMean(post, "post");
  if (c.pre_rms > 0.0) {
    c.ratio = c.post_rms / c.pre_rms;
  } else {
    c.ratio = c.post_rms > 0.0 ? std::numeric_limits<double>::infinity() : 1.0;
  }
  c.voluntary_contraction = c.ratio > ratio_threshold || c.ratio < 1.0 / ratio_threshold;
  return c;
}

EmgComparison CompareEmgPrePost(std::span<const double> emg, double rate_hz, double window_s,
                                double ratio_threshold) {
  if (!(rate_hz > 0.0) || !(window_s > 0.0)) {
    throw std::invalid_argument("CompareEmgPrePost: rate and window must be positive");
  }
  const std::size_t w = static_cast<std::size_t>(std::llround(window_s * rate_hz));
  if (w < 2 || emg.size() < 2 * w) {
    throw std::invalid_argument("CompareEmgPrePost: recording shorter than two windows");
  }
  return CompareEmg(emg.first(w), emg.last(w), ratio_threshold);
}

Coverage PhasePlaneCoverage(std::span<const double> angle_deg,
                            std::span<const double> velocity_deg_s,
                            std::span<const double> angle_edges_deg,
                            std::span<const double> velocity_edges_deg_s, int min_samples) {
  if (angle_deg.size() != velocity_deg_s.size()) {
    throw std::invalid_argument("PhasePlaneCoverage: angle and velocity differ in length");
  }
  CheckEdges(angle_edges_deg, "angle edges");
  CheckEdges(velocity_edges_deg_s, "velocity edges");
  const int na = static_cast<int>(angle_edges_deg.size()) - 1;
  const int nv = static_cast<int>(velocity_edges_deg_s.size()) - 1;
  Coverage c;
  c.cells_total = na * nv;
  c.counts.assign(static_cast<std::size_t>(c.cells_total), 0);
  std::size_t angle_bin = 0, velocity_bin = 0;
  for (std::size_t i = 0; i < angle_deg.size(); ++i) {
    const int a = Bin(angle_edges_deg, angle_deg[i], angle_bin);
    const int v = Bin(velocity_edges_deg_s, velocity_deg_s[i], velocity_bin);
    if (a >= 0 && v >= 0) ++c.counts[static_cast<std::size_t>(a * nv + v)];
  }
  for (int k : c.counts) c.cells_visited += k >= min_samples ? 1 : 0;
  c.share = static_cast<double>(c.cells_visited) / static_cast<double>(c.cells_total);
  return c;
}

std::string CoverageWarning(const std::string& what, const Coverage& coverage, double warn_below) {
  if (coverage.share >= warn_below) return {};
  char buf[256];
  std::snprintf(buf, sizeof buf,
                "%s: phase-plane coverage %.0f%% of %d cells; curves may be under-determined "
                "or their errors coupled (§6.8)",
                what.c_str(), 100.0 * coverage.share, coverage.cells_total);
  return buf;
}

}  // namespace fesbench::model
