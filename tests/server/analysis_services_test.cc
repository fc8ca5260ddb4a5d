// The analysis services on a temporary database: identification from
// model-simulated (noise-free) trials, prediction against a stored trial,
// and the paired t-test of a comparison (docs/MODEL.md; docs/API.md).

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "api/trial.h"
#include "model/identify_passive_only.h"
#include "model/parameter_set.h"
#include "model/signal.h"
#include "model/simulate.h"
#include "model/stimulus_generators.h"
#include "model/trajectory.h"
#include "server/services/analysis_json.h"
#include "server/services/comparison_service.h"
#include "server/services/identification_service.h"
#include "server/services/model_check.h"
#include "server/services/prediction_service.h"
#include "storage/audit_log.h"
#include "storage/database.h"
#include "storage/parameter_sets.h"
#include "storage/predictions.h"
#include "storage/sessions.h"
#include "storage/subjects.h"
#include "storage/trials.h"

namespace fesbench::server::services {
namespace {

const Actor kAnalyst{0, "ana", Role::kAnalyst};

// Truth whose τ_ptv breakpoints lie inside the velocities the trials reach.
model::ParameterSet Truth() {
  model::ParameterSet p = model::ExampleParameterSet();
  p.passive.torque_velocity =
      p.passive.torque_velocity.Resampled({-200, -100, -50, 0, 50, 100, 200});
  p.passive = model::ReferencePassive(p.passive);
  return p;
}

// A trial named `name` from a simulation; stim_ma is the commanded envelope
// when given (as the bench records it), velocity/acceleration optional.
api::Trial TrialOf(const std::string& name, const model::SimulationResult& sim,
                   const model::SampledSignal* env, bool kinematics) {
  api::Trial t;
  t.name = name;
  t.sample_rate_hz = 200.0;
  t.SetChannel("t_s", sim.t_s);
  std::vector<double> stim(sim.size(), 0.0);
  if (env != nullptr) {
    for (std::size_t i = 0; i < stim.size() && i < env->size(); ++i) stim[i] = env->values[i];
  }
  t.SetChannel("stim_ma", stim);
  t.SetChannel("angle_deg", sim.angle_deg);
  t.SetChannel("torque_nm", sim.torque_nm);
  if (kinematics) {
    t.SetChannel("velocity_deg_s", sim.velocity_deg_s);
    t.SetChannel("accel_deg_s2", sim.accel_deg_s2);
  }
  return t;
}

model::SimulationOptions Whole(const model::SampledSignal& env) {
  model::SimulationOptions o;
  o.duration_s = env.EndTime();
  return o;
}

double MaxDiff(const model::PiecewiseLinear& a, const model::PiecewiseLinear& b, double lo,
               double hi, double step) {
  double e = 0.0;
  for (double x = lo; x <= hi + 1e-9; x += step) e = std::max(e, std::abs(a(x) - b(x)));
  return e;
}

class AnalysisServicesTest : public ::testing::Test {
 protected:
  void SetUp() override {
    static std::atomic<int> counter{0};
    dir_ = std::filesystem::temp_directory_path() /
           ("fesbench_jobsvc_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
    storage::DatabaseOptions o;
    o.path = (dir_ / "fesbench.db").string();
    auto db = storage::Database::Open(o);
    ASSERT_TRUE(db.ok()) << db.status().ToString();
    db_ = std::move(*db);
  }
  void TearDown() override {
    db_.reset();
    std::filesystem::remove_all(dir_);
  }

  storage::Session MakeSession(const std::string& code) {
    storage::SubjectRepository subjects(*db_);
    auto subject = subjects.Create(code, storage::SubjectDetails{});
    EXPECT_TRUE(subject.ok()) << subject.status().ToString();
    auto leg = subjects.AddLeg(subject->id, storage::Side::kRight);
    EXPECT_TRUE(leg.ok()) << leg.status().ToString();
    storage::SessionDetails details;
    details.date = "2026-01-02";
    details.accelerometer_placement = "shank";
    auto session = storage::SessionRepository(*db_).Create(subject->id, leg->id, details);
    EXPECT_TRUE(session.ok()) << session.status().ToString();
    return *session;
  }

  std::int64_t Store(const storage::Session& s, const api::Trial& t) {
    auto id = storage::TrialRepository(*db_).Insert({s.id, {}}, t);
    EXPECT_TRUE(id.ok()) << id.status().ToString();
    return id.ok() ? *id : 0;
  }

  std::int64_t StoreSet(const storage::Session& s, const model::ParameterSet& p) {
    storage::NewParameterSet n;
    n.subject_id = s.subject_id;
    n.leg_id = s.leg_id;
    n.params = p;
    auto r = storage::ParameterSetRepository(*db_).Insert(n);
    EXPECT_TRUE(r.ok()) << r.status().ToString();
    return r.ok() ? r->id : 0;
  }

  // The thesis's identification trials of `truth` (§5.3–5.4), noise-free.
  std::vector<std::int64_t> StoreIdentificationTrials(const storage::Session& s,
                                                      const model::ParameterSet& truth) {
    std::vector<std::int64_t> ids;
    const model::GeneratorParams range = {{"threshold_ma", 20}, {"max_ma", 45}};
    const model::SampledSignal ramp = model::MakeStimulus("isometric_ramp_irc", range);
    ids.push_back(
        Store(s, TrialOf("isometric_ramp_irc",
                         model::SimulateIsometric(
                             truth, model::PulsesFromEnvelope(ramp, model::kDefaultPulseRateHz),
                             90.0, Whole(ramp)),
                         &ramp, false)));
    for (std::uint64_t seed : {3u, 8u}) {
      model::SumOfSinesOptions so;
      so.min_deg = 12;
      so.max_deg = 108;
      so.seed = seed;
      const model::SumOfSinesTrajectory traj(so);
      model::SimulationOptions o;
      o.duration_s = traj.duration_s();
      ids.push_back(
          Store(s, TrialOf("passive_simultaneous_" + std::to_string(ids.size()),
                           model::SimulateTrajectory(truth, {}, traj, o), nullptr, true)));
    }
    for (double seed : {11.0, 12.0}) {
      const model::SampledSignal env =
          model::MakeStimulus("random_binary_dense", {{"amplitude_ma", 26}, {"seed", seed}});
      ids.push_back(Store(
          s, TrialOf(
                 "active_random_binary_rb" + std::to_string(ids.size()),
                 model::SimulateFreeSwing(
                     truth, model::PulsesFromEnvelope(env, model::kDefaultPulseRateHz), Whole(env)),
                 &env, true)));
    }
    return ids;
  }

  std::filesystem::path dir_;
  std::unique_ptr<storage::Database> db_;
};

IdentificationRequest SimultaneousRequest(std::int64_t session_id,
                                          const model::ParameterSet& truth) {
  IdentificationRequest r;
  r.session_id = session_id;
  r.passive_method = model::PassiveMethod::kSimultaneous;
  r.irc_method = model::IrcMethod::kRampCorrelation;
  r.breakpoints.passive_angle = model::BreakpointSpec{0, truth.passive.torque_angle.x()};
  r.breakpoints.passive_velocity = model::BreakpointSpec{0, truth.passive.torque_velocity.x()};
  return r;
}

TEST_F(AnalysisServicesTest, IdentificationRecoversKnownParametersAndStoresVersions) {
  const model::ParameterSet truth = Truth();
  const storage::Session s = MakeSession("S1");
  std::vector<std::int64_t> trial_ids = StoreIdentificationTrials(s, truth);
  IdentificationService service(*db_);
  IdentificationRequest req = SimultaneousRequest(s.id, truth);
  req.models = {model::ModelKind::kFull, model::ModelKind::kTorqueGenerator};
  auto fit = service.Fit(kAnalyst, req);
  ASSERT_TRUE(fit.ok()) << fit.status().ToString();
  ASSERT_EQ(fit->stored.size(), 2u);
  EXPECT_EQ(fit->stored[0].version, 1);
  EXPECT_EQ(fit->stored[0].model, "full");
  EXPECT_EQ(fit->stored[1].version, 2);
  EXPECT_EQ(fit->stored[1].model, "torque_generator");
  std::sort(trial_ids.begin(), trial_ids.end());
  EXPECT_EQ(fit->trial_ids, trial_ids);

  storage::ParameterSetRepository sets(*db_);
  auto stored = sets.Get(fit->stored[0].parameter_set_id);
  ASSERT_TRUE(stored.ok()) << stored.status().ToString();
  const model::ParameterSet& est = stored->params;
  // The tolerances of tests/model: pole 2 %, IRC 0.02 away from threshold,
  // passive 0.05 N·m, inertia 1 %.
  EXPECT_NEAR(est.contraction.pole_per_s, 25.0, 0.02 * 25.0);
  double irc_err = 0.0;
  for (double u = 27.0; u <= 45.0; u += 0.5)
    irc_err = std::max(irc_err, std::abs(est.irc(u) - truth.irc(u)));
  EXPECT_LT(irc_err, 0.02);
  EXPECT_LT(MaxDiff(est.passive.torque_angle, truth.passive.torque_angle, 15, 105, 0.5), 0.05);
  EXPECT_LT(MaxDiff(est.passive.torque_velocity, truth.passive.torque_velocity, -150, 150, 1),
            0.05);
  EXPECT_NEAR(est.passive.inertia_kgm2, truth.passive.inertia_kgm2,
              0.01 * truth.passive.inertia_kgm2);
  EXPECT_NEAR(est.active.torque_scale_nm, truth.active.torque_scale_nm,
              0.05 * truth.active.torque_scale_nm);
  EXPECT_NEAR(est.active.torque_angle(90.0), 1.0, 1e-9);
  // Provenance.
  EXPECT_EQ(est.provenance.irc_method, "ramp_correlation");
  EXPECT_EQ(est.provenance.passive_method, "simultaneous");
  EXPECT_EQ(est.provenance.active_method, "log_least_squares");
  EXPECT_EQ(est.provenance.trial_ids, trial_ids);
  EXPECT_EQ(stored->trial_ids, trial_ids);
  ASSERT_TRUE(est.provenance.active_trial_id.has_value());
  EXPECT_EQ(*est.provenance.active_trial_id, trial_ids[3]);
  EXPECT_TRUE(est.provenance.fit_rms.count("passive_nm"));
  EXPECT_TRUE(est.provenance.fit_rms.count("active_nm"));
  EXPECT_EQ(est.provenance.software_version, storage::StorageSoftwareVersion());
  auto tg = sets.Get(fit->stored[1].parameter_set_id);
  ASSERT_TRUE(tg.ok());
  EXPECT_EQ(tg->params.model, model::ModelKind::kTorqueGenerator);
  EXPECT_EQ(tg->params.provenance.active_method, "torque_generator");
  EXPECT_EQ(tg->params.passive, est.passive);
  // The audit entry of the same transaction.
  auto audit = storage::AuditLog(*db_).List({});
  ASSERT_TRUE(audit.ok());
  ASSERT_EQ(audit->size(), 1u);
  EXPECT_EQ((*audit)[0].entry.action, "identification.fit");
  EXPECT_EQ((*audit)[0].entry.actor, "ana");
  EXPECT_EQ(fit->audit_id, (*audit)[0].id);

  // A second fit is a new version; the first stays as it was.
  req.models = {model::ModelKind::kFull};
  auto again = service.Fit(kAnalyst, req);
  ASSERT_TRUE(again.ok()) << again.status().ToString();
  ASSERT_EQ(again->stored.size(), 1u);
  EXPECT_EQ(again->stored[0].version, 3);
  EXPECT_NE(again->stored[0].parameter_set_id, fit->stored[0].parameter_set_id);
  auto first = sets.Get(fit->stored[0].parameter_set_id);
  ASSERT_TRUE(first.ok());
  EXPECT_EQ(first->params, est);
  EXPECT_EQ(first->summary.version, 1);

  // The JSON result names the stored ids.
  const nlohmann::json j = IdentificationResultToJson(*fit);
  EXPECT_EQ(j["parameter_sets"][0]["id"], fit->stored[0].parameter_set_id);
  EXPECT_EQ(j["parameter_sets"][1]["version"], 2);
}

TEST_F(AnalysisServicesTest, IdentificationRefusesMissingTrialsUnknownIdsAndWrongRole) {
  const storage::Session s = MakeSession("S2");
  const model::ParameterSet truth = Truth();
  const model::GeneratorParams range = {{"threshold_ma", 20}, {"max_ma", 45}};
  const model::SampledSignal ramp = model::MakeStimulus("isometric_ramp_irc", range);
  const std::int64_t ramp_id =
      Store(s, TrialOf("isometric_ramp_irc",
                       model::SimulateIsometric(
                           truth, model::PulsesFromEnvelope(ramp, model::kDefaultPulseRateHz), 90.0,
                           Whole(ramp)),
                       &ramp, false));
  IdentificationService service(*db_);
  IdentificationRequest req;
  req.session_id = s.id;
  req.passive_method = model::PassiveMethod::kSequential;
  auto missing = service.Fit(kAnalyst, req);
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.status().code(), api::ErrorCode::kFailedPrecondition);
  EXPECT_NE(missing.status().message().find("passive_positions"), std::string::npos);
  EXPECT_NE(missing.status().message().find("active_random_binary"), std::string::npos);
  EXPECT_EQ(missing.status().message().find("isometric_ramp_irc"), std::string::npos);

  req.method = model::IdentificationMethod::kRapid;
  auto rapid = service.Fit(kAnalyst, req);
  EXPECT_EQ(rapid.status().code(), api::ErrorCode::kFailedPrecondition);
  EXPECT_NE(rapid.status().message().find("rapid_free_swing_passive"), std::string::npos);

  IdentificationRequest unknown;
  unknown.session_id = 9999;
  EXPECT_EQ(service.Fit(kAnalyst, unknown).status().code(), api::ErrorCode::kNotFound);
  IdentificationRequest unknown_trial;
  unknown_trial.trial_ids = {ramp_id, 9999};
  EXPECT_EQ(service.Fit(kAnalyst, unknown_trial).status().code(), api::ErrorCode::kNotFound);

  EXPECT_EQ(service.Fit(Actor{0, "cli", Role::kClinician}, req).status().code(),
            api::ErrorCode::kPermissionDenied);
  IdentificationRequest bad;
  bad.session_id = s.id;
  bad.models = {model::ModelKind::kFull, model::ModelKind::kFull};  // duplicate
  auto invalid = service.Fit(kAnalyst, bad);
  EXPECT_EQ(invalid.status().code(), api::ErrorCode::kInvalidArgument);
  EXPECT_EQ(invalid.status().field(), "models[1]");
  // Nothing was stored by the refused requests.
  storage::HistoryQuery query;
  query.subject_id = s.subject_id;
  auto history = storage::ParameterSetRepository(*db_).History(query);
  ASSERT_TRUE(history.ok());
  EXPECT_TRUE(history->empty());
}

// docs/MODEL.md: trials that support the passive block but not the
// stimulated ones give a passive-only set, what was not fitted named;
// without the passive block nothing is fitted.
TEST_F(AnalysisServicesTest, IdentificationFitsTheBlocksItsTrialsSupport) {
  const model::ParameterSet truth = Truth();
  const storage::Session s = MakeSession("S14");
  const std::vector<std::int64_t> all = StoreIdentificationTrials(s, truth);
  IdentificationService service(*db_);
  IdentificationRequest req = SimultaneousRequest(s.id, truth);
  req.session_id.reset();

  // The two motor trials alone: the passive block, J fitted with it (Eq. 4.31).
  req.trial_ids = {all[1], all[2]};
  auto passive = service.Fit(kAnalyst, req);
  ASSERT_TRUE(passive.ok()) << passive.status().ToString();
  auto set = storage::ParameterSetRepository(*db_).Get(passive->stored[0].parameter_set_id);
  ASSERT_TRUE(set.ok());
  EXPECT_TRUE(model::IsPassiveOnly(set->params));
  EXPECT_EQ(set->params.provenance.irc_method, "none");
  EXPECT_EQ(set->params.provenance.active_method, "none");
  EXPECT_EQ(set->params.provenance.passive_method, "simultaneous");
  EXPECT_NEAR(set->params.passive.inertia_kgm2, truth.passive.inertia_kgm2,
              0.05 * truth.passive.inertia_kgm2);
  std::string warnings;
  for (const std::string& w : set->params.provenance.warnings) warnings += w + "\n";
  EXPECT_NE(warnings.find("not identified"), std::string::npos) << warnings;
  EXPECT_NE(warnings.find("isometric_ramp_irc"), std::string::npos) << warnings;
  EXPECT_NE(warnings.find("active_random_binary"), std::string::npos) << warnings;

  // With the ramp too: the IRC and contraction dynamics fitted, the active
  // curves still named as missing.
  req.trial_ids = {all[0], all[1], all[2]};
  auto with_irc = service.Fit(kAnalyst, req);
  ASSERT_TRUE(with_irc.ok()) << with_irc.status().ToString();
  set = storage::ParameterSetRepository(*db_).Get(with_irc->stored[0].parameter_set_id);
  EXPECT_EQ(set->params.provenance.irc_method, "ramp_correlation");
  EXPECT_EQ(set->params.provenance.active_method, "none");
  EXPECT_TRUE(model::IsPassiveOnly(set->params));
  EXPECT_GT(set->params.irc(45.0), 0.5);

  // A variant needs active curves; the active trials alone support nothing.
  req.models = {model::ModelKind::kFull, model::ModelKind::kTorqueGenerator};
  EXPECT_EQ(service.Fit(kAnalyst, req).status().code(), api::ErrorCode::kFailedPrecondition);
  req.models = {model::ModelKind::kFull};
  req.trial_ids = {all[3], all[4]};
  auto none = service.Fit(kAnalyst, req);
  EXPECT_EQ(none.status().code(), api::ErrorCode::kFailedPrecondition);
  EXPECT_NE(none.status().message().find("passive_simultaneous"), std::string::npos);
}

TEST_F(AnalysisServicesTest, PredictionOfATrialMadeFromTheSameParametersHasZeroError) {
  const model::ParameterSet truth = Truth();
  const storage::Session s = MakeSession("S3");
  const std::int64_t set_id = StoreSet(s, truth);
  const model::SampledSignal env =
      model::MakeStimulus("random_binary_dense", {{"amplitude_ma", 26}, {"seed", 99}});
  const std::int64_t trial_id = Store(
      s, TrialOf("prediction_random_binary",
                 model::SimulateFreeSwing(
                     truth, model::PulsesFromEnvelope(env, model::kDefaultPulseRateHz), Whole(env)),
                 &env, true));
  PredictionService service(*db_);
  PredictionRequest req;
  req.parameter_set_id = set_id;
  req.trial_id = trial_id;
  auto r = service.Predict(kAnalyst, req);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->mode, PredictionMode::kFreeSwing);
  // A clinician's model check runs too.
  EXPECT_TRUE(service.Predict(Actor{0, "cli", Role::kClinician}, req).ok());
  ASSERT_TRUE(r->errors.has_value());
  EXPECT_EQ(r->errors->channel, "angle_deg");
  EXPECT_EQ(r->errors->samples, env.size());
  EXPECT_LT(r->errors->e_rms, 1e-9);
  EXPECT_LT(r->errors->e_abs, 1e-9);
  ASSERT_TRUE(r->errors->normalised_rms && r->errors->e_ave);
  EXPECT_LT(*r->errors->normalised_rms, 1e-9);
  EXPECT_LT(*r->errors->e_ave, 1e-9);
  // Stored: the prediction and its evaluation.
  ASSERT_GT(r->prediction_id, 0);
  ASSERT_TRUE(r->evaluation_id.has_value());
  storage::PredictionRepository repo(*db_);
  auto eval = repo.GetEvaluation(*r->evaluation_id);
  ASSERT_TRUE(eval.ok()) << eval.status().ToString();
  EXPECT_EQ(eval->evaluation.channel, "angle_deg");
  EXPECT_EQ(eval->evaluation.prediction_id, r->prediction_id);
  EXPECT_LT(eval->evaluation.rms_error, 1e-9);
  auto pred = repo.GetPrediction(r->prediction_id);
  ASSERT_TRUE(pred.ok());
  EXPECT_EQ(nlohmann::json::parse(pred->prediction.input_json)["trial_id"], trial_id);

  // A prediction from a stimulus generator: isometric, offset removed.
  PredictionRequest stim;
  stim.parameter_set_id = set_id;
  stim.stimulus = StimulusSpec{"prediction_step", {{"threshold_ma", 20}, {"max_ma", 45}}};
  stim.mode = PredictionMode::kIsometric;
  auto iso = service.Predict(kAnalyst, stim);
  ASSERT_TRUE(iso.ok()) << iso.status().ToString();
  EXPECT_EQ(iso->predicted.size(), 1000u);  // 5 s at 200 Hz
  EXPECT_FALSE(iso->errors.has_value());
  EXPECT_DOUBLE_EQ(iso->predicted.torque_nm.front(), 0.0);
  // Plateau torque: τ_scale·R(u) at 90°, 0 deg/s (f_ata = f_atv = 1), u = 20 + 0.75·25.
  EXPECT_NEAR(iso->predicted.torque_nm[700], truth.active.torque_scale_nm * truth.irc(38.75),
              0.01 * truth.active.torque_scale_nm);
}

// docs/MODEL.md, pulse timing: a prediction on a stored trial replays the pulses the trial
// stores (what the stimulator delivered), not pulses rebuilt from stim_ma.
TEST_F(AnalysisServicesTest, PredictionOfAStoredTrialReplaysItsStoredPulses) {
  const model::ParameterSet truth = Truth();
  const storage::Session s = MakeSession("S9");
  const std::int64_t set_id = StoreSet(s, truth);
  const model::SampledSignal env =
      model::MakeStimulus("random_binary_dense", {{"amplitude_ma", 26}, {"seed", 99}});
  // A stimulator whose pulses came 7 ms after the grid of the envelope.
  model::PulseTrain delivered = model::PulsesFromEnvelope(env, model::kDefaultPulseRateHz);
  for (model::Pulse& p : delivered) p.t_s += 0.007;
  api::Trial trial = TrialOf("prediction_random_binary",
                             model::SimulateFreeSwing(truth, delivered, Whole(env)), &env, true);
  const auto predict = [&](const api::Trial& t) {
    PredictionRequest req;
    req.parameter_set_id = set_id;
    req.trial_id = Store(s, t);
    auto r = PredictionService(*db_).Predict(kAnalyst, req);
    EXPECT_TRUE(r.ok()) << r.status().ToString();
    return r.ok() && r->errors ? r->errors->e_rms : -1.0;
  };
  const double without_pulses = predict(trial);  // the envelope on the grid
  api::PulseRecord record;
  for (const model::Pulse& p : delivered) record.Append(p.t_s, p.stim_ma);
  trial.pulses = record;
  const double with_pulses = predict(trial);
  EXPECT_LT(with_pulses, 1e-9) << "without stored pulses: " << without_pulses;
  EXPECT_GT(without_pulses, 1e-3);
}

// §6.1.2: the isometric prediction's torque is scaled by the best-fit
// constant; a set whose τ_scale is twice the truth's fits with k = 1/2 and no
// error left.
TEST_F(AnalysisServicesTest, IsometricPredictionFitsTheScaleOfSection612) {
  const model::ParameterSet truth = Truth();
  const storage::Session s = MakeSession("S5");
  model::ParameterSet doubled = truth;
  doubled.active.torque_scale_nm *= 2.0;
  const std::int64_t set_id = StoreSet(s, doubled);
  const model::SampledSignal env =
      model::MakeStimulus("plateau_profile", {{"threshold_ma", 20}, {"max_ma", 45}});
  const std::int64_t trial_id =
      Store(s, TrialOf("isometric_prediction",
                       model::SimulateIsometric(
                           truth, model::PulsesFromEnvelope(env, model::kDefaultPulseRateHz), 90.0,
                           Whole(env)),
                       &env, false));
  PredictionService service(*db_);
  PredictionRequest req;
  req.parameter_set_id = set_id;
  req.trial_id = trial_id;
  auto plain = service.Compute(req);
  ASSERT_TRUE(plain.ok()) << plain.status().ToString();
  EXPECT_EQ(plain->mode, PredictionMode::kIsometric);
  EXPECT_FALSE(plain->fitted_scale.has_value());
  EXPECT_GT(plain->errors->e_rms, 1.0);
  req.fit_scale = true;
  auto fitted = service.Compute(req);
  ASSERT_TRUE(fitted.ok()) << fitted.status().ToString();
  ASSERT_TRUE(fitted->fitted_scale.has_value());
  EXPECT_NEAR(*fitted->fitted_scale, 0.5, 1e-9);
  EXPECT_LT(fitted->errors->e_rms, 1e-9);
  EXPECT_EQ(PredictionResultToJson(*fitted, false)["fitted_scale"], *fitted->fitted_scale);

  // Only for an isometric trial.
  PredictionRequest stim;
  stim.parameter_set_id = set_id;
  stim.stimulus = StimulusSpec{"prediction_step", {}};
  stim.fit_scale = true;
  EXPECT_EQ(service.Compute(stim).status().field(), "fit_scale");
  req.mode = PredictionMode::kFreeSwing;
  EXPECT_EQ(service.Compute(req).status().field(), "fit_scale");
  EXPECT_EQ(ReadPredictionRequest({{"parameter_set_id", 1}, {"trial_id", 2}, {"fit_scale", 1}})
                .status()
                .field(),
            "fit_scale");
}

// Free swing stops at the bench's range of motion: a set whose passive
// torque only ever pushes into extension leaves the knee on the 10° stop,
// where without stops it would fall through.
TEST_F(AnalysisServicesTest, FreeSwingPredictionStopsAtTheRangeOfMotion) {
  const model::ParameterSet truth = Truth();
  const storage::Session s = MakeSession("S6");
  model::ParameterSet falling = truth;
  falling.passive.torque_angle = model::PiecewiseLinear::Constant(5.0, 90.0);
  const std::int64_t set_id = StoreSet(s, falling);
  const model::SampledSignal env =
      model::MakeStimulus("random_binary_dense", {{"amplitude_ma", 26}, {"seed", 5}});
  const std::int64_t trial_id = Store(
      s, TrialOf("prediction_random_binary",
                 model::SimulateFreeSwing(
                     truth, model::PulsesFromEnvelope(env, model::kDefaultPulseRateHz), Whole(env)),
                 &env, true));
  PredictionRequest req;
  req.parameter_set_id = set_id;
  req.trial_id = trial_id;
  auto stopped = PredictionService(*db_).Compute(req);
  ASSERT_TRUE(stopped.ok()) << stopped.status().ToString();
  ASSERT_TRUE(stopped->joint_limits.has_value());
  const auto& a = stopped->predicted.angle_deg;
  EXPECT_EQ(*std::min_element(a.begin(), a.end()), 10.0);
  EXPECT_EQ(a.back(), 10.0);
  PredictionConfig unbounded;
  unbounded.joint_limits.reset();
  auto free = PredictionService(*db_, unbounded).Compute(req);
  ASSERT_TRUE(free.ok()) << free.status().ToString();
  EXPECT_FALSE(free->joint_limits.has_value());
  EXPECT_LT(free->predicted.angle_deg.back(), 0.0);
  // A stimulus prediction may not start outside the range of motion.
  PredictionRequest stim;
  stim.parameter_set_id = set_id;
  stim.stimulus = StimulusSpec{"prediction_step", {}};
  stim.initial_angle_deg = 120.0;
  EXPECT_EQ(PredictionService(*db_).Compute(stim).status().field(), "initial_angle_deg");
}

// A prediction reports the share of its samples where the set's curves are
// extrapolated (outside the ranges recorded in its provenance), and nothing
// for a set that records no ranges.
TEST_F(AnalysisServicesTest, FreeSwingPredictionReportsTheShareOutsideTheIdentifiedRanges) {
  const model::ParameterSet truth = Truth();
  const storage::Session s = MakeSession("S8");
  model::ParameterSet ranged = truth;
  ranged.provenance.identified_range_deg["tau_pta"] = {60.0, 100.0};
  const std::int64_t ranged_id = StoreSet(s, ranged);
  const std::int64_t plain_id = StoreSet(s, truth);
  PredictionRequest req;
  req.stimulus = StimulusSpec{"prediction_step", {}};
  req.parameter_set_id = ranged_id;
  auto with_ranges = PredictionService(*db_).Compute(req);
  ASSERT_TRUE(with_ranges.ok()) << with_ranges.status().ToString();
  const auto& a = with_ranges->predicted.angle_deg;
  ASSERT_FALSE(a.empty());
  const auto outside =
      std::count_if(a.begin(), a.end(), [](double x) { return x < 60.0 || x > 100.0; });
  ASSERT_GT(outside, 0) << "the step swings the knee out of 60–100°";
  ASSERT_TRUE(with_ranges->share_outside_identified_ranges.has_value());
  EXPECT_NEAR(*with_ranges->share_outside_identified_ranges,
              static_cast<double>(outside) / static_cast<double>(a.size()), 1e-12);
  req.parameter_set_id = plain_id;
  auto without = PredictionService(*db_).Compute(req);
  ASSERT_TRUE(without.ok()) << without.status().ToString();
  EXPECT_FALSE(without->share_outside_identified_ranges.has_value());
}

TEST_F(AnalysisServicesTest, PredictionRejectsBadInputNamingTheField) {
  const storage::Session s = MakeSession("S4");
  const std::int64_t set_id = StoreSet(s, Truth());
  PredictionService service(*db_);
  PredictionRequest req;
  req.parameter_set_id = set_id;
  req.stimulus = StimulusSpec{"prediction_step", {}};
  req.duration_s = 601.0;
  auto longer = service.Predict(kAnalyst, req);
  EXPECT_EQ(longer.status().code(), api::ErrorCode::kInvalidArgument);
  EXPECT_EQ(longer.status().field(), "duration_s");
  req.duration_s.reset();
  req.stimulus->generator = "nope";
  EXPECT_EQ(service.Predict(kAnalyst, req).status().field(), "stimulus.generator");
  req.stimulus = StimulusSpec{"prediction_step", {{"max_ma", 500}}};
  EXPECT_EQ(service.Predict(kAnalyst, req).status().field(), "stimulus.params.max_ma");
  req.stimulus = StimulusSpec{"prediction_step", {}};
  req.initial_angle_deg = 200;
  EXPECT_EQ(service.Predict(kAnalyst, req).status().field(), "initial_angle_deg");
  req.initial_angle_deg.reset();
  req.parameter_set_id = 9999;
  EXPECT_EQ(service.Predict(kAnalyst, req).status().code(), api::ErrorCode::kNotFound);
  PredictionRequest trial_req;
  trial_req.parameter_set_id = set_id;
  trial_req.trial_id = 9999;
  EXPECT_EQ(service.Predict(kAnalyst, trial_req).status().code(), api::ErrorCode::kNotFound);

  // Strict JSON: unknown fields and wrong types are refused with the path.
  auto unknown = ReadPredictionRequest({{"parameter_set_id", 1}, {"trial_id", 2}, {"x", 1}});
  EXPECT_EQ(unknown.status().field(), "x");
  auto typed = ReadPredictionRequest({{"parameter_set_id", "1"}, {"trial_id", 2}});
  EXPECT_EQ(typed.status().field(), "parameter_set_id");
  auto nested = ReadPredictionRequest(
      {{"parameter_set_id", 1}, {"stimulus", {{"generator", "prediction_step"}, {"p", 1}}}});
  EXPECT_EQ(nested.status().field(), "stimulus.p");
  auto ok = ReadPredictionRequest(
      {{"parameter_set_id", 1},
       {"stimulus", {{"generator", "prediction_step"}, {"params", {{"max_ma", 40}}}}},
       {"mode", "isometric"}});
  ASSERT_TRUE(ok.ok()) << ok.status().ToString();
  EXPECT_EQ(ok->stimulus->params.at("max_ma"), 40.0);
  auto ident = ReadIdentificationRequest(
      {{"session_id", 1}, {"breakpoints", {{"active_angle", {10, 5}}}}});
  EXPECT_EQ(ident.status().field(), "breakpoints.active_angle[1]");
  auto ident_unknown = ReadIdentificationRequest({{"session_id", 1}, {"breakpoint", 3}});
  EXPECT_EQ(ident_unknown.status().field(), "breakpoint");
}

TEST_F(AnalysisServicesTest, ComparisonReproducesHandComputedPairedTTest) {
  // Three subjects; set a is the truth, set b scales τ_scale by 1 + k. On an
  // isometric trial of the truth the relative torque error of b is exactly k
  // at every sample, so normalised RMS (Eq. 6.1) is k for b and 0 for a:
  // d = (−0.1, −0.2, −0.4), d̄ = −0.7/3, S_d = sqrt(((0.1333)² + (0.0333)² +
  // (0.1667)²)/2) = 0.152753, t = d̄/(S_d/√3) = −√7 = −2.645751, df = 2,
  // two-sided p = 1 − |t|/√(t² + 2) = 1 − √7/3 = 0.118083 (t CDF for 2
  // degrees of freedom), t_crit(0.95, 2) = 4.302653.
  const model::ParameterSet truth = Truth();
  const model::SampledSignal env =
      model::MakeStimulus("plateau_profile", {{"threshold_ma", 20}, {"max_ma", 45}});
  const model::SimulationResult sim = model::SimulateIsometric(
      truth, model::PulsesFromEnvelope(env, model::kDefaultPulseRateHz), 90.0, Whole(env));
  ComparisonRequest req;
  req.metric = "normalised_rms";
  for (const double k : {0.1, 0.2, 0.4}) {
    const storage::Session s = MakeSession("C" + std::to_string(static_cast<int>(k * 10)));
    model::ParameterSet b = truth;
    b.active.torque_scale_nm *= 1.0 + k;
    const std::int64_t a_id = StoreSet(s, truth);
    const std::int64_t b_id = StoreSet(s, b);
    const std::int64_t trial = Store(s, TrialOf("isometric_prediction", sim, &env, false));
    req.pairs.push_back({a_id, b_id, {trial}});
  }
  ComparisonService service(*db_);
  auto r = service.Compare(req);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ASSERT_EQ(r->pairs.size(), 3u);
  EXPECT_NEAR(r->pairs[0].a_error, 0.0, 1e-9);
  EXPECT_NEAR(r->pairs[0].b_error, 0.1, 1e-9);
  EXPECT_NEAR(r->pairs[2].b_error, 0.4, 1e-9);
  EXPECT_EQ(r->unit, "1");
  ASSERT_TRUE(r->test.has_value()) << r->test_note;
  const model::PairedTTestResult& t = *r->test;
  EXPECT_EQ(t.n, 3u);
  EXPECT_NEAR(t.mean_difference, -0.7 / 3.0, 1e-9);
  EXPECT_NEAR(t.sd_difference, 0.152752523, 1e-8);
  EXPECT_NEAR(t.t, -std::sqrt(7.0), 1e-7);
  EXPECT_DOUBLE_EQ(t.df, 2.0);
  EXPECT_NEAR(t.p_value, 1.0 - std::sqrt(7.0) / 3.0, 1e-7);
  EXPECT_NEAR(t.t_critical, 4.302653, 1e-5);
  EXPECT_FALSE(t.significant);
  // The same comparison as a job: its record carries the JSON result.
  {
    JobPool pool;
    auto job = SubmitComparison(pool, service, kAnalyst, req);
    ASSERT_TRUE(job.ok()) << job.status().ToString();
    pool.Shutdown(/*drain=*/true);
    auto record = pool.Get(*job);
    ASSERT_TRUE(record.ok());
    ASSERT_EQ(record->state, JobState::kDone) << record->error.ToString();
    EXPECT_NEAR(record->result["t_test"]["t"].get<double>(), -std::sqrt(7.0), 1e-7);
  }
  const nlohmann::json j = ComparisonResultToJson(*r);
  EXPECT_EQ(j["t_test"]["n"], 3);
  EXPECT_EQ(j["pairs"][1]["trials"][0]["trial_id"], req.pairs[1].trial_ids[0]);

  EXPECT_TRUE(j["t_test_note"].is_null());

  // One pair: its errors, no t-test, and the result says why.
  ComparisonRequest one = req;
  one.pairs.resize(1);
  auto single = service.Compare(one);
  ASSERT_TRUE(single.ok()) << single.status().ToString();
  EXPECT_FALSE(single->test.has_value());
  EXPECT_NEAR(single->pairs[0].b_error, 0.1, 1e-9);
  const nlohmann::json single_json = ComparisonResultToJson(*single);
  EXPECT_TRUE(single_json["t_test"].is_null());
  EXPECT_THAT(single_json["t_test_note"].get<std::string>(), ::testing::HasSubstr("at least 2 pairs, got 1"));
  // Equal differences (S_d = 0): t undefined, said so, errors kept.
  ComparisonRequest same = req;
  same.pairs = {req.pairs[0], req.pairs[0]};
  auto flat = service.Compare(same);
  ASSERT_TRUE(flat.ok()) << flat.status().ToString();
  EXPECT_FALSE(flat->test.has_value());
  EXPECT_THAT(flat->test_note, ::testing::HasSubstr("S_d = 0"));
  // No pair at all: refused, naming the field.
  ComparisonRequest none = req;
  none.pairs.clear();
  auto refused = service.Compare(none);
  EXPECT_EQ(refused.status().code(), api::ErrorCode::kInvalidArgument);
  EXPECT_EQ(refused.status().field(), "pairs");
  ComparisonRequest unknown = req;
  unknown.pairs[1].b_parameter_set_id = 9999;
  EXPECT_EQ(service.Compare(unknown).status().code(), api::ErrorCode::kNotFound);
  ComparisonRequest crossed = req;
  crossed.pairs[0].b_parameter_set_id = req.pairs[1].b_parameter_set_id;
  auto mixed = service.Compare(crossed);
  EXPECT_EQ(mixed.status().code(), api::ErrorCode::kInvalidArgument);
  EXPECT_EQ(mixed.status().field(), "pairs[0].b_parameter_set_id");
  auto parsed = ReadComparisonRequest(
      {{"pairs",
        {{{"a_parameter_set_id", 1}, {"b_parameter_set_id", 2}, {"trial_ids", {3}}},
         {{"a_parameter_set_id", 1}, {"b_parameter_set_id", 2}, {"trial_id", {3}}}}}});
  EXPECT_EQ(parsed.status().field(), "pairs[1].trial_ids");
}

// A pendulum test recorded elsewhere: no stimulation column, a start a few
// degrees hyperextended, no stops declared — predicted as the knee moved,
// with the passive end-range stiffness as its only stop; the same swing
// recorded on this bench is predicted within the bench's stops.
TEST_F(AnalysisServicesTest, AnImportedPendulumTestIsPredictedWithoutTheBenchsStops) {
  const model::ParameterSet truth = Truth();
  const storage::Session s = MakeSession("S13");
  const std::int64_t set_id = StoreSet(s, truth);
  model::SimulationOptions o;
  o.duration_s = 4.0;
  o.initial_angle_deg = -6.0;
  const model::SimulationResult swing = model::SimulateFreeSwing(truth, {}, o);
  api::Trial trial;
  trial.name = "free_swing_passive";
  trial.sample_rate_hz = 200.0;
  trial.SetChannel("t_s", swing.t_s);
  trial.SetChannel("angle_deg", swing.angle_deg);
  trial.SetChannel("velocity_deg_s", swing.velocity_deg_s);
  storage::TrialImport provenance{"sto", "a pendulum test", R"({"kind":"free_swing_passive"})",
                                  "ana", std::nullopt};
  auto imported = storage::TrialRepository(*db_).Insert({s.id, {}}, trial, provenance);
  ASSERT_TRUE(imported.ok()) << imported.status().ToString();
  PredictionService service(*db_);
  PredictionRequest req;
  req.parameter_set_id = set_id;
  req.trial_id = *imported;
  auto r = service.Predict(kAnalyst, req);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_FALSE(r->joint_limits.has_value());
  EXPECT_DOUBLE_EQ(r->initial_angle_deg, -6.0);
  EXPECT_LT(r->errors->e_rms, 1e-6);
  // On this bench: the stops, the start clamped to 10°.
  const std::int64_t bench_trial = Store(s, trial);
  req.trial_id = bench_trial;
  auto on_bench = service.Predict(kAnalyst, req);
  ASSERT_TRUE(on_bench.ok()) << on_bench.status().ToString();
  ASSERT_TRUE(on_bench->joint_limits.has_value());
  EXPECT_DOUBLE_EQ(on_bench->initial_angle_deg, 10.0);
  EXPECT_GT(on_bench->errors->e_rms, 0.1);
}

// The model check (docs/MODEL.md): the set predicts its leg's validation
// trials it was not fitted on; training and identification trials are left
// out; each trial is judged in its own quantity and the set gets its worst
// trial's verdict.
TEST_F(AnalysisServicesTest, ModelCheckJudgesTheFreshValidationTrialsInTheirOwnUnits) {
  const model::ParameterSet truth = Truth();
  const storage::Session s = MakeSession("S11");
  const model::SampledSignal rb =
      model::MakeStimulus("random_binary_dense", {{"amplitude_ma", 26}, {"seed", 99}});
  const model::SampledSignal plateau =
      model::MakeStimulus("plateau_profile", {{"threshold_ma", 20}, {"max_ma", 45}});
  const auto swing = [&](const std::string& name) {
    return Store(s, TrialOf(name,
                            model::SimulateFreeSwing(
                                truth, model::PulsesFromEnvelope(rb, model::kDefaultPulseRateHz),
                                Whole(rb)),
                            &rb, true));
  };
  const std::int64_t training = swing("prediction_random_binary_training");
  swing("active_random_binary_rb1");  // not a validation kind
  const std::int64_t fresh_swing = swing("prediction_random_binary");
  const std::int64_t fresh_iso = Store(
      s, TrialOf("isometric_prediction",
                 model::SimulateIsometric(
                     truth, model::PulsesFromEnvelope(plateau, model::kDefaultPulseRateHz), 90.0,
                     Whole(plateau)),
                 &plateau, false));
  model::ParameterSet fitted = truth;
  fitted.provenance.trial_ids = {training};
  fitted.provenance.warnings = {
      "active: 124 stimulated samples with non-positive active torque skipped (passive set "
      "inconsistent with the trial?)",
      "something the check does not know"};
  const std::int64_t set_id = StoreSet(s, fitted);
  PredictionService predictions(*db_);
  const Actor clinician{0, "cli", Role::kClinician};

  auto check = CheckModel(*db_, predictions, clinician, set_id);
  ASSERT_TRUE(check.ok()) << check.status().ToString();
  EXPECT_EQ(check->verdict, ModelVerdict::kGoodForControl) << check->summary;
  ASSERT_EQ(check->trials.size(), 2u);
  EXPECT_EQ(check->trials[0].trial_id, fresh_iso);  // newest first
  EXPECT_EQ(check->trials[0].unit, "N.m");
  EXPECT_EQ(check->trials[0].quantity, "torque");
  ASSERT_TRUE(check->trials[0].measured_range.has_value());
  EXPECT_GT(*check->trials[0].measured_range, 1.0);
  EXPECT_EQ(check->trials[1].trial_id, fresh_swing);
  EXPECT_EQ(check->trials[1].unit, "deg");
  EXPECT_LT(*check->trials[1].e_rms, 1e-9);
  for (const ModelCheckTrial& t : check->trials) {
    ASSERT_TRUE(t.prediction_id.has_value());
    EXPECT_TRUE(storage::PredictionRepository(*db_).GetPrediction(*t.prediction_id).ok());
  }
  ASSERT_EQ(check->warnings.size(), 2u);
  EXPECT_THAT(check->warnings[0], ::testing::HasSubstr("124 samples"));
  EXPECT_THAT(check->warnings[0], ::testing::Not(::testing::HasSubstr("non-positive")));
  EXPECT_EQ(check->warnings[1], "something the check does not know");
  EXPECT_EQ(check->technical_warnings, fitted.provenance.warnings);
  const nlohmann::json j = ModelCheckToJson(*check);
  EXPECT_EQ(j["verdict"], "good_for_control");
  EXPECT_EQ(j["trials"][0]["unit"], "N.m");

  // τ_scale doubled: the isometric torque is off by the whole plateau
  // (E_RMS over its range near 1/2 of the plateau's share > 30 %).
  model::ParameterSet strong = fitted;
  strong.active.torque_scale_nm *= 2.0;
  const std::int64_t strong_id = StoreSet(s, strong);
  auto bad = CheckModel(*db_, predictions, clinician, strong_id);
  ASSERT_TRUE(bad.ok()) << bad.status().ToString();
  EXPECT_EQ(bad->verdict, ModelVerdict::kDoNotUse);
  EXPECT_EQ(bad->trials[0].verdict, ModelVerdict::kDoNotUse);
  EXPECT_THAT(bad->trials[0].explanation, ::testing::HasSubstr("N·m"));
  // The thresholds decide: the same free-swing error between good and care.
  const double e = *bad->trials[1].e_rms;
  ASSERT_GT(e, 0.1);
  ModelCheckThresholds th;
  th.angle_good_deg = 0.5 * e;
  th.angle_care_deg = 2.0 * e;
  th.torque_good_share = th.torque_care_share = 10.0;
  auto care = CheckModel(*db_, predictions, clinician, strong_id, th);
  ASSERT_TRUE(care.ok());
  EXPECT_EQ(care->trials[1].verdict, ModelVerdict::kUseWithCare);
  EXPECT_EQ(care->trials[0].verdict, ModelVerdict::kGoodForControl);
  EXPECT_EQ(care->verdict, ModelVerdict::kUseWithCare);

  // Nothing fresh on another leg: no verdict but what to do.
  const storage::Session other = MakeSession("S12");
  const std::int64_t lonely = StoreSet(other, truth);
  auto none = CheckModel(*db_, predictions, clinician, lonely);
  ASSERT_TRUE(none.ok());
  EXPECT_EQ(none->verdict, ModelVerdict::kNoFreshTrials);
  EXPECT_THAT(none->summary, ::testing::HasSubstr("prediction protocol"));
  EXPECT_EQ(CheckModel(*db_, predictions, clinician, 9999).status().code(),
            api::ErrorCode::kNotFound);
}

}  // namespace
}  // namespace fesbench::server::services
