// The session report's renderer (docs/API.md): every section, stored text
// escaped, self-contained (no script, no external resource), well-formed
// SVG plots, e-stops and clamps and warnings shown, absent data said.

#include "server/services/session_report.h"

#include <gtest/gtest.h>

#include <regex>
#include <string>

namespace fesbench::server::services {
namespace {

using nlohmann::json;

std::size_t Count(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (std::size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

model::ParameterSet Set() {
  model::ParameterSet p;
  p.irc = model::PiecewiseLinear({0.0, 15.0, 40.0}, {0.0, 0.0, 1.0});
  p.passive.torque_angle = model::PiecewiseLinear({0.0, 130.0}, {-10.0, 12.0});
  p.passive.torque_velocity = model::PiecewiseLinear({-400.0, 400.0}, {-2.0, 2.0});
  p.active.torque_angle = model::PiecewiseLinear({0.0, 90.0, 130.0}, {0.4, 1.0, 0.6});
  p.active.torque_velocity = model::PiecewiseLinear({-400.0, 0.0, 400.0}, {1.3, 1.0, 0.5});
  p.provenance.trial_ids = {2, 3};
  p.provenance.identified_range_deg["tau_pta"] = {20.0, 100.0};
  p.provenance.warnings = {"active: <7> samples skipped"};
  return p;
}

SessionReport Report() {
  SessionReport r;
  r.software_version = "0.1.0";
  r.generated_at_utc = "2026-11-25T10:00:00.000000Z";
  r.session = {{"id", 4},
               {"leg", "right"},
               {"date", "2026-11-25"},
               {"revision", 2},
               {"details",
                {{"threshold_ma", 15.0},
                 {"max_tolerated_ma", 40.0},
                 {"notes", "<script>alert('x')</script> & \"quoted\""}}}};
  r.subject = {{"code", "S-01"}, {"details", {{"age_years", 34}, {"sex", "female"}}}};
  r.runs = json::array({{{"run_id", 7},
                         {"protocol", "rapid_parameterisation"},
                         {"state", "done"},
                         {"reason", ""},
                         {"trial_ids", {2, 3}},
                         {"safety_events",
                          {{{"kind", "amplitude_clamped"}, {"requested", 50}, {"applied", 40}},
                           {{"kind", "amplitude_clamped"}, {"requested", 45}, {"applied", 40}}}}},
                        {{"run_id", 8},
                         {"protocol", "prediction_step"},
                         {"state", "aborted"},
                         {"reason", "e-stop: button on the web page"},
                         {"trial_ids", json::array()},
                         {"safety_events", json::array()}}});
  r.trials = json::array({{{"id", 2}, {"name", "rapid_free_swing_passive"}, {"num_samples", 360}},
                          {{"id", 9}, {"name", "prediction_step"}, {"num_samples", 4}}});
  ReportSet set{12, 1, "2026-11-25T09:00:00Z", Set(), {}};
  ReportPrediction fresh;
  fresh.prediction_id = 3;
  fresh.trial_id = 9;
  fresh.trial_name = "prediction_step";
  fresh.e_rms = 1.5;
  fresh.e_abs = 1.1;
  fresh.share_outside = 0.4;
  fresh.t_s = {0.0, 0.005, 0.01, 0.015};
  fresh.measured = {90.0, 89.0, 88.0, 87.5};
  fresh.predicted = {90.0, 89.5, 88.4, 87.0};
  set.predictions.push_back(fresh);
  // An isometric trial's prediction: torque, in N·m.
  ReportPrediction isometric = fresh;
  isometric.prediction_id = 4;
  isometric.trial_id = 10;
  isometric.trial_name = "prediction_isometric";
  isometric.channel = "torque_nm";
  isometric.unit = "N.m";
  isometric.e_rms = 2.25;
  isometric.measured = {0.0, 5.0, 10.0, 12.0};
  isometric.predicted = {0.0, 4.0, 11.0, 12.5};
  set.predictions.push_back(isometric);
  r.sets.push_back(set);
  return r;
}

TEST(SessionReportTest, EverySectionEscapedAndSelfContained) {
  const std::string html = RenderSessionReport(Report());
  EXPECT_EQ(html.rfind("<!DOCTYPE html>", 0), 0u);
  for (const char* id : {"id=\"session\"", "id=\"runs-section\"", "id=\"trials-section\"",
                         "id=\"warnings\"", "id=\"set-12\""}) {
    EXPECT_NE(html.find(id), std::string::npos) << id;
  }
  // Stored text is escaped; nothing runs, nothing is fetched.
  EXPECT_EQ(html.find("<script"), std::string::npos);
  EXPECT_NE(html.find("&lt;script&gt;alert(&#39;x&#39;)&lt;/script&gt; &amp; &quot;quoted&quot;"),
            std::string::npos);
  EXPECT_NE(html.find("active: &lt;7&gt; samples skipped"), std::string::npos);
  EXPECT_EQ(html.find("src="), std::string::npos);
  const std::regex external(R"((href|src)\s*=\s*"?https?:)");
  EXPECT_FALSE(std::regex_search(html, external));
  EXPECT_EQ(Count(html, "http://"), Count(html, "http://www.w3.org/2000/svg"));
  // Plots: five curves and the twitch, two predictions; each SVG closed.
  EXPECT_EQ(Count(html, "<svg"), 8u);
  EXPECT_EQ(Count(html, "<svg"), Count(html, "</svg>"));
  EXPECT_EQ(Count(html, "<polyline"), 10u);       // 6 curves + 2 × (measured + predicted)
  EXPECT_EQ(Count(html, "class=\"range\""), 1u);  // τ_pta's identified range only
  // Outcomes: the clamps counted, the e-stop named, the extrapolation warned.
  EXPECT_NE(html.find("amplitude_clamped × 2"), std::string::npos);
  EXPECT_NE(html.find("Run 8 (prediction_step): e-stop: button on the web page"),
            std::string::npos);
  EXPECT_NE(html.find("40 % of the prediction lies outside"), std::string::npos);
  // Errors in the unit of what they compare.
  EXPECT_NE(html.find("<td>knee angle</td><td class=\"n\">1.50 deg</td>"), std::string::npos);
  EXPECT_NE(html.find("<td>torque</td><td class=\"n\">2.25 N.m</td>"), std::string::npos);
  EXPECT_EQ(html.find("E_RMS (deg)"), std::string::npos);
  EXPECT_NE(html.find("(prediction_isometric): torque"), std::string::npos);
  // A4 print rules.
  EXPECT_NE(html.find("@page{size:A4"), std::string::npos);
}

TEST(SessionReportTest, AbsentDataIsSaid) {
  SessionReport r = Report();
  r.sets.front().predictions.clear();
  r.runs = json::array();
  r.trials = json::array();
  std::string html = RenderSessionReport(r);
  EXPECT_NE(html.find("No runs in this session."), std::string::npos);
  EXPECT_NE(html.find("No trials recorded in this session."), std::string::npos);
  EXPECT_NE(html.find("No prediction on a trial this set was not fitted on yet"),
            std::string::npos);
  EXPECT_NE(html.find("No e-stop during this session"), std::string::npos);
  r.sets.clear();
  html = RenderSessionReport(r);
  EXPECT_NE(html.find("No parameter set for this leg yet"), std::string::npos);
  // A set predicted only on its own training trial shows no "fresh" figure.
  r = Report();
  for (ReportPrediction& p : r.sets.front().predictions) p.fresh = false;
  html = RenderSessionReport(r);
  EXPECT_NE(html.find("No prediction on a trial this set was not fitted on yet"),
            std::string::npos);
}

TEST(SessionReportTest, HtmlEscape) {
  EXPECT_EQ(HtmlEscape("a<b>&\"c'"), "a&lt;b&gt;&amp;&quot;c&#39;");
  EXPECT_EQ(HtmlEscape("τ_pta 1.5 N·m"), "τ_pta 1.5 N·m");
}

}  // namespace
}  // namespace fesbench::server::services
