#pragma once

/// @file
/// The session report (GET /sessions/{id}/report, `fesbench report`): one
/// self-contained, printable HTML page a clinician can file — the subject by
/// pseudonymous code, the session's values, its runs and their outcomes
/// (safety events: e-stops, clamps), its trials, the parameter sets
/// identified from them with their curves drawn (identified range marked),
/// predictions on trials the set was not fitted on (measured against
/// predicted), and the warnings. Inline CSS and SVG only: no script, no
/// external resource; A4 print rules.
///
/// Gathering (GatherSessionReport) reads storage; rendering
/// (RenderSessionReport) is a pure function of what was gathered.

#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "api/status.h"
#include "model/parameter_set.h"
#include "storage/database.h"

namespace fesbench::server::services {

/// One stored prediction of a set on a stored trial.
struct ReportPrediction {
  std::int64_t prediction_id = 0;
  std::int64_t trial_id = 0;
  std::string trial_name;
  bool fresh = true;  ///< the trial is not among the set's provenance trials.
  /// The channel the errors compare (angle_deg of a free swing, torque_nm
  /// of an isometric trial) and its unit.
  std::string channel = "angle_deg";
  std::string unit = "deg";
  std::optional<double> e_rms;  ///< in `unit`.
  std::optional<double> e_abs;
  std::optional<double> share_outside;  ///< of samples outside the identified ranges.
  std::vector<double> t_s;              ///< measured and predicted `channel`, on the trial's time.
  std::vector<double> measured;
  std::vector<double> predicted;
};

struct ReportSet {
  std::int64_t id = 0;
  int version = 1;
  std::string created_at_utc;
  model::ParameterSet params;
  std::vector<ReportPrediction> predictions;
};

struct SessionReport {
  std::string software_version;
  std::string generated_at_utc;
  nlohmann::json session;  ///< GET /sessions/{id}
  nlohmann::json subject;  ///< GET /subjects/{id} (code and details only are shown)
  nlohmann::json runs;     ///< array of GET /runs/{id}
  nlohmann::json trials;   ///< array of trial summaries (GET /sessions/{id}/trials items)
  std::vector<ReportSet> sets;
  bool sets_from_session = true;  ///< false: none was fitted here; the leg's approved one is shown.
  bool shown_set_approved = false;  ///< with !sets_from_session: the set shown is approved (else newest).
  std::vector<std::string> estops;  ///< e-stop latches during the session's runs.
};

/// Reads what the report shows (the JSON parts are given in the API's
/// shapes by the caller). kNotFound for an unknown session.
api::Result<SessionReport> GatherSessionReport(storage::Database& db, std::int64_t session_id,
                                               SessionReport base);

/// The report as one HTML document. Every stored string is escaped.
std::string RenderSessionReport(const SessionReport& report);

/// `text` with &, <, >, " and ' escaped for HTML text and attributes.
std::string HtmlEscape(std::string_view text);

}  // namespace fesbench::server::services
