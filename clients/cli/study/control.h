#pragma once

/// @file
/// The study's control chapter (docs/STUDY.md, thesis §7.6.3): each leg's rapid
/// set drives the `tracking` protocol with the three controllers on a
/// 0.2 Hz sine 30–80° and on a sequence of holds (30 s each), and, with the
/// leg's fatigue rate turned up five-fold, on the sine for 2 minutes. Every
/// run starts from a fresh bench (the virtual subject is put again), so no
/// controller inherits another's fatigue. The tables give tracking RMS,
/// overshoot, settling time and charge per controller and the paired
/// t-tests (Eq. 6.3) between them.

#include <cstdint>
#include <filesystem>
#include <iosfwd>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "api/run.h"
#include "api/run_start.h"
#include "api/virtual_subject.h"
#include "clients/cli/api_client.h"

namespace fesbench::cli::study {

/// Starts a protocol and heart-beats it to its end; the run as it ended.
/// Throws CliError (server class) when the run is refused, fails or aborts.
api::RunView RunProtocol(ApiClient& client, std::int64_t session_id,
                         const api::StartRunRequest& request);

/// One tracking run's figures, or why there are none.
struct TrackingFigures {
  double rms_deg = 0.0;
  double max_error_deg = 0.0;
  double overshoot_deg = 0.0;  ///< holds only (NaN otherwise).
  double settling_s = 0.0;     ///< holds only (NaN otherwise).
  double charge_mc = 0.0;
  double saturated_s = 0.0;
  double tau_scale_nm = 0.0;         ///< the controller's τ̂ at the end.
  double worst_overshoot_deg = 0.0;  ///< the run's worst hold (NaN without holds).
  double worst_settling_s = 0.0;     ///< the run's worst hold (NaN without holds).
  double above_1hz_deg = 0.0;        ///< the error's RMS above 1 Hz.
  double zero_ma_s = 0.0;            ///< seconds commanded 0 mA.
  double max_ma_s = 0.0;             ///< seconds commanded the maximum.
  double backoffs = 0.0;             ///< the loop's oscillation back-offs.
  std::string failure;               ///< non-empty: refused or failed, the server's words.
};

/// A leg's tracking runs: condition ("sine", "holds", "fatigue") →
/// controller ("pid", "inverse_model", "adaptive") → figures.
struct LegControl {
  int index = 0;
  std::string family;
  std::int64_t parameter_set_id = 0;
  std::map<std::string, std::map<std::string, TrackingFigures>> runs;
};

/// Runs the chapter's tracking runs on a leg with its rapid set.
/// `subject` is the virtual subject as the server returned it (PUT
/// /bench/virtual-subject), put again before every run.
LegControl RunLegControl(ApiClient& client, int index, const std::string& family,
                         std::int64_t session_id, std::int64_t parameter_set_id,
                         const api::VirtualSubject& subject, std::ostream& log);

/// The chapter's tables as Markdown (and one CSV each in dir).
void WriteControlChapter(const std::vector<LegControl>& legs, const std::filesystem::path& dir,
                         std::ostream& markdown);

}  // namespace fesbench::cli::study
