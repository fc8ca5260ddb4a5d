#pragma once

/// @file
/// The study's internals shared by its runs (study.cc) and its tables
/// (cohort_tables.cc): what one leg of the cohort recorded, and the names of
/// its inputs and parameter sets.

#include <cstdint>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "api/analysis_results.h"
#include "api/virtual_subject.h"
#include "clients/cli/study/control.h"
#include "clients/cli/study/tables.h"
#include "model/identify_isometric.h"
#include "model/parameter_set.h"

namespace fesbench::cli::study {

inline constexpr const char* kRapid = "rapid_parameterisation";

// The clinician chain (docs/STUDY.md): the rapid set predicting each default
// prediction protocol's fresh trial. Label and trial name.
struct Input {
  std::string label;
  std::string trial;
};
inline const std::vector<Input> kChainInputs = {
    {"rb_seed3", "prediction_random_binary_seed3"},
    {"rb_seed4", "prediction_random_binary_seed4"},
    {"step", "prediction_step"},
    {"ramp", "prediction_ramp"},
    {"sine", "prediction_sine"},
};

// Prediction inputs of the thesis tables (§5.4.5): label and trial name.
inline const std::vector<Input> kInputs = {
    {"step", "prediction_step"},         {"ramp", "prediction_ramp"},
    {"sine", "prediction_sine"},         {"rb1", "active_random_binary_rb1"},
    {"rb2", "active_random_binary_rb2"},
};

// The six full-model parameter sets (3 passive methods × 2 active trains).
inline const std::vector<std::string> kPassiveMethods = {"sequential", "simultaneous", "free_swing"};
inline const std::vector<std::string> kTrains = {"rb1", "rb2"};
inline const std::vector<std::string> kSimplified = {"torque_generator", "single_segment",
                                              "static_gain_pwl_velocity", "parametric"};
// Isometric IRC variants (Tables 6.1, 6.2): irc method × contraction order.
struct IrcVariant {
  std::string key;
  model::IrcMethod irc_method;
  int order;
};
inline const std::vector<IrcVariant> kIrcVariants = {
    {"step_o3", model::IrcMethod::kStep, 3},
    {"ramp_o3", model::IrcMethod::kRampCorrelation, 3},
    {"step_o2", model::IrcMethod::kStep, 2},
    {"ramp_o2", model::IrcMethod::kRampCorrelation, 2}};

inline std::string SetKey(const std::string& passive, const std::string& train) {
  return passive + "_" + train;
}


// A leg's virtual subject as the server drew it (PUT /bench/virtual-subject
// {"draw_seed": N}): the truth for the tables and what the session records.
struct DrawnSubject {
  std::string family;
  std::uint64_t draw_seed = 0;
  model::ParameterSet truth;
  double threshold_ma = 0.0;
  double max_tolerated_ma = 0.0;
  double body_mass_kg = 0.0;
  double height_m = 0.0;
  double shank_length_m = 0.0;
  api::VirtualSubject as_drawn;  // the server's subject (put again to reset the bench)
};

// Everything one leg recorded: runs, trials, sets, errors, control.
struct LegData {
  int index = 0;
  DrawnSubject subject;
  std::int64_t session_id = 0;
  std::map<std::string, std::int64_t> trials;       // name → id
  std::map<std::string, double> bench_s;            // protocol → bench seconds
  std::map<std::string, std::int64_t> sets;         // set key → parameter set id
  std::map<std::string, std::string> set_failures;  // set key → message
  std::map<std::string, std::string> run_failures;  // run label → message
  std::map<std::string, model::ParameterSet> params;
  std::optional<model::Provenance> rapid_provenance;  // the rapid set's, as stored
  std::map<std::string, std::string> prediction_failures;  // "set|input" → message
  // set key → input label → {e_rms, e_abs} (deg; isometric: N·m)
  std::map<std::string, std::map<std::string, std::pair<double, double>>> errors;
  std::map<std::string, api::PredictionColumns> plot_columns;  // "set|input" → predicted columns
  std::optional<LegControl> control;         // the tracking runs with the rapid set
};


/// The study's tables, the clinician chain first (study.md's order).
std::vector<Table> BuildTables(const std::vector<LegData>& legs);

}  // namespace fesbench::cli::study
