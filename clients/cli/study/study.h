#pragma once

/// @file
/// The virtual-cohort study (`fesbench study`, thesis ch. 6 and §7.4.1):
/// drives a running fesbench-server with a simulated bench through its
/// public HTTP API for N seeded virtual legs of one or more shape families,
/// then writes the clinician-chain table (docs/STUDY.md: the default rapid set
/// predicting the default prediction protocols, its errors against the
/// truth), the equivalents of Tables 6.1–6.9, per-leg error tables
/// (Appendices J, K) and bench times as Markdown and CSV, and gnuplot PNGs
/// of predicted vs measured knee angle.
/// Deterministic for a seed given a fresh server with the same --seed.

#include <cstdint>
#include <filesystem>
#include <iosfwd>
#include <string>
#include <vector>

#include "clients/cli/api_client.h"

namespace fesbench::cli::study {

struct StudyOptions {
  int legs = 16;  ///< cohort size, ≥ 2 (t-tests need n − 1 ≥ 1).
  /// leg i's virtual subject is the server's draw from seed·1000 + i
  /// (PUT /bench/virtual-subject {"draw_seed"}).
  std::uint64_t seed = 1;
  /// Shape families of the drawn legs ("thesis", "analytic", "plateau"; PUT
  /// /bench/virtual-subject {"family"}), taken in turn: leg i is
  /// families[(i − 1) mod size].
  std::vector<std::string> families = {"thesis", "analytic"};
  std::filesystem::path output_dir;  ///< created; tables, data files and PNGs go here.
  std::string date = "2026-01-01";   ///< session date (fixed for determinism).
  bool plots = true;                 ///< run gnuplot (if found on PATH).
};

struct StudySummary {
  int legs_done = 0;
  int identifications_failed = 0;
  bool plots_drawn = false;
  std::string plot_note;  ///< why plots are missing, if they are.
};

/// Runs the study. Needs an admin token (PUT /bench/virtual-subject).
/// Throws CliError on a server error that stops the study (a failed run);
/// an identification that fails is recorded in the tables as "failed".
StudySummary RunStudy(ApiClient& client, const StudyOptions& options, std::ostream& log);

}  // namespace fesbench::cli::study
