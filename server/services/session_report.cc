#include "server/services/session_report.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <set>

#include "api/model_call.h"
#include "api/trial.h"
#include "model/joint_model.h"
#include "storage/parameter_sets.h"
#include "storage/predictions.h"
#include "storage/sessions.h"
#include "api/time_utc.h"
#include "storage/trials.h"

namespace fesbench::server::services {
namespace {

using nlohmann::json;

// What a prediction's errors compare, in words.
std::string QuantityName(const std::string& channel) {
  if (channel == "angle_deg") return "knee angle";
  if (channel == "torque_nm") return "torque";
  return HtmlEscape(channel);
}

std::string Fixed(double v, int digits) {
  if (!std::isfinite(v)) return "—";
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, "%.*f", digits, v);
  return buffer;
}

std::string Text(const json& j, const char* key) {
  if (!j.is_object() || !j.contains(key) || j[key].is_null()) return "—";
  const json& v = j[key];
  if (v.is_string()) return HtmlEscape(v.get<std::string>());
  if (v.is_number_integer()) return std::to_string(v.get<std::int64_t>());
  if (v.is_number()) return Fixed(v.get<double>(), 2);
  return HtmlEscape(v.dump());
}

// --- SVG plots -----------------------------------------------------------------

struct Series {
  std::string label;
  std::string color;
  std::vector<double> x;
  std::vector<double> y;
  bool dashed = false;
};

struct PlotSpec {
  std::string title;
  std::string x_label;
  std::string y_label;
  std::vector<Series> series;
  std::optional<std::pair<double, double>> shaded;  ///< x range drawn as "identified".
};

// A "nice" tick step for a span (1, 2 or 5 × 10^k).
double TickStep(double span) {
  if (!(span > 0.0)) return 1.0;
  const double raw = span / 5.0;
  const double magnitude = std::pow(10.0, std::floor(std::log10(raw)));
  const double r = raw / magnitude;
  return (r < 1.5 ? 1.0 : r < 3.5 ? 2.0 : r < 7.5 ? 5.0 : 10.0) * magnitude;
}

std::string Svg(const PlotSpec& p) {
  constexpr double kW = 640, kH = 250, kLeft = 58, kRight = 14, kTop = 28, kBottom = 42;
  double x0 = INFINITY, x1 = -INFINITY, y0 = INFINITY, y1 = -INFINITY;
  for (const Series& s : p.series) {
    for (std::size_t i = 0; i < s.x.size() && i < s.y.size(); ++i) {
      if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i])) continue;
      x0 = std::min(x0, s.x[i]);
      x1 = std::max(x1, s.x[i]);
      y0 = std::min(y0, s.y[i]);
      y1 = std::max(y1, s.y[i]);
    }
  }
  std::string out =
      "<figure class=\"plot\"><svg xmlns=\"http://www.w3.org/2000/svg\" viewBox=\"0 0 " +
      Fixed(kW, 0) + " " + Fixed(kH, 0) + "\" role=\"img\" aria-label=\"" + HtmlEscape(p.title) +
      "\">";
  out += "<text x=\"" + Fixed(kW / 2, 0) + "\" y=\"17\" class=\"t\">" + HtmlEscape(p.title) +
         "</text>";
  if (!std::isfinite(x0)) {
    out += "<text x=\"" + Fixed(kW / 2, 0) + "\" y=\"" + Fixed(kH / 2, 0) +
           "\" class=\"t\">no data</text></svg></figure>";
    return out;
  }
  if (y1 - y0 < 1e-9) {
    y0 -= 1.0;
    y1 += 1.0;
  }
  if (x1 - x0 < 1e-12) x1 = x0 + 1.0;
  const double pad = 0.05 * (y1 - y0);
  y0 -= pad;
  y1 += pad;
  auto sx = [&](double x) { return kLeft + (x - x0) / (x1 - x0) * (kW - kLeft - kRight); };
  auto sy = [&](double y) { return kTop + (y1 - y) / (y1 - y0) * (kH - kTop - kBottom); };
  if (p.shaded) {
    const double a = std::clamp(p.shaded->first, x0, x1), b = std::clamp(p.shaded->second, x0, x1);
    if (b > a) {
      out += "<rect x=\"" + Fixed(sx(a), 1) + "\" y=\"" + Fixed(kTop, 1) + "\" width=\"" +
             Fixed(sx(b) - sx(a), 1) + "\" height=\"" + Fixed(kH - kTop - kBottom, 1) +
             "\" class=\"range\"><title>identified range</title></rect>";
    }
  }
  // Axes and ticks.
  out += "<rect x=\"" + Fixed(kLeft, 1) + "\" y=\"" + Fixed(kTop, 1) + "\" width=\"" +
         Fixed(kW - kLeft - kRight, 1) + "\" height=\"" + Fixed(kH - kTop - kBottom, 1) +
         "\" class=\"frame\"/>";
  const double xs = TickStep(x1 - x0), ys = TickStep(y1 - y0);
  for (double t = std::ceil(x0 / xs) * xs; t <= x1 + 1e-9 * xs; t += xs) {
    out += "<line x1=\"" + Fixed(sx(t), 1) + "\" x2=\"" + Fixed(sx(t), 1) + "\" y1=\"" +
           Fixed(kTop, 1) + "\" y2=\"" + Fixed(kH - kBottom, 1) + "\" class=\"grid\"/>";
    out += "<text x=\"" + Fixed(sx(t), 1) + "\" y=\"" + Fixed(kH - kBottom + 14, 1) +
           "\" class=\"tick\">" + Fixed(std::abs(t) < 1e-12 ? 0.0 : t, xs < 1 ? 2 : 0) + "</text>";
  }
  for (double t = std::ceil(y0 / ys) * ys; t <= y1 + 1e-9 * ys; t += ys) {
    out += "<line x1=\"" + Fixed(kLeft, 1) + "\" x2=\"" + Fixed(kW - kRight, 1) + "\" y1=\"" +
           Fixed(sy(t), 1) + "\" y2=\"" + Fixed(sy(t), 1) + "\" class=\"grid\"/>";
    out += "<text x=\"" + Fixed(kLeft - 5, 1) + "\" y=\"" + Fixed(sy(t) + 4, 1) +
           "\" class=\"ytick\">" + Fixed(std::abs(t) < 1e-12 ? 0.0 : t, ys < 1 ? 2 : 0) + "</text>";
  }
  out += "<text x=\"" + Fixed((kLeft + kW - kRight) / 2, 0) + "\" y=\"" + Fixed(kH - 6, 0) +
         "\" class=\"t\">" + HtmlEscape(p.x_label) + "</text>";
  out += "<text transform=\"translate(13 " + Fixed((kTop + kH - kBottom) / 2, 0) +
         ") rotate(-90)\" class=\"t\">" + HtmlEscape(p.y_label) + "</text>";
  // Lines (at most ~800 points each).
  for (const Series& s : p.series) {
    const std::size_t n = std::min(s.x.size(), s.y.size());
    const std::size_t stride = std::max<std::size_t>(1, n / 800);
    std::string points;
    for (std::size_t i = 0; i < n; i += stride) {
      if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i])) continue;
      points += Fixed(sx(s.x[i]), 1) + "," + Fixed(sy(s.y[i]), 1) + " ";
    }
    out += "<polyline fill=\"none\" stroke=\"" + s.color + "\" stroke-width=\"1.6\"" +
           (s.dashed ? " stroke-dasharray=\"5 3\"" : "") + " points=\"" + points + "\"/>";
  }
  out += "</svg><figcaption>";
  for (const Series& s : p.series) {
    out += "<span class=\"key\"><span class=\"swatch\" style=\"background:" + s.color +
           "\"></span>" + HtmlEscape(s.label) + "</span> ";
  }
  if (p.shaded)
    out += "<span class=\"key\"><span class=\"swatch range\"></span>identified range</span>";
  out += "</figcaption></figure>";
  return out;
}

std::optional<std::pair<double, double>> RangeOf(
    const std::map<std::string, model::CurveRange>& ranges, const char* key) {
  const auto it = ranges.find(key);
  if (it == ranges.end()) return std::nullopt;
  return std::pair{it->second.lo, it->second.hi};
}

std::string CurvePlots(const model::ParameterSet& params) {
  std::string out = "<div class=\"plots\">";
  PlotSpec irc{"Recruitment curve (IRC, §4.1)", "stimulation (mA)", "activation", {}, {}};
  irc.series.push_back({"R(u)", "#1f5fbf", params.irc.x(), params.irc.y()});
  out += Svg(irc);
  api::Result<std::string> curves = api::CallModel([&] {
    std::string svg;
    const model::JointModel joint = model::JointModel::FromParameters(params);
    std::vector<double> angle, pta, ata, velocity, ptv, atv;
    for (int a = 0; a <= 130; ++a) {
      angle.push_back(a);
      pta.push_back(joint.PassiveAngleTorque(a));
      ata.push_back(joint.AngleGain(a));
    }
    for (int v = -400; v <= 400; v += 5) {
      velocity.push_back(v);
      ptv.push_back(joint.PassiveVelocityTorque(v));
      atv.push_back(joint.VelocityGain(v));
    }
    const model::Provenance& p = params.provenance;
    svg += Svg({"Passive torque–angle τ_pta (§4.2)",
                "knee angle (deg)",
                "N·m",
                {{"τ_pta", "#b03a2e", angle, pta}},
                RangeOf(p.identified_range_deg, "tau_pta")});
    svg += Svg({"Active torque–angle f_ata (§4.3)",
                "knee angle (deg)",
                "gain",
                {{"f_ata", "#1e8449", angle, ata}},
                RangeOf(p.identified_range_deg, "f_ata")});
    svg += Svg({"Passive torque–velocity τ_ptv",
                "knee velocity (deg/s)",
                "N·m",
                {{"τ_ptv", "#b03a2e", velocity, ptv}},
                RangeOf(p.identified_range_deg_s, "tau_ptv")});
    svg += Svg({"Active torque–velocity f_atv",
                "knee velocity (deg/s)",
                "gain",
                {{"f_atv", "#1e8449", velocity, atv}},
                RangeOf(p.identified_range_deg_s, "f_atv")});
    return svg;
  });
  out += curves.ok() ? *curves
                     : "<p class=\"warn\">The curves cannot be drawn: " +
                           HtmlEscape(curves.status().message()) + "</p>";
  // Twitch: the contraction dynamics' impulse response t^(n−1)·e^(−a·t), peak 1 (§4.1.3).
  const int n = params.contraction.order;
  const double a = params.contraction.pole_per_s;
  std::vector<double> t, h;
  const double peak_t = (n - 1) / a;
  const double peak = std::pow(peak_t, n - 1) * std::exp(-a * peak_t);
  for (int i = 0; i <= 200; ++i) {
    const double ti = 0.5 * i / 200.0;
    t.push_back(ti);
    h.push_back(peak > 0 ? std::pow(ti, n - 1) * std::exp(-a * ti) / peak : 0.0);
  }
  out += Svg({"Twitch (contraction dynamics, order " + std::to_string(n) + ", pole " + Fixed(a, 1) +
                  " s⁻¹)",
              "time after the pulse (s)",
              "normalised torque",
              {{"twitch", "#7d3c98", t, h}},
              {}});
  return out + "</div>";
}

const char* kStyle = R"css(
body{font:14px/1.45 system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;color:#1b1f24;margin:24px auto;max-width:980px;padding:0 16px}
h1{font-size:22px;margin:0 0 4px}h2{font-size:18px;margin:28px 0 8px;border-bottom:2px solid #d0d7de;padding-bottom:4px}
h3{font-size:15px;margin:18px 0 6px}.meta{color:#57606a;margin:0 0 16px}
table{border-collapse:collapse;margin:6px 0 12px;width:100%}th,td{border:1px solid #d0d7de;padding:4px 8px;text-align:left;vertical-align:top}
th{background:#f0f3f6}td.n{text-align:right;font-variant-numeric:tabular-nums}
.plots{display:grid;grid-template-columns:1fr 1fr;gap:10px}.plot{margin:0;border:1px solid #d0d7de;border-radius:4px;padding:4px}
svg{width:100%;height:auto;display:block}svg text{font-size:11px;fill:#1b1f24}svg .t{text-anchor:middle;font-size:12px}
svg .tick{text-anchor:middle}svg .ytick{text-anchor:end}svg .grid{stroke:#e6e9ec;stroke-width:1}svg .frame{fill:none;stroke:#8c959f}
svg .range{fill:#fff3bf}figcaption{font-size:12px;color:#57606a;padding:2px 6px}.key{margin-right:12px;white-space:nowrap}
.swatch{display:inline-block;width:14px;height:4px;margin-right:4px;vertical-align:middle}.swatch.range{height:10px;background:#fff3bf;border:1px solid #e3c95f}
.warn{background:#fff8e1;border-left:4px solid #e3a008;padding:6px 10px;margin:6px 0}.stop{background:#fdecea;border-left:4px solid #c0392b;padding:6px 10px;margin:6px 0}
.none{color:#57606a;font-style:italic}.ok{color:#1e8449}
@media print{@page{size:A4;margin:14mm}body{margin:0;max-width:none;font-size:11px}section{break-inside:avoid-page}
section.break{break-before:page}.plots{grid-template-columns:1fr 1fr}h2{margin-top:12px}}
)css";

// What a run gave, in a clinician's words and units (as the web page's runs
// table): the set it made or used, the tolerance test's values, the
// tracking error, the daily check's verdict.
std::string Outcome(const json& r) {
  std::vector<std::string> parts;
  const auto number = [](const json& j, const char* key) -> std::optional<double> {
    if (j.is_object() && j.contains(key) && j[key].is_number()) return j[key].get<double>();
    return std::nullopt;
  };
  if (r.contains("parameter_set_id") && r["parameter_set_id"].is_number_integer()) {
    parts.push_back("parameter set " + std::to_string(r["parameter_set_id"].get<std::int64_t>()));
  }
  const json result = r.value("result", json::object());
  if (result.is_object() && result.contains("max_tolerated_ma")) {
    const auto thr = number(result, "threshold_ma");
    const auto max = number(result, "max_tolerated_ma");
    parts.push_back(max ? "threshold " + (thr ? Fixed(*thr, 1) : std::string("—")) +
                              " mA, max tolerated " + Fixed(*max, 1) + " mA"
                        : std::string("no max tolerated recorded"));
  }
  if (const auto rms = number(r.value("values", json::object()), "tracking_rms_deg")) {
    parts.push_back("tracking error " + Fixed(*rms, 1) + "° RMS");
  }
  if (result.is_object() && result.contains("verdict") && result["verdict"].is_string()) {
    std::string verdict = result["verdict"].get<std::string>();
    std::replace(verdict.begin(), verdict.end(), '_', ' ');
    parts.push_back("daily check: " + HtmlEscape(verdict));
  }
  std::string out;
  for (const std::string& p : parts) out += (out.empty() ? "" : "; ") + p;
  return out.empty() ? "—" : out;
}

std::string RunsTable(const json& runs) {
  if (!runs.is_array() || runs.empty()) return "<p class=\"none\">No runs in this session.</p>";
  std::string out =
      "<table id=\"runs\"><thead><tr><th>Run</th><th>Protocol</th><th>State</th><th>Reason</th>"
      "<th>Started (UTC)</th><th>Finished (UTC)</th><th>Outcome</th><th>Trials</th>"
      "<th>Safety events</th>"
      "</tr></thead><tbody>";
  for (const json& r : runs) {
    std::string safety;
    if (r.contains("safety_events") && r["safety_events"].is_array()) {
      std::map<std::string, int> counts;
      for (const json& e : r["safety_events"]) counts[e.value("kind", std::string("event"))]++;
      for (const auto& [kind, count] : counts) {
        safety += (safety.empty() ? "" : ", ") + HtmlEscape(kind) + " × " + std::to_string(count);
      }
    }
    out += "<tr><td class=\"n\">" + Text(r, "run_id") + "</td><td>" + Text(r, "protocol") +
           "</td><td>" + Text(r, "state") + "</td><td>" + Text(r, "reason") + "</td><td>" +
           Text(r, "started_at_utc") + "</td><td>" + Text(r, "finished_at_utc") + "</td><td>" +
           Outcome(r) + "</td><td class=\"n\">" +
           std::to_string(r.contains("trial_ids") ? r["trial_ids"].size() : 0) + "</td><td>" +
           (safety.empty() ? "none" : safety) + "</td></tr>";
  }
  return out + "</tbody></table>";
}

std::string TrialsTable(const json& trials) {
  if (!trials.is_array() || trials.empty()) {
    return "<p class=\"none\">No trials recorded in this session.</p>";
  }
  std::string out =
      "<table id=\"trials\"><thead><tr><th>Trial</th><th>Kind</th><th>Run</th><th>Samples</th>"
      "<th>Rate (Hz)</th><th>Recorded (UTC)</th></tr></thead><tbody>";
  for (const json& t : trials) {
    out += "<tr><td class=\"n\">" + Text(t, "id") + "</td><td>" + Text(t, "name") +
           "</td><td class=\"n\">" + Text(t, "run_id") + "</td><td class=\"n\">" +
           Text(t, "num_samples") + "</td><td class=\"n\">" + Text(t, "sample_rate_hz") +
           "</td><td>" + Text(t, "created_at_utc") + "</td></tr>";
  }
  return out + "</tbody></table>";
}

std::string SetSection(const ReportSet& set) {
  const model::ParameterSet& p = set.params;
  std::string out = "<section class=\"break\" id=\"set-" + std::to_string(set.id) +
                    "\"><h2>Parameter set " + std::to_string(set.id) + " (version " +
                    std::to_string(set.version) + ")</h2>";
  out += "<table class=\"params\"><tbody>";
  auto row = [&](const std::string& name, const std::string& value) {
    out += "<tr><th>" + name + "</th><td>" + value + "</td></tr>";
  };
  row("Model", HtmlEscape(model::ModelKindName(p.model)));
  row("Created (UTC)", HtmlEscape(set.created_at_utc));
  row("Methods", "IRC " + HtmlEscape(p.provenance.irc_method) + "; passive " +
                     HtmlEscape(p.provenance.passive_method) + "; active " +
                     HtmlEscape(p.provenance.active_method) + "; J " +
                     HtmlEscape(p.provenance.inertia_method));
  row("Inertia J", Fixed(p.passive.inertia_kgm2, 4) + " kg·m²");
  row("Active gain τ_scale", Fixed(p.active.torque_scale_nm, 2) + " N·m");
  row("Contraction", "order " + std::to_string(p.contraction.order) + ", pole " +
                         Fixed(p.contraction.pole_per_s, 2) + " s⁻¹");
  std::string trials;
  for (std::int64_t id : p.provenance.trial_ids) {
    trials += (trials.empty() ? "" : ", ") + std::to_string(id);
  }
  row("Fitted on trials", trials.empty() ? "—" : trials);
  std::string fits;
  for (const auto& [part, rms] : p.provenance.fit_rms) {
    fits += (fits.empty() ? "" : "; ") + HtmlEscape(part) + " " + Fixed(rms, 3);
  }
  row("Fit RMS", fits.empty() ? "—" : fits);
  out += "</tbody></table>";
  out += CurvePlots(p);

  out += "<h3>Predictions on fresh trials</h3>";
  std::vector<const ReportPrediction*> fresh;
  for (const ReportPrediction& r : set.predictions) {
    if (r.fresh) fresh.push_back(&r);
  }
  if (fresh.empty()) {
    out +=
        "<p class=\"none\">No prediction on a trial this set was not fitted on yet (the "
        "web page's Prediction, or `fesbench predict --params " +
        std::to_string(set.id) + "`).</p>";
  } else {
    // Each error in the unit of what it compares (the knee angle of a free
    // swing, the torque of an isometric trial).
    out +=
        "<table class=\"predictions\"><thead><tr><th>Prediction</th><th>Trial</th>"
        "<th>Compared</th><th>E_RMS</th><th>E_ABS</th><th>Outside identified ranges</th></tr>"
        "</thead><tbody>";
    for (const ReportPrediction* r : fresh) {
      const std::string unit = " " + HtmlEscape(r->unit);
      out += "<tr><td class=\"n\">" + std::to_string(r->prediction_id) + "</td><td>" +
             std::to_string(r->trial_id) + " " + HtmlEscape(r->trial_name) + "</td><td>" +
             QuantityName(r->channel) + "</td><td class=\"n\">" +
             (r->e_rms ? Fixed(*r->e_rms, 2) + unit : "—") + "</td><td class=\"n\">" +
             (r->e_abs ? Fixed(*r->e_abs, 2) + unit : "—") + "</td><td class=\"n\">" +
             (r->share_outside ? Fixed(100.0 * *r->share_outside, 0) + " %" : "—") + "</td></tr>";
    }
    out += "</tbody></table><div class=\"plots\">";
    for (std::size_t k = 0; k < fresh.size() && k < 4; ++k) {
      const ReportPrediction& r = *fresh[k];
      out += Svg({"Trial " + std::to_string(r.trial_id) + " (" + r.trial_name +
                      "): " + QuantityName(r.channel),
                  "time (s)",
                  r.unit,
                  {{"measured", "#1b1f24", r.t_s, r.measured},
                   {"predicted", "#1f5fbf", r.t_s, r.predicted, true}},
                  {}});
    }
    out += "</div>";
  }
  return out + "</section>";
}

std::vector<std::string> Warnings(const SessionReport& r) {
  std::vector<std::string> out;
  for (const ReportSet& set : r.sets) {
    for (const std::string& w : set.params.provenance.warnings) {
      out.push_back("Set " + std::to_string(set.id) + ": " + w);
    }
    for (const ReportPrediction& p : set.predictions) {
      if (p.fresh && p.share_outside && *p.share_outside > 0.2) {
        out.push_back("Set " + std::to_string(set.id) + " on trial " + std::to_string(p.trial_id) +
                      ": " + Fixed(100.0 * *p.share_outside, 0) +
                      " % of the prediction lies outside the ranges the curves were identified "
                      "over (extrapolated)");
      }
    }
    if (set.params.provenance.identified_range_deg.empty()) {
      out.push_back("Set " + std::to_string(set.id) +
                    ": no identified ranges recorded (coverage unknown)");
    }
  }
  if (!r.sets_from_session && !r.sets.empty()) {
    out.push_back(r.shown_set_approved
                      ? "No parameter set was identified from this session's trials; the leg's "
                        "approved set is shown"
                      : "No parameter set was identified from this session's trials and none is "
                        "approved for the leg; the leg's newest set is shown");
  }
  return out;
}

}  // namespace

std::string HtmlEscape(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&#39;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

api::Result<SessionReport> GatherSessionReport(storage::Database& db, std::int64_t session_id,
                                               SessionReport report) {
  auto session = storage::SessionRepository(db).Get(session_id);
  if (!session.ok()) return session.status();
  storage::ParameterSetRepository sets(db);
  auto ids = sets.IdsForSession(session_id);
  if (!ids.ok()) return ids.status();
  std::vector<std::int64_t> set_ids = *ids;
  if (set_ids.empty()) {
    report.sets_from_session = false;
    // The leg's approved set, the one that drives stimulation; the newest
    // only when none is approved.
    auto approved = sets.Approved(session->leg_id);
    if (approved.ok()) {
      set_ids.push_back(approved->summary.id);
      report.shown_set_approved = true;
    } else {
      auto latest = sets.Latest(session->subject_id, session->leg_id);
      if (latest.ok()) set_ids.push_back(latest->summary.id);
    }
  }
  storage::TrialRepository trials(db);
  storage::PredictionRepository predictions(db);
  for (std::int64_t id : set_ids) {
    auto stored = sets.Get(id);
    if (!stored.ok()) return stored.status();
    ReportSet set{id,
                  stored->summary.version,
                  api::FormatUtc(stored->summary.created_at),
                  stored->params,
                  {}};
    const std::set<std::int64_t> fitted(stored->trial_ids.begin(), stored->trial_ids.end());
    auto stored_predictions = predictions.PredictionsFor(id);
    if (!stored_predictions.ok()) return stored_predictions.status();
    for (const storage::Prediction& p : *stored_predictions) {
      if (!p.prediction.trial_id) continue;
      auto owner = trials.Owner(*p.prediction.trial_id);
      if (!owner.ok() || owner->session_id != session_id) continue;
      const json out = json::parse(p.prediction.output_json, nullptr, false);
      if (out.is_discarded()) continue;
      ReportPrediction r;
      r.prediction_id = p.id;
      r.trial_id = *p.prediction.trial_id;
      r.fresh = !fitted.contains(r.trial_id);
      if (out.contains("errors") && out["errors"].is_object()) {
        const json& e = out["errors"];
        if (e.contains("e_rms") && e["e_rms"].is_number()) r.e_rms = e["e_rms"].get<double>();
        if (e.contains("e_abs") && e["e_abs"].is_number()) r.e_abs = e["e_abs"].get<double>();
        if (e.contains("channel") && e["channel"].is_string()) r.channel = e["channel"];
        if (e.contains("unit") && e["unit"].is_string()) r.unit = e["unit"];
      }
      if (out.contains("share_outside_identified_ranges") &&
          out["share_outside_identified_ranges"].is_number()) {
        r.share_outside = out["share_outside_identified_ranges"].get<double>();
      }
      auto trial = trials.Get(r.trial_id);
      if (!trial.ok()) return trial.status();
      r.trial_name = trial->name.value_or("");
      if (const auto* t = trial->Values("t_s"); t != nullptr) r.t_s = *t;
      if (const auto* a = trial->Values(r.channel); a != nullptr) r.measured = *a;
      if (out.contains("columns") && out["columns"].contains(r.channel)) {
        for (const json& v : out["columns"][r.channel]) {
          r.predicted.push_back(v.is_number() ? v.get<double>() : NAN);
        }
      }
      if (r.predicted.size() != r.t_s.size()) r.predicted.resize(r.t_s.size(), NAN);
      // Each trial once: its newest prediction by this set (they come in
      // id order; an earlier one of the same trial is replaced).
      auto same = std::find_if(set.predictions.begin(), set.predictions.end(),
                               [&](const ReportPrediction& x) { return x.trial_id == r.trial_id; });
      if (same != set.predictions.end()) {
        *same = std::move(r);
      } else {
        set.predictions.push_back(std::move(r));
      }
    }
    report.sets.push_back(std::move(set));
  }
  return report;
}

std::string RenderSessionReport(const SessionReport& r) {
  const json& details = r.session.value("details", json::object());
  const json& subject_details = r.subject.value("details", json::object());
  const std::string code = Text(r.subject, "code");
  std::string out =
      "<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\"><title>"
      "fesbench session " +
      Text(r.session, "id") + " — " + code +
      "</title><meta name=\"viewport\" content=\"width=device-width\"><style>" + kStyle +
      "</style></head><body>";
  out += "<header><h1>Session " + Text(r.session, "id") + " — subject " + code + ", " +
         Text(r.session, "leg") + " leg, " + Text(r.session, "date") + "</h1>";
  out += "<p class=\"meta\">fesbench " + HtmlEscape(r.software_version) + " · report generated " +
         HtmlEscape(r.generated_at_utc) +
         " · subject identified by pseudonymous code only</p></header>";

  out += "<section id=\"session\"><h2>Subject and session</h2><table><tbody>";
  out += "<tr><th>Subject</th><td>" + code + " (age " + Text(subject_details, "age_years") +
         ", sex " + Text(subject_details, "sex") + ", height " +
         Text(subject_details, "height_cm") + " cm, weight " + Text(subject_details, "weight_kg") +
         " kg, shank " + Text(subject_details, "shank_length_cm") + " cm)</td></tr>";
  out += "<tr><th>Stimulation threshold</th><td>" + Text(details, "threshold_ma") + " mA</td></tr>";
  out += "<tr><th>Maximum tolerated</th><td>" + Text(details, "max_tolerated_ma") + " mA</td></tr>";
  out += "<tr><th>Accelerometer placement</th><td>" + Text(details, "accelerometer_placement") +
         "</td></tr>";
  out += "<tr><th>Notes</th><td>" + Text(details, "notes") + "</td></tr>";
  out += "<tr><th>Revision</th><td>" + Text(r.session, "revision") + "</td></tr>";
  out += "</tbody></table></section>";

  out += "<section id=\"runs-section\"><h2>Runs and their outcomes</h2>" + RunsTable(r.runs);
  std::vector<std::string> stops;
  if (r.runs.is_array()) {
    for (const json& run : r.runs) {
      const std::string reason = run.value("reason", std::string());
      if (reason.find("e-stop") != std::string::npos) {
        stops.push_back("Run " + std::to_string(run.value("run_id", 0)) + " (" +
                        run.value("protocol", std::string()) + "): " + reason);
      }
    }
  }
  out += "<h3>E-stops</h3>";
  if (stops.empty()) {
    out += "<p class=\"ok\">No e-stop during this session's runs.</p>";
  } else {
    for (const std::string& s : stops) out += "<p class=\"stop\">" + HtmlEscape(s) + "</p>";
  }
  out += "</section>";

  out += "<section id=\"trials-section\"><h2>Trials</h2>" + TrialsTable(r.trials) + "</section>";

  out += "<section id=\"warnings\"><h2>Warnings</h2>";
  const std::vector<std::string> warnings = Warnings(r);
  if (warnings.empty()) {
    out += "<p class=\"ok\">None.</p>";
  } else {
    for (const std::string& w : warnings) out += "<p class=\"warn\">" + HtmlEscape(w) + "</p>";
  }
  out += "</section>";

  if (r.sets.empty()) {
    out +=
        "<section id=\"sets\"><h2>Parameter sets</h2><p class=\"none\">No parameter set for "
        "this leg yet (run the rapid routine, or POST /identifications).</p></section>";
  }
  for (const ReportSet& set : r.sets) out += SetSection(set);
  out += "</body></html>\n";
  return out;
}

}  // namespace fesbench::server::services
