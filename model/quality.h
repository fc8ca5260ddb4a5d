#pragma once

/// @file
/// Data-quality checks of identification trials: the EMG pre/post
/// comparison that flags voluntary contraction (§5.2.1, Fig. 5-6) and the
/// phase-plane coverage of a trial (§6.6, §6.8, Fig. 6-30).

#include <cstddef>
#include <span>
#include <string>
#include <vector>

namespace fesbench::model {

/// Result of comparing EMG recorded before and after a trial section.
struct EmgComparison {
  double pre_rms = 0.0;  ///< RMS about the mean, EMG units.
  double post_rms = 0.0;
  double ratio = 0.0;  ///< post_rms / pre_rms (∞ if pre_rms is 0 and post is not).
  bool voluntary_contraction = false;  ///< ratio outside [1/threshold, threshold].
};

/// §5.2.1: "A noticeable difference between the two signals indicated
/// voluntary contraction": flags when the post/pre RMS ratio exceeds
/// ratio_threshold or falls below 1/ratio_threshold (the subject was
/// contracting before and relaxed after).
/// @throws std::invalid_argument if either window has fewer than 2 samples,
///   holds a non-finite value, or ratio_threshold <= 1.
EmgComparison CompareEmg(std::span<const double> pre, std::span<const double> post,
                         double ratio_threshold = 1.5);

/// The same on one EMG recording: the first and last window_s (Fig. 5-6:
/// the first and last tenth of a second) at rate_hz.
/// @throws std::invalid_argument as CompareEmg, or if the recording is
///   shorter than two windows or rate_hz <= 0.
EmgComparison CompareEmgPrePost(std::span<const double> emg, double rate_hz, double window_s = 0.1,
                                double ratio_threshold = 1.5);

/// Phase-plane coverage of a trial on a grid of angle × velocity cells.
struct Coverage {
  double share = 0.0;  ///< visited cells / all cells, 0–1.
  int cells_visited = 0;
  int cells_total = 0;
  std::vector<int> counts;  ///< samples per cell, angle-major.
};

/// Counts samples in the cells between consecutive angle edges and velocity
/// edges (samples outside the edges are not counted); a cell is visited
/// with at least min_samples samples. Typically the edges are the fit's
/// breakpoints, so an unvisited cell is a pair of segments the data never
/// excite together (§6.8).
/// @throws std::invalid_argument if the columns differ in length or an
///   edge list has fewer than 2 strictly increasing values.
Coverage PhasePlaneCoverage(std::span<const double> angle_deg,
                            std::span<const double> velocity_deg_s,
                            std::span<const double> angle_edges_deg,
                            std::span<const double> velocity_edges_deg_s, int min_samples = 1);

/// A warning when coverage.share < warn_below ("<what>: phase-plane
/// coverage 18% of 100 cells; curves may be under-determined or their
/// errors coupled (§6.8)"), else empty.
std::string CoverageWarning(const std::string& what, const Coverage& coverage,
                            double warn_below = 0.25);

}  // namespace fesbench::model
