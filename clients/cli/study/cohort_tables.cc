// The study's tables (see cohort.h): the clinician chain, the equivalents of
// Tables 6.1–6.9, per-leg errors and bench times, from the legs' records.

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "api/model_call.h"
#include "clients/cli/study/cohort.h"
#include "clients/cli/study/tables.h"
#include "model/evaluation.h"
#include "model/joint_model.h"

namespace fesbench::cli::study {

namespace {

// ---- tables -----------------------------------------------------------

double ErrorOf(const LegData& leg, const std::string& key, const std::string& input) {
  auto s = leg.errors.find(key);
  if (s == leg.errors.end()) return kNaN;
  auto e = s->second.find(input);
  return e == s->second.end() ? kNaN : e->second.first;
}

// A paired t-test row (Eq. 6.3) over the legs where both errors exist.
std::vector<std::string> TTestRow(const std::vector<LegData>& legs, const std::string& input,
                                  const std::string& a, const std::string& b) {
  std::vector<double> xa, xb;
  for (const auto& leg : legs) {
    const double ea = ErrorOf(leg, a, input), eb = ErrorOf(leg, b, input);
    if (std::isfinite(ea) && std::isfinite(eb)) xa.push_back(ea), xb.push_back(eb);
  }
  std::vector<std::string> row = {input, a, b};
  for (std::string& cell : TTestCells(xa, xb)) row.push_back(std::move(cell));
  return row;
}

const std::vector<std::string> kTTestHeader = {"input",  "set_a",     "set_b",      "n", "mean_a",
                                               "mean_b", "mean_diff", "sd_diff",    "t", "df",
                                               "p",      "t_crit_95", "significant"};

// The ranges a set's curves were identified over, compactly: "curve lo..hi;
// …"; "n/a" without the set.
std::string RangeText(const std::optional<model::Provenance>& provenance,
                      std::map<std::string, model::CurveRange> model::Provenance::*ranges) {
  if (!provenance) return "n/a";
  std::string text;
  for (const auto& [curve, r] : (*provenance).*ranges) {
    text += (text.empty() ? "" : "; ") + curve + " " + Num(r.lo, 1) + ".." + Num(r.hi, 1);
  }
  return text;
}

double RelativeErrorPct(double identified, double truth) {
  return std::isfinite(identified) && truth != 0.0 ? 100.0 * (identified - truth) / truth : kNaN;
}

// The clinician chain (docs/STUDY.md): per leg, the default rapid set predicting
// the default prediction protocols' fresh trials, its J, pole and τ_scale
// errors against the truth, its identified ranges and the routine's bench
// time; then medians and worst values, over all legs and per family.
Table BuildChainTable(const std::vector<LegData>& legs) {
  Table t{"clinician_chain",
          "Clinician chain: default rapid set -> default prediction protocols (E_RMS deg), "
          "rapid set vs truth (%), bench time",
          {"leg", "family", "draw_seed"},
          {},
          "Every protocol parameter at its default (prediction_random_binary seeds 3 and 4). "
          "Each leg runs its prediction protocols before the rapid routine, then the rapid set "
          "predicts those trials (POST /predictions). Errors vs truth: (identified - truth) / "
          "truth. identified_range_*: from the rapid set's provenance (n/a if not recorded). "
          "worst: largest E_RMS, largest |error|, longest bench time. A refused or failed run or "
          "prediction is n/a with its reason in notes."};
  for (const auto& in : kChainInputs) t.header.push_back(in.label + "_e_rms_deg");
  const std::vector<std::string> numeric_tail = {"j_error_pct", "pole_error_pct",
                                                 "tau_scale_error_pct"};
  for (const auto& h : numeric_tail) t.header.push_back(h);
  for (const std::string h :
       {"identified_range_deg", "identified_range_deg_s", "rapid_bench_s", "notes"})
    t.header.push_back(h);

  // Per leg the numeric columns, in header order (E_RMS…, J, pole, τ_scale, bench).
  const auto values = [](const LegData& leg) {
    std::vector<double> v;
    for (const auto& in : kChainInputs) v.push_back(ErrorOf(leg, "rapid", in.label));
    const auto p = leg.params.find("rapid");
    const model::ParameterSet* set = p == leg.params.end() ? nullptr : &p->second;
    const model::ParameterSet& truth = leg.subject.truth;
    v.push_back(set ? RelativeErrorPct(set->passive.inertia_kgm2, truth.passive.inertia_kgm2)
                    : kNaN);
    v.push_back(set ? RelativeErrorPct(set->contraction.pole_per_s, truth.contraction.pole_per_s)
                    : kNaN);
    // τ_scale at the max tolerated amplitude, τ_scale·R(u_max): a leg whose
    // recruitment plateaus below full activation (the plateau family) has a
    // true R(u_max) < 1, while an identified IRC reaches 1 at the top of
    // what was tested, so raw τ_scale values are not comparable; the
    // torque the set drives at the maximum is.
    const double u_max = leg.subject.max_tolerated_ma;
    v.push_back(set ? RelativeErrorPct(set->active.torque_scale_nm * set->irc(u_max),
                                       truth.active.torque_scale_nm * truth.irc(u_max))
                    : kNaN);
    const auto b = leg.bench_s.find(kRapid);
    v.push_back(b == leg.bench_s.end() ? kNaN : b->second);
    return v;
  };
  for (const auto& leg : legs) {
    const std::vector<double> v = values(leg);
    std::vector<std::string> row = {std::to_string(leg.index), leg.subject.family,
                                    std::to_string(leg.subject.draw_seed)};
    for (std::size_t i = 0; i + 1 < v.size(); ++i) row.push_back(Num(v[i], 3));
    row.push_back(RangeText(leg.rapid_provenance, &model::Provenance::identified_range_deg));
    row.push_back(RangeText(leg.rapid_provenance, &model::Provenance::identified_range_deg_s));
    row.push_back(Num(v.back(), 2));
    std::string notes;
    const auto note = [&](const std::string& text) { notes += (notes.empty() ? "" : "; ") + text; };
    for (const auto& in : kChainInputs) {
      if (auto f = leg.run_failures.find(in.trial); f != leg.run_failures.end()) {
        note(in.trial + " run: " + f->second);
      }
      if (auto f = leg.prediction_failures.find("rapid|" + in.label);
          f != leg.prediction_failures.end()) {
        note("rapid -> " + in.label + ": " + f->second);
      }
    }
    if (auto f = leg.run_failures.find(kRapid); f != leg.run_failures.end()) {
      note(std::string(kRapid) + " run: " + f->second);
    }
    row.push_back(notes);
    t.rows.push_back(row);
  }
  // Summary rows: all legs, then each family when there are several.
  std::vector<std::string> families;
  for (const auto& leg : legs)
    if (std::find(families.begin(), families.end(), leg.subject.family) == families.end())
      families.push_back(leg.subject.family);
  std::vector<std::string> groups = {"all"};
  if (families.size() > 1) groups.insert(groups.end(), families.begin(), families.end());
  for (const auto& group : groups) {
    std::vector<std::vector<double>> cols;
    int n = 0;
    for (const auto& leg : legs) {
      if (group != "all" && leg.subject.family != group) continue;
      ++n;
      const std::vector<double> v = values(leg);
      cols.resize(v.size());
      for (std::size_t i = 0; i < v.size(); ++i) cols[i].push_back(v[i]);
    }
    for (const std::string stat : {"median", "worst"}) {
      std::vector<std::string> row = {stat, group, std::to_string(n) + " legs"};
      for (std::size_t i = 0; i < cols.size(); ++i) {
        const double x = stat == "median" ? Median(cols[i]) : Worst(cols[i]);
        row.push_back(Num(x, i + 1 == cols.size() ? 2 : 3));
        if (i + 2 == cols.size()) row.insert(row.end(), {"", ""});  // the ranges
      }
      row.push_back("");
      t.rows.push_back(row);
    }
  }
  return t;
}

// 6.1 / 6.2: isometric prediction, scaled by its best-fit constant
// (§6.1.2), judged by Eq. 6.1 (normalised RMS), Eq. 6.2 (E_AVE) and the
// torque E_RMS (Eq. 6.9, N·m).
void IsometricTables(const std::vector<LegData>& legs, std::vector<Table>& out) {
  const std::vector<std::string> measures = {"isometric_normalised", "isometric_e_ave",
                                             "isometric"};
  Table t{"table_6_1_isometric_irc",
          "Table 6.1: isometric prediction, step IRC vs ramp-correlation IRC (paired t-test)",
          kTTestHeader,
          {},
          "3rd-order contraction dynamics for both; the prediction scaled by the best-fit "
          "constant (§6.1.2). Inputs: isometric_normalised = Eq. 6.1, isometric_e_ave = Eq. "
          "6.2, isometric = torque E_RMS (N.m)."};
  for (const auto& m : measures)
    t.rows.push_back(TTestRow(legs, m, "irc_step_o3", "irc_ramp_o3"));
  out.push_back(t);
  Table u{"table_6_2_isometric_order",
          "Table 6.2: isometric prediction, 2nd vs 3rd order contraction dynamics (paired "
          "t-test)",
          kTTestHeader,
          {},
          "Rows per IRC method and error measure, as Table 6.1."};
  for (const auto& m : measures) {
    u.rows.push_back(TTestRow(legs, m, "irc_ramp_o2", "irc_ramp_o3"));
    u.rows.push_back(TTestRow(legs, m, "irc_step_o2", "irc_step_o3"));
  }
  out.push_back(u);
}

// 6.3: inertia by method with the virtual truth.
void InertiaTable(const std::vector<LegData>& legs, std::vector<Table>& out) {
  // Sequential and rapid sets take J from the anthropometrics (Eq. 4.13,
  // §7.4.1), the thesis's "calculated" column; simultaneous (Eq. 4.31)
  // and free swing (Eq. 4.35) estimate it.
  Table t{"table_6_3_inertia",
          "Table 6.3: limb inertia by method (kg.m^2), with the virtual truth",
          {"leg", "anthropometric_eq_4_13", "simultaneous", "free_swing", "truth"},
          {},
          "anthropometric_eq_4_13: the inertia the sequential and rapid sets use, "
          "calculated from body mass and shank length (Eq. 4.13)."};
  const std::vector<std::string> keys = {"sequential_rb1", "simultaneous_rb1", "free_swing_rb1"};
  std::map<std::string, std::vector<double>> cols;
  for (const auto& leg : legs) {
    std::vector<std::string> row = {std::to_string(leg.index)};
    for (const auto& key : keys) {
      auto p = leg.params.find(key);
      const double j = p == leg.params.end() ? kNaN : p->second.passive.inertia_kgm2;
      cols[key].push_back(j);
      row.push_back(Num(j));
    }
    // typed-reads: not JSON (the table's column of true values)
    cols["truth"].push_back(leg.subject.truth.passive.inertia_kgm2);
    row.push_back(Num(leg.subject.truth.passive.inertia_kgm2));
    t.rows.push_back(row);
  }
  for (const std::string stat : {"mean", "sd"}) {
    std::vector<std::string> row = {stat};
    for (const std::string key :
         {"sequential_rb1", "simultaneous_rb1", "free_swing_rb1", "truth"})
      row.push_back(Num(stat == "mean" ? Mean(cols[key]) : Sd(cols[key])));
    t.rows.push_back(row);
  }
  out.push_back(t);
}

// 6.4: linearised ζ and ω_n (Table 6.4).
void LinearisedTable(const std::vector<LegData>& legs, std::vector<Table>& out) {
  Table t{"table_6_4_linearised",
          "Table 6.4: linearised passive dynamics about the rest angle (zeta, omega_n rad/s)",
          {"leg", "method", "rest_angle_deg", "zeta", "omega_n_rad_s"},
          {},
          ""};
  for (const auto& leg : legs) {
    std::vector<std::pair<std::string, const model::ParameterSet*>> sets;
    for (const std::string key :
         {"sequential_rb1", "simultaneous_rb1", "free_swing_rb1", "rapid"}) {
      auto p = leg.params.find(key);
      sets.emplace_back(key, p == leg.params.end() ? nullptr : &p->second);
    }
    sets.emplace_back("truth", &leg.subject.truth);
    for (const auto& [key, p] : sets) {
      std::vector<std::string> row = {std::to_string(leg.index), key};
      // §6.9, Table 6.4: linearised about the free-hanging rest angle; n/a
      // without a set, a rest angle, or a restoring stiffness there.
      std::vector<std::string> cells = {"n/a", "n/a", "n/a"};
      const std::optional<double> rest_deg =
          p != nullptr && !p->passive.torque_angle.empty() && !p->passive.torque_velocity.empty()
              ? model::FindPassiveRestAngle(p->passive)
              : std::nullopt;
      if (rest_deg) {
        // Refused (no restoring stiffness at the rest angle): not linearisable.
        if (const api::Result<model::PassiveLinearisation> lin =
                api::CallModel([&] { return model::LinearisePassive(p->passive, *rest_deg, 0.0); });
            lin.ok()) {
          cells = {Num(*rest_deg, 2), Num(lin->damping_ratio), Num(lin->natural_frequency_rad_s)};
        }
      }
      row.insert(row.end(), cells.begin(), cells.end());
      t.rows.push_back(row);
    }
  }
  out.push_back(t);
}

// 6.5–6.8: paired t-tests between parameter sets for each input.
void SetTTestTable(const std::vector<LegData>& legs, std::vector<Table>& out) {
  Table t{"table_6_5_6_8_ttests",
          "Tables 6.5-6.8: paired t-tests of free-swing prediction E_RMS (deg) between parameter "
          "sets, per input",
          kTTestHeader,
          {},
          "Positive mean_diff: set_a has more error. significant: |t| > t_crit (95 %)."};
  for (const auto& input : kInputs) {
    for (const auto& train : kTrains) {
      t.rows.push_back(TTestRow(legs, input.label, SetKey("sequential", train),
                                SetKey("simultaneous", train)));
      t.rows.push_back(TTestRow(legs, input.label, SetKey("simultaneous", train),
                                SetKey("free_swing", train)));
      t.rows.push_back(
          TTestRow(legs, input.label, SetKey("sequential", train), SetKey("free_swing", train)));
    }
    for (const auto& p : kPassiveMethods)
      t.rows.push_back(TTestRow(legs, input.label, SetKey(p, "rb1"), SetKey(p, "rb2")));
    t.rows.push_back(TTestRow(legs, input.label, "rapid", "free_swing_rb1"));
  }
  out.push_back(t);
}

// 6.9: full vs simplified.
void SimplifiedTable(const std::vector<LegData>& legs, std::vector<Table>& out) {
  Table t{"table_6_9_simplified",
          "Table 6.9: full model vs simplified models (free swing passive, RB1), E_RMS deg",
          kTTestHeader,
          {},
          ""};
  for (const auto& input : kInputs)
    for (const auto& m : kSimplified)
      t.rows.push_back(TTestRow(legs, input.label, m, "free_swing_rb1"));
  out.push_back(t);
}

// Appendices J, K: per-leg errors.
void ErrorTables(const std::vector<LegData>& legs, std::vector<Table>& out) {
  Table t{"appendix_jk_per_leg_errors",
          "Appendices J and K: per-leg prediction errors (E_RMS and E_ABS, deg; isometric N.m)",
          {"leg", "set", "input", "e_rms", "e_abs"},
          {},
          ""};
  for (const auto& leg : legs)
    for (const auto& [key, inputs] : leg.errors)
      for (const auto& [input, e] : inputs)
        t.rows.push_back({std::to_string(leg.index), key, input, Num(e.first), Num(e.second)});
  out.push_back(t);
  std::vector<std::string> keys = {"rapid"};
  for (const auto& p : kPassiveMethods)
    for (const auto& tr : kTrains) keys.push_back(SetKey(p, tr));
  for (const auto& s : kSimplified) keys.push_back(s);
  // One row per set, one column per input: `stat` of its E_RMS over the legs.
  const auto by_set = [&](Table table, double (*stat)(std::vector<double>)) {
    for (const auto& input : kInputs) table.header.push_back(input.label);
    for (const auto& key : keys) {
      std::vector<std::string> row = {key};
      for (const auto& input : kInputs) {
        std::vector<double> v;
        for (const auto& leg : legs) v.push_back(ErrorOf(leg, key, input.label));
        row.push_back(Num(stat(std::move(v)), 3));
      }
      table.rows.push_back(row);
    }
    out.push_back(std::move(table));
  };
  by_set({"mean_errors", "Mean E_RMS (deg) by parameter set and input over the cohort", {"set"},
          {}, ""},
         [](std::vector<double> v) { return Mean(v); });
  // Medians: a few poorly identified sets (a knee predicted to sit on a
  // stop for seconds) weigh heavily in the means.
  by_set({"median_errors", "Median E_RMS (deg) by parameter set and input over the cohort",
          {"set"}, {}, "The median is robust to the few predictions that fail badly."},
         [](std::vector<double> v) { return Median(std::move(v)); });
}

// §7.4.1 bench time per parameterisation.
void BenchTimeTable(const std::vector<LegData>& legs, std::vector<Table>& out) {
  Table t{"bench_time",
          "Bench time per parameterisation (s of bench time), §7.4.1",
          {"leg", "rapid_s", "traditional_s (step IRC + sequential passive)"},
          {},
          "Thesis: rapid < 30 s vs traditional 12.5 min (750 s)."};
  std::vector<double> rapid, traditional;
  for (const auto& leg : legs) {
    auto at = [&](const std::string& p) {
      auto it = leg.bench_s.find(p);
      return it == leg.bench_s.end() ? kNaN : it->second;
    };
    const double r = at("rapid_parameterisation");
    const double tr = at("isometric_step_irc") + at("passive_sequential");
    rapid.push_back(r);
    traditional.push_back(tr);
    t.rows.push_back({std::to_string(leg.index), Num(r, 2), Num(tr, 2)});
  }
  t.rows.push_back({"mean", Num(Mean(rapid), 2), Num(Mean(traditional), 2)});
  out.push_back(t);
}

}  // namespace

std::vector<Table> BuildTables(const std::vector<LegData>& legs) {
  std::vector<Table> tables;
  tables.push_back(BuildChainTable(legs));
  IsometricTables(legs, tables);
  InertiaTable(legs, tables);
  LinearisedTable(legs, tables);
  SetTTestTable(legs, tables);
  SimplifiedTable(legs, tables);
  ErrorTables(legs, tables);
  BenchTimeTable(legs, tables);
  return tables;
}

}  // namespace fesbench::cli::study
