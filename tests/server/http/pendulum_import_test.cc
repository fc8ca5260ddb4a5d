// The pendulum test on the simulated bench (protocol pendulum_test, a
// seeded cohort of both shape families) against the truth, and a pendulum
// test brought in as a lab would (docs/API.md, "Bringing your own
// recordings"): OpenSim motion files with the knee flexion-negative, other
// coordinates left out, the knee starting hyperextended; the passive curves
// identified from one swing with method passive, a held-out swing of the
// same leg predicted without stops; the passive-only set refused where it
// would stand for a stimulated muscle.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <string>
#include <vector>
#include <thread>

#include "api/parameter_set_json.h"
#include "model/parameter_set.h"
#include "model/simulate.h"
#include "tests/server/http/server_process.h"

namespace fesbench::testing {
namespace {

using nlohmann::json;

// A knee released at rest from `start_deg` (fesbench convention, flexion
// positive) swinging for `duration_s`, written as OpenSim IK writes it:
// 100 Hz, degrees, knee_angle_r flexion-negative, beside a hip coordinate.
std::string PendulumMot(double start_deg, double duration_s) {
  model::SimulationOptions o;
  o.initial_angle_deg = start_deg;
  o.duration_s = duration_s;
  o.output_rate_hz = 100.0;
  const model::SimulationResult sim =
      model::SimulateFreeSwing(model::ExampleParameterSet(), {}, o);
  // The examiner holds the shank for 0.8 s first (0.1° of marker jitter).
  std::vector<double> angle(80, start_deg);
  for (std::size_t i = 0; i < angle.size(); ++i) angle[i] += 0.1 * std::sin(1.3 * i);
  angle.insert(angle.end(), sim.angle_deg.begin(), sim.angle_deg.end());
  std::string rows;
  char line[128];
  for (std::size_t i = 0; i < angle.size(); ++i) {
    std::snprintf(line, sizeof line, "%16.8f\t%16.8f\t%16.8f\n", 0.01 * (i + 1), 28.0,
                  -angle[i]);
    rows += line;
  }
  return "Coordinates\nversion=1\nnRows=" + std::to_string(angle.size()) +
         "\nnColumns=3\ninDegrees=yes\n\nUnits are S.I. units (second, meters, Newtons, ...)\n"
         "Angles are in degrees.\n\nendheader\ntime\thip_flexion_r\tknee_angle_r\n" +
         rows;
}

TEST(PendulumImportTest, PassiveCurvesFromOneSwingPredictAnotherAndDriveNoStimulation) {
  ServerProcess server;
  auto c = server.Client();
  c.set_read_timeout(60);
  const std::string admin = server.admin_token();
  const std::string analyst = CreateUserToken(c, admin, "ana", "analyst");
  const std::string clinician = CreateUserToken(c, admin, "cora", "clinician");
  auto subject = Call(c, "POST", "/api/v1/subjects", clinician,
                      {{"code", "PEN-01"}, {"details", json::object()}, {"legs", {"right"}}});
  ASSERT_EQ(subject.status, 201) << subject.text;
  auto session = Call(c, "POST",
                      "/api/v1/subjects/" + std::to_string(subject.body["id"].get<int>()) +
                          "/sessions",
                      clinician, {{"leg", "right"}, {"date", "2026-11-27"}});
  ASSERT_EQ(session.status, 201) << session.text;
  const std::string import_path =
      "/api/v1/sessions/" + std::to_string(session.body["id"].get<int>()) + "/trials";
  const json spec = {{"kind", "free_swing_passive"},
                     {"format", "sto"},
                     {"columns", {{{"column", "knee_angle_r"}}}},
                     {"unmapped", "ignore"},
                     {"source", "pendulum test, OpenSim IK"}};
  std::int64_t trial[2] = {0, 0};
  const double start_deg[2] = {-5.0, 10.0};  // hyperextended, then slightly flexed
  for (int k = 0; k < 2; ++k) {
    auto imported =
        Call(c, "POST", import_path, clinician, {{"spec", spec}, {"data", PendulumMot(start_deg[k], 8.0)}});
    ASSERT_EQ(imported.status, 201) << imported.text;
    trial[k] = imported.body["trials"][0]["id"];
    auto stored = Call(c, "GET", "/api/v1/trials/" + std::to_string(trial[k]), analyst);
    ASSERT_EQ(stored.status, 200);
    std::vector<std::string> names;
    for (const json& ch : stored.body["channels"]) {
      names.push_back(ch["name"]);
      if (ch["name"] == "angle_deg") {  // flexion positive, not clipped at a stop
        EXPECT_NEAR(ch["values"][0].get<double>(), start_deg[k], 0.11);
      }
    }
    EXPECT_EQ(names, (std::vector<std::string>{"t_s", "angle_deg"})) << stored.text.substr(0, 300);
  }

  // The thesis's methods cannot use swings alone; the refusal points to passive.
  auto thesis = Call(c, "POST", "/api/v1/identifications", analyst,
                     {{"trial_ids", {trial[0]}}, {"method", "thesis"}});
  if (thesis.status == 202) thesis.body = WaitForJob(c, analyst, thesis.body["id"])["error"];
  else thesis.body = thesis.body["error"];
  EXPECT_NE(thesis.body.dump().find("method passive"), std::string::npos) << thesis.body.dump();
  // Without the limb's inertia there is no scale for the torques.
  auto no_j = Call(c, "POST", "/api/v1/identifications", analyst,
                   {{"trial_ids", {trial[0]}}, {"method", "passive"}});
  ASSERT_EQ(no_j.status, 202) << no_j.text;
  const json no_j_job = WaitForJob(c, analyst, no_j.body["id"]);
  EXPECT_EQ(no_j_job["state"], "failed");
  EXPECT_NE(no_j_job.dump().find("inertia_kgm2"), std::string::npos) << no_j_job.dump();
  auto wrong = Call(c, "POST", "/api/v1/identifications", analyst,
                    {{"trial_ids", {trial[0]}}, {"method", "passive"}, {"irc_method", "step"}});
  EXPECT_EQ(wrong.status, 400) << wrong.text;
  EXPECT_EQ(wrong.body["error"]["field"], "irc_method");
  for (const json& bad : {json(0.05), json(-2.0), json(1e9)}) {
    auto no_gravity = Call(c, "POST", "/api/v1/identifications", analyst,
                           {{"trial_ids", {trial[0]}}, {"method", "passive"},
                            {"gravity_moment_nm", bad}});
    EXPECT_EQ(no_gravity.status, 400) << no_gravity.text;
    EXPECT_EQ(no_gravity.body["error"]["field"], "gravity_moment_nm") << no_gravity.text;
  }

  auto fit = Call(c, "POST", "/api/v1/identifications", analyst,
                  {{"trial_ids", {trial[0]}}, {"method", "passive"}, {"inertia_kgm2", 0.36}});
  ASSERT_EQ(fit.status, 202) << fit.text;
  const json job = WaitForJob(c, analyst, fit.body["id"]);
  ASSERT_EQ(job["state"], "done") << job.dump().substr(0, 2000);
  const std::int64_t set_id = job["result"]["parameter_sets"][0]["id"];
  auto set = Call(c, "GET", "/api/v1/parameter-sets/" + std::to_string(set_id), analyst);
  ASSERT_EQ(set.status, 200);
  const json& prov = set.body["parameters"]["provenance"];
  EXPECT_EQ(prov["irc_method"], "none");
  EXPECT_EQ(prov["active_method"], "none");
  EXPECT_EQ(prov["inertia_method"], "given");
  EXPECT_NE(prov["warnings"].dump().find("not identified"), std::string::npos) << prov.dump();

  // The held-out swing, predicted without stops (it starts at 10° and passes 110°).
  auto predicted = Call(c, "POST", "/api/v1/predictions", analyst,
                        {{"parameter_set_id", set_id}, {"trial_id", trial[1]}});
  ASSERT_EQ(predicted.status, 202) << predicted.text;
  const json p = WaitForJob(c, analyst, predicted.body["id"]);
  ASSERT_EQ(p["state"], "done") << p.dump().substr(0, 1000);
  const double e_rms = p["result"]["errors"]["e_rms"];
  EXPECT_LT(e_rms, 2.0);  // 1.19° when written
  // Judged from where the knee had left the hold by 2° (the hand's release).
  EXPECT_GT(p["result"]["released_at_s"].get<double>(), 0.8);
  EXPECT_LT(p["result"]["released_at_s"].get<double>(), 1.0);
  EXPECT_TRUE(p["result"].value("joint_limits", json()).is_null()) << p["result"].dump(0).substr(0, 300);
  std::cout << "[ figure ] held-out swing predicted by the passive-only set: E_RMS " << e_rms
            << " deg\n";

  // A stimulated prediction and an approval are refused, naming why.
  auto stimulated =
      Call(c, "POST", "/api/v1/predictions", analyst,
           {{"parameter_set_id", set_id},
            {"stimulus", {{"generator", "prediction_step"}, {"params", json::object()}}}});
  std::string why = stimulated.text;
  if (stimulated.status == 202) why = WaitForJob(c, analyst, stimulated.body["id"]).dump();
  EXPECT_NE(why.find("passive only"), std::string::npos) << why;
  auto approve = Call(c, "POST", "/api/v1/parameter-sets/" + std::to_string(set_id) + "/approve",
                      clinician, {{"note", "looks fine"}});
  EXPECT_EQ(approve.status, 409) << approve.text;
  EXPECT_NE(approve.text.find("passive only"), std::string::npos) << approve.text;
  EXPECT_EQ(server.Terminate(), 0);
}

// τ_pta + τ_ptv(0) (only the sum is identifiable, §6.5) at angle_deg.
double StaticTorque(const model::ParameterSet& p, double angle_deg) {
  return p.passive.torque_angle(angle_deg) + p.passive.torque_velocity(0.0);
}

// The least-squares slope of τ_ptv over [−v, v], N·m per deg/s: the
// damping a swing of that speed meets.
double DampingSlope(const model::ParameterSet& p, double v) {
  double sxy = 0.0, sxx = 0.0;
  for (int i = -50; i <= 50; ++i) {
    const double x = v * i / 50.0;
    sxy += x * (p.passive.torque_velocity(x) - p.passive.torque_velocity(0.0));
    sxx += x * x;
  }
  return sxy / sxx;
}

// docs/MODEL.md, "Passive-only identification" on the bench: each leg's
// first swing identified with every default (the subject's weight and
// shank length recorded, nothing else given), its second predicted; J, the
// static torque and the damping against the truth the bench's leg is made
// of (its extras — hysteresis, friction, noise — are not in the model).
// J is tried from the swing's period with gravity's moment from the body
// measures; on these legs the swing does not determine it (the tissue's
// stiffness reaches mid-range and passes for gravity's: J ×0.8 and ×1.25
// fit as well), so the answer says so and takes Eq. 4.13's.
TEST(PendulumImportTest, ThePendulumProtocolOnACohortOfBothFamiliesAgainstTheTruth) {
  ServerProcess server;
  auto c = server.Client();
  c.set_read_timeout(60);
  const std::string admin = server.admin_token();
  std::vector<double> static_err, damping_err, held_out, j_err, j_eq413, pendulum_j, profile;
  int leg = 0;
  for (const std::string family : {"thesis", "analytic"}) {
    for (int seed = 1; seed <= 4; ++seed, ++leg) {
      auto drawn = Call(c, "PUT", "/api/v1/bench/virtual-subject", admin,
                        {{"draw_seed", seed}, {"family", family}});
      ASSERT_EQ(drawn.status, 200) << drawn.text;
      const model::ParameterSet truth = *api::ParameterSetFromJson(drawn.body["truth"]);
      const json& anthro = drawn.body["anthropometrics"];
      const std::string code = "PEN-" + family + "-" + std::to_string(seed);
      auto subject = Call(c, "POST", "/api/v1/subjects", admin,
                          {{"code", code},
                           {"details",
                            {{"weight_kg", anthro["body_mass_kg"]},
                             {"shank_length_cm", anthro["shank_length_m"].get<double>() * 100.0}}},
                           {"legs", {"right"}}});
      ASSERT_EQ(subject.status, 201) << subject.text;
      auto session = Call(c, "POST",
                          "/api/v1/subjects/" + std::to_string(subject.body["id"].get<int>()) +
                              "/sessions",
                          admin,
                          {{"leg", "right"},
                           {"date", "2026-11-28"},
                           {"threshold_ma", drawn.body["threshold_ma"]},
                           {"max_tolerated_ma", drawn.body["max_tolerated_ma"]}});
      ASSERT_EQ(session.status, 201) << session.text;
      const std::int64_t session_id = session.body["id"];
      const json run = RunToEnd(c, admin, session_id, {{"protocol", "pendulum_test"}});
      ASSERT_EQ(run["state"], "done") << run.dump().substr(0, 500);
      auto trials = Call(c, "GET", "/api/v1/sessions/" + std::to_string(session_id) + "/trials",
                         admin);
      ASSERT_EQ(trials.status, 200);
      std::map<std::string, std::int64_t> by_name;
      for (const json& t : trials.body["items"]) by_name[t["name"]] = t["id"];
      ASSERT_TRUE(by_name.count("pendulum_1") && by_name.count("pendulum_2")) << trials.text;

      auto fit = Call(c, "POST", "/api/v1/identifications", admin,
                      {{"trial_ids", {by_name["pendulum_1"]}}, {"method", "passive"}});
      ASSERT_EQ(fit.status, 202) << fit.text;
      const json job = WaitForJob(c, admin, fit.body["id"]);
      ASSERT_EQ(job["state"], "done") << job.dump().substr(0, 1000);
      const std::int64_t set_id = job["result"]["parameter_sets"][0]["id"];
      auto set = Call(c, "GET", "/api/v1/parameter-sets/" + std::to_string(set_id), admin);
      const model::ParameterSet est = *api::ParameterSetFromJson(set.body["parameters"]);
      const json& values = job["result"]["report"]["values"];
      EXPECT_EQ(values["pendulum_inertia_determined"], 0.0) << values.dump();
      EXPECT_EQ(est.provenance.inertia_method, "anthropometric");
      j_err.push_back(100.0 * (est.passive.inertia_kgm2 / truth.passive.inertia_kgm2 - 1.0));
      pendulum_j.push_back(100.0 * (values["pendulum_inertia_kgm2"].get<double>() /
                                        truth.passive.inertia_kgm2 -
                                    1.0));
      profile.push_back(100.0 * (std::min(values["pendulum_profile_low_deg"].get<double>(),
                                          values["pendulum_profile_high_deg"].get<double>()) /
                                     job["result"]["report"]["fit_rms"]["pendulum_inertia_deg"]
                                         .get<double>() -
                                 1.0));

      // The static torque over the angles the swing visited, against the
      // truth's span there; the damping over 80 % of the speeds it reached.
      const model::CurveRange seen = est.provenance.identified_range_deg.at("tau_pta");
      const model::CurveRange speeds = est.provenance.identified_range_deg_s.at("tau_ptv");
      double sum = 0.0, lo = INFINITY, hi = -INFINITY;
      int n = 0;
      for (double a = seen.lo; a <= seen.hi; a += 1.0, ++n) {
        const double e = StaticTorque(est, a) - StaticTorque(truth, a);
        sum += e * e;
        lo = std::min(lo, StaticTorque(truth, a));
        hi = std::max(hi, StaticTorque(truth, a));
      }
      static_err.push_back(100.0 * std::sqrt(sum / n) / (hi - lo));
      const double v = 0.8 * std::min(-speeds.lo, speeds.hi);
      damping_err.push_back(100.0 * (DampingSlope(est, v) / DampingSlope(truth, v) - 1.0));
      const double eq413 = 0.061 * anthro["body_mass_kg"].get<double>() *
                           std::pow(0.735 * anthro["shank_length_m"].get<double>(), 2);
      j_eq413.push_back(100.0 * (eq413 / truth.passive.inertia_kgm2 - 1.0));

      auto predicted = Call(c, "POST", "/api/v1/predictions", admin,
                            {{"parameter_set_id", set_id}, {"trial_id", by_name["pendulum_2"]}});
      ASSERT_EQ(predicted.status, 202) << predicted.text;
      const json p = WaitForJob(c, admin, predicted.body["id"]);
      ASSERT_EQ(p["state"], "done") << p.dump().substr(0, 1000);
      held_out.push_back(p["result"]["errors"]["e_rms"]);
      std::cout << "[ figure ] " << code << ": swing " << seen.lo << "…" << seen.hi
                << " deg; static torque RMS error " << static_err.back()
                << " % of its span; damping " << damping_err.back()
                << " %; held-out swing E_RMS " << held_out.back() << " deg; J " << j_err.back()
                << " % (Eq. 4.13: " << j_eq413.back() << " %; the swing's best J "
                << pendulum_j.back() << " %, J ×0.8 or ×1.25 fits within " << profile.back()
                << " % of its output error)\n";
    }
  }
  const auto worst = [](const std::vector<double>& v) {
    double w = 0.0;
    for (double x : v) w = std::max(w, std::abs(x));
    return w;
  };
  const auto median = [](std::vector<double> v) {
    for (double& x : v) x = std::abs(x);
    std::sort(v.begin(), v.end());
    return 0.5 * (v[(v.size() - 1) / 2] + v[v.size() / 2]);
  };
  std::cout << "[ figure ] J error median " << median(j_err) << " %, worst " << worst(j_err)
            << " %; the swing's best J median " << median(pendulum_j) << " %, worst "
            << worst(pendulum_j) << " %\n";
  std::cout << "[ figure ] static torque error median " << median(static_err) << " %, worst "
            << worst(static_err) << " %; damping median " << median(damping_err) << " %, worst "
            << worst(damping_err) << " %; held-out E_RMS median " << median(held_out)
            << " deg, worst " << worst(held_out) << " deg\n";
  // Bounds a little above the figures when written (docs/MODEL.md): the
  // held-out swing 0.24–0.63°, the static torque 2.7–5.3 % on six legs of
  // eight (16 % and 38 % on two), with Eq. 4.13's J (−9.6…+1.9 %). One
  // release angle leaves the split between τ_pta and τ_ptv ill-conditioned,
  // and the damping takes the bench's hysteresis and friction (not in the
  // model) too: 85–290 % above the truth's viscous damping, reported, not
  // bounded.
  EXPECT_LT(worst(held_out), 1.0);
  EXPECT_LT(median(static_err), 6.0);
  EXPECT_EQ(server.Terminate(), 0);
}

}  // namespace
}  // namespace fesbench::testing
