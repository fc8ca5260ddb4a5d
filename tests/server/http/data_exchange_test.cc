// Data in and out (docs/API.md, "Session archives"): a session exported from one server and
// imported into a fresh one gives the same trials bit for bit, the same
// parameter sets and the same identification results; the archive follows
// the BIDS layout; a recording imported as CSV predicts like a bench trial;
// bad uploads are refused naming the place and store nothing; an analyst
// loads the export with pandas.

#include <gtest/gtest.h>
#include <sys/mman.h>
#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>
#include <thread>

#include "api/bids.h"
#include "server/services/import_upload.h"
#include "tests/server/http/server_process.h"

namespace fesbench::testing {
namespace {

using nlohmann::json;

// Subject, right leg, session with the virtual subject's values; its id.
std::int64_t NewSession(httplib::Client& client, const std::string& token,
                        const std::string& code) {
  auto subject = Call(client, "POST", "/api/v1/subjects", token,
                      {{"code", code},
                       {"details",
                        {{"age_years", 41},
                         {"sex", "male"},
                         {"height_cm", 178},
                         {"weight_kg", 75},
                         {"shank_length_cm", 43}}},
                       {"legs", {"right"}}});
  EXPECT_EQ(subject.status, 201) << subject.text;
  auto session = Call(
      client, "POST",
      "/api/v1/subjects/" + std::to_string(subject.body["id"].get<int>()) + "/sessions", token,
      {{"leg", "right"}, {"date", "2026-11-25"}, {"threshold_ma", 14}, {"max_tolerated_ma", 45}});
  EXPECT_EQ(session.status, 201) << session.text;
  return session.body["id"];
}

// POST /identifications {session_id, method: rapid}; the stored set's parameters.
json Identify(httplib::Client& client, const std::string& token, std::int64_t session_id) {
  auto submitted = Call(client, "POST", "/api/v1/identifications", token,
                        {{"session_id", session_id}, {"method", "rapid"}});
  EXPECT_EQ(submitted.status, 202) << submitted.text;
  const json job = WaitForJob(client, token, submitted.body["id"]);
  EXPECT_EQ(job["state"], "done") << job.dump().substr(0, 2000);
  // The IRC's onset is the session's threshold (NewSession: 14 mA).
  EXPECT_EQ(job["result"]["report"]["values"].value("irc_onset_ma", -1.0), 14.0);
  const std::int64_t set_id = job["result"]["parameter_sets"][0]["id"];
  auto set = Call(client, "GET", "/api/v1/parameter-sets/" + std::to_string(set_id), token);
  EXPECT_EQ(set.status, 200);
  return set.body["parameters"];
}

// A parameter set's JSON with its trial ids renamed by `ids`.
json MapTrialIds(json params, const std::map<std::int64_t, std::int64_t>& ids) {
  json& p = params["provenance"];
  for (auto& id : p["trial_ids"]) id = ids.at(id.get<std::int64_t>());
  if (p.contains("active_trial_id") && p["active_trial_id"].is_number_integer()) {
    p["active_trial_id"] = ids.at(p["active_trial_id"].get<std::int64_t>());
  }
  return params;
}

httplib::Result PostBytes(httplib::Client& client, const std::string& path,
                          const std::string& token, const std::string& body,
                          const std::string& type) {
  return client.Post(path, {{"Authorization", "Bearer " + token}}, body, type);
}

// An export read back as the server reads an upload: from a file.
api::Result<server::services::UnpackedArchive> Unpack(const std::string& bytes,
                                                      server::services::ArchiveFormat format,
                                                      server::services::MemoryBudget& budget) {
  const int fd = ::memfd_create("export", MFD_CLOEXEC);
  EXPECT_EQ(::write(fd, bytes.data(), bytes.size()), static_cast<ssize_t>(bytes.size()));
  ::lseek(fd, 0, SEEK_SET);
  auto unpacked = server::services::UnpackArchive(fd, format, budget);
  ::close(fd);
  return unpacked;
}

TEST(DataExchangeTest, ExportImportRoundTripAndRecordingImport) {
  ServerProcess a;
  auto ca = a.Client();
  ca.set_read_timeout(60);
  const std::string admin_a = a.admin_token();
  const std::int64_t session_a = NewSession(ca, admin_a, "EXP-01");
  const json run = RunToEnd(ca, admin_a, session_a, {{"protocol", "rapid_parameterisation"}});
  ASSERT_EQ(run["state"], "done") << run.dump();
  const json rb = RunToEnd(ca, admin_a, session_a, {{"protocol", "prediction_random_binary"}});
  ASSERT_EQ(rb["state"], "done") << rb.dump();
  const json identified_a = Identify(ca, admin_a, session_a);

  // Export in both forms; the zip is the one imported.
  const std::string export_path = "/api/v1/sessions/" + std::to_string(session_a) + "/export";
  auto zip = ca.Get(export_path, {{"Authorization", "Bearer " + admin_a}});
  ASSERT_TRUE(zip);
  ASSERT_EQ(zip->status, 200) << zip->body.substr(0, 500);
  EXPECT_EQ(zip->get_header_value("Content-Type"), "application/zip");
  EXPECT_NE(zip->get_header_value("Content-Disposition").find("fesbench-session-"),
            std::string::npos);
  auto tgz = ca.Get(export_path + "?format=tar.gz", {{"Authorization", "Bearer " + admin_a}});
  ASSERT_TRUE(tgz);
  ASSERT_EQ(tgz->status, 200);
  EXPECT_EQ(tgz->get_header_value("Content-Type"), "application/gzip");
  server::services::MemoryBudget budget(std::size_t{192} << 20);
  auto unpacked = Unpack(zip->body, server::services::ArchiveFormat::kZip, budget);
  ASSERT_TRUE(unpacked.ok()) << unpacked.status().ToString();
  auto unpacked_tgz = Unpack(tgz->body, server::services::ArchiveFormat::kTarGz, budget);
  ASSERT_TRUE(unpacked_tgz.ok()) << unpacked_tgz.status().ToString();
  const api::FileMap* files = &unpacked->files;
  EXPECT_EQ(*files, unpacked_tgz->files);
  // The BIDS layout's required files and columns (api/bids.h: v1.11.0).
  const api::Status layout = api::ValidateBidsLayout(*files);
  EXPECT_TRUE(layout.ok()) << layout.ToString();
  EXPECT_TRUE(files->contains("README.md"));
  EXPECT_TRUE(files->contains("derivatives/fesbench/runs.json"));
  EXPECT_TRUE(files->contains("participants.tsv"));
  EXPECT_EQ(files->at("participants.tsv").find("EXP-01"), std::string::npos)
      << "BIDS labels are alphanumeric";
  EXPECT_NE(files->at("participants.tsv").find("sub-EXP01"), std::string::npos);

  // An analyst's pandas, if this machine has it (Debian python3-pandas,
  // under /usr/bin/python3 whatever python3 comes first on PATH).
  const std::string python =
      std::filesystem::exists("/usr/bin/python3") ? "/usr/bin/python3" : "python3";
  if (std::system((python + " -c 'import pandas' 2>/dev/null").c_str()) == 0) {
    const auto dir = a.dir() / "export";
    std::filesystem::create_directories(dir);
    std::ofstream(dir / "s.zip", std::ios::binary) << zip->body;
    const std::string script =
        "import os, sys, zipfile, glob, pandas as pd\n"
        "zipfile.ZipFile(sys.argv[1] + '/s.zip').extractall(sys.argv[1])\n"
        "motion = sorted(glob.glob(sys.argv[1] + '/*/sub-*/ses-*/motion/*_motion.tsv'))\n"
        "assert motion, 'no motion files'\n"
        "prefix = max(motion, key=os.path.getsize)[:-len('_motion.tsv')]\n"
        "ch = pd.read_csv(prefix + '_channels.tsv', sep='\\t')\n"
        "data = pd.read_csv(prefix + '_motion.tsv', sep='\\t', header=None, names=ch['name'])\n"
        "assert list(ch.columns[:5]) == ['name', 'component', 'type', 'tracked_point', 'units']\n"
        "assert 'angle_deg' in data.columns and len(data) > 100, data.columns\n"
        "ev = pd.read_csv(prefix + '_events.tsv', sep='\\t')\n"
        "assert list(ev.columns[:2]) == ['onset', 'duration']\n"
        "print(len(data), 'rows', len(ev), 'pulses')\n";
    std::ofstream(dir / "load.py") << script;
    EXPECT_EQ(std::system((python + " " + (dir / "load.py").string() + " " + dir.string()).c_str()),
              0);
  } else {
    std::cout << "[ note ] python3-pandas not installed: the pandas load was not run\n";
  }

  // The same prediction asked twice: the report shows the trial once (its
  // newest), in the unit of what it compares.
  const std::int64_t rb_trial = rb["trial_ids"][0];
  for (int i = 0; i < 2; ++i) {
    auto submitted = Call(ca, "POST", "/api/v1/predictions", admin_a,
                          {{"parameter_set_id", run["parameter_set_id"]}, {"trial_id", rb_trial}});
    ASSERT_EQ(submitted.status, 202) << submitted.text;
    ASSERT_EQ(WaitForJob(ca, admin_a, submitted.body["id"])["state"], "done");
  }

  // The session report: one HTML page with every section; 404 for no session.
  auto report = ca.Get("/api/v1/sessions/" + std::to_string(session_a) + "/report",
                       {{"Authorization", "Bearer " + admin_a}});
  ASSERT_TRUE(report);
  ASSERT_EQ(report->status, 200) << report->body.substr(0, 300);
  EXPECT_EQ(report->get_header_value("Content-Type").rfind("text/html", 0), 0u);
  for (const char* part :
       {"id=\"session\"", "id=\"runs-section\"", "id=\"trials-section\"", "id=\"warnings\"",
        "Parameter set", "rapid_parameterisation", "Predictions on fresh trials", "EXP-01"}) {
    EXPECT_NE(report->body.find(part), std::string::npos) << part;
  }
  EXPECT_EQ(report->body.find("<script"), std::string::npos);
  const std::string row =
      "<td>" + std::to_string(rb_trial) + " prediction_random_binary</td><td>knee angle</td>";
  std::size_t rows = 0;
  for (auto at = report->body.find(row); at != std::string::npos;
       at = report->body.find(row, at + 1)) {
    ++rows;
  }
  EXPECT_EQ(rows, 1u) << "each trial's prediction once";
  auto no_report = Call(ca, "GET", "/api/v1/sessions/999/report", admin_a);
  EXPECT_EQ(no_report.status, 404);

  // One trial's .sto says where it comes from; its EMG as its own CSV.
  const std::int64_t first_trial = run["trial_ids"][0];
  auto sto = ca.Get("/api/v1/trials/" + std::to_string(first_trial) + "?format=sto",
                    {{"Authorization", "Bearer " + admin_a}});
  ASSERT_TRUE(sto);
  EXPECT_NE(sto->body.find("\nfesbench_subject=EXP-01\n"), std::string::npos)
      << sto->body.substr(0, 300);
  EXPECT_NE(sto->body.find("\nfesbench_session_id=" + std::to_string(session_a) + "\n"),
            std::string::npos);
  // The knee as OpenSim's coordinate of the right leg, flexion negative.
  {
    const std::size_t labels_at = sto->body.find("endheader\n") + 10;
    const std::string labels =
        sto->body.substr(labels_at, sto->body.find('\n', labels_at) - labels_at);
    EXPECT_NE(labels.find("\tknee_angle_r"), std::string::npos) << labels;
    EXPECT_EQ(labels.find("angle_deg"), std::string::npos) << labels;
    auto trial = Call(ca, "GET", "/api/v1/trials/" + std::to_string(first_trial), admin_a);
    const std::string first_row = sto->body.substr(sto->body.find('\n', labels_at) + 1, 200);
    std::vector<std::string> values;
    std::stringstream row(first_row.substr(0, first_row.find('\n')));
    for (std::string v; std::getline(row, v, '\t');) values.push_back(v);
    std::vector<std::string> names;
    std::stringstream header(labels);
    for (std::string v; std::getline(header, v, '\t');) names.push_back(v);
    const std::size_t knee = std::find(names.begin(), names.end(), "knee_angle_r") - names.begin();
    ASSERT_LT(knee, values.size());
    double angle = 0.0;
    for (const auto& c : trial.body["channels"]) {
      if (c["name"] == "angle_deg") angle = c["values"][0];
    }
    EXPECT_EQ(std::stod(values[knee]), -angle);
  }
  auto emg = ca.Get("/api/v1/trials/" + std::to_string(first_trial) + "?format=csv&group=emg",
                    {{"Authorization", "Bearer " + admin_a}});
  ASSERT_TRUE(emg);
  ASSERT_EQ(emg->status, 200) << emg->body;
  EXPECT_EQ(emg->body.rfind("t_s,emg_mv\n", 0), 0u) << emg->body.substr(0, 100);
  EXPECT_NE(emg->get_header_value("Content-Disposition").find("-emg.csv"), std::string::npos);

  // A fresh server: the archive into a new session.
  ServerProcess b;
  auto cb = b.Client();
  cb.set_read_timeout(60);
  const std::string admin_b = b.admin_token();
  const std::int64_t session_b = NewSession(cb, admin_b, "IMP-01");
  const std::string import_path = "/api/v1/sessions/" + std::to_string(session_b) + "/trials";

  // Refusals first, each storing nothing.
  auto garbage = PostBytes(cb, import_path, admin_b, "not an archive", "application/zip");
  ASSERT_TRUE(garbage);
  EXPECT_EQ(garbage->status, 400) << garbage->body;
  EXPECT_NE(garbage->body.find("not a zip archive"), std::string::npos) << garbage->body;
  auto truncated = PostBytes(cb, import_path, admin_b, zip->body.substr(0, zip->body.size() / 2),
                             "application/zip");
  ASSERT_TRUE(truncated);
  EXPECT_EQ(truncated->status, 400) << truncated->body;
  auto text = PostBytes(cb, import_path, admin_b, "t_s\n0\n", "text/plain");
  ASSERT_TRUE(text);
  EXPECT_EQ(text->status, 400);
  EXPECT_NE(text->body.find("Content-Type"), std::string::npos);
  auto bad_csv = Call(cb, "POST", import_path, admin_b,
                      {{"spec", {{"kind", "free_swing_passive"}}},
                       {"data", "t_s,angle_deg\n0,90\n0.005,91\n0.005,92\n"}});
  EXPECT_EQ(bad_csv.status, 400);
  EXPECT_NE(bad_csv.body["error"]["message"].get<std::string>().find("line 4, column 1 (t_s)"),
            std::string::npos)
      << bad_csv.text;
  auto bad_spec = Call(cb, "POST", import_path, admin_b,
                       {{"spec", {{"kind", "walking"}}}, {"data", "t_s\n0\n"}});
  EXPECT_EQ(bad_spec.status, 400);
  EXPECT_EQ(bad_spec.body["error"]["field"], "spec.kind");
  // One convention for the spec's fields, whether the spec alone or the spec
  // against the file is wrong.
  auto bad_unit = Call(cb, "POST", import_path, admin_b,
                       {{"spec",
                         {{"kind", "free_swing_passive"},
                          {"columns", {{{"column", "knee"}, {"channel", "angle_deg"},
                                        {"unit", "furlong"}}}}}},
                        {"data", "t_s,knee\n0,90\n0.005,91\n0.01,92\n"}});
  EXPECT_EQ(bad_unit.status, 400);
  EXPECT_EQ(bad_unit.body["error"]["field"], "spec.columns[0].unit") << bad_unit.text;
  auto bad_time = Call(cb, "POST", import_path, admin_b,
                       {{"spec", {{"kind", "free_swing_passive"}, {"time_unit", "ms"}}},
                        {"data", "t_s,angle_deg\n0,90\n0.005,91\n0.01,92\n"}});
  EXPECT_EQ(bad_time.status, 400);
  EXPECT_EQ(bad_time.body["error"]["field"], "spec.time_unit") << bad_time.text;
  auto none = Call(cb, "GET", import_path, admin_b);
  ASSERT_EQ(none.status, 200);
  EXPECT_TRUE(none.body["items"].empty()) << "a refused import stored something";

  auto imported = PostBytes(cb, import_path + "?name=s.zip", admin_b, zip->body, "application/zip");
  ASSERT_TRUE(imported);
  ASSERT_EQ(imported->status, 201) << imported->body.substr(0, 2000);
  const json result = json::parse(imported->body);
  // The same archive again: refused, nothing doubled.
  auto again = PostBytes(cb, import_path, admin_b, tgz->body, "application/gzip");
  ASSERT_TRUE(again);
  EXPECT_EQ(again->status, 409) << again->body;
  EXPECT_NE(again->body.find("already in session"), std::string::npos) << again->body;
  const json original_trials = run["trial_ids"];
  ASSERT_EQ(result["trials"].size(), original_trials.size() + rb["trial_ids"].size());
  std::map<std::int64_t, std::int64_t> ids;
  for (const auto& t : result["trials"]) ids[t["original_id"]] = t["id"];
  // Every trial bit for bit (JSON numbers round-trip exactly), provenance kept.
  for (const auto& [old_id, new_id] : ids) {
    auto ta = Call(ca, "GET", "/api/v1/trials/" + std::to_string(old_id), admin_a);
    auto tb = Call(cb, "GET", "/api/v1/trials/" + std::to_string(new_id), admin_b);
    ASSERT_EQ(ta.status, 200);
    ASSERT_EQ(tb.status, 200);
    EXPECT_EQ(tb.body["import"]["format"], "archive");
    EXPECT_EQ(tb.body["import"]["original_trial_id"], old_id);
    json ja = ta.body, jb = tb.body;
    for (json* j : {&ja, &jb}) {
      j->erase("id");
      j->erase("import");
    }
    EXPECT_EQ(ja, jb) << "trial " << old_id;
  }
  // The run's parameter set came with them.
  ASSERT_GE(result["parameter_sets"].size(), 1u);
  for (const auto& s : result["parameter_sets"]) {
    auto sa =
        Call(ca, "GET", "/api/v1/parameter-sets/" + std::to_string(s["original_id"].get<int>()),
             admin_a);
    auto sb =
        Call(cb, "GET", "/api/v1/parameter-sets/" + std::to_string(s["id"].get<int>()), admin_b);
    ASSERT_EQ(sb.status, 200);
    EXPECT_EQ(MapTrialIds(sa.body["parameters"], ids), sb.body["parameters"]);
  }
  // Identification on the imported trials: the same result.
  const json identified_b = Identify(cb, admin_b, session_b);
  EXPECT_EQ(MapTrialIds(identified_a, ids), identified_b);

  // A recording made elsewhere: the RB trial as CSV with time in ms and the
  // angle in radians, predicted with the imported set like a bench trial.
  const std::int64_t rb_id = rb["trial_ids"][0];
  auto csv = ca.Get("/api/v1/trials/" + std::to_string(rb_id) + "?format=csv",
                    {{"Authorization", "Bearer " + admin_a}});
  ASSERT_TRUE(csv);
  auto table = api::ReadTextTable(csv->body, "csv");
  ASSERT_TRUE(table.ok());
  std::string converted = "time_ms,knee_rad,stim_ma\n";
  const std::size_t t_col =
      std::find(table->labels.begin(), table->labels.end(), "t_s") - table->labels.begin();
  const std::size_t a_col =
      std::find(table->labels.begin(), table->labels.end(), "angle_deg") - table->labels.begin();
  const std::size_t s_col =
      std::find(table->labels.begin(), table->labels.end(), "stim_ma") - table->labels.begin();
  for (std::size_t i = 0; i < table->num_rows(); ++i) {
    converted += std::to_string(table->columns[t_col][i] * 1000.0) + "," +
                 std::to_string(table->columns[a_col][i] * M_PI / 180.0) + "," +
                 std::to_string(table->columns[s_col][i]) + "\n";
  }
  auto recording =
      Call(cb, "POST", import_path, admin_b,
           {{"spec",
             {{"kind", "prediction_random_binary"},
              {"time_column", "time_ms"},
              {"time_unit", "ms"},
              {"sample_rate_hz", 200},
              {"columns", {{{"column", "knee_rad"}, {"channel", "angle_deg"}, {"unit", "rad"}}}},
              {"source", "another rig"},
              {"stops_deg", {10, 110}}}},
            {"data", converted}});
  ASSERT_EQ(recording.status, 201) << recording.text;
  const std::int64_t recording_id = recording.body["trials"][0]["id"];
  auto stored = Call(cb, "GET", "/api/v1/trials/" + std::to_string(recording_id), admin_b);
  EXPECT_EQ(stored.body["import"]["source"], "another rig");
  auto predicted =
      Call(cb, "POST", "/api/v1/predictions", admin_b,
           {{"parameter_set_id", result["parameter_sets"][0]["id"]}, {"trial_id", recording_id}});
  ASSERT_EQ(predicted.status, 202) << predicted.text;
  const json job = WaitForJob(cb, admin_b, predicted.body["id"]);
  ASSERT_EQ(job["state"], "done") << job.dump().substr(0, 1000);
  const double e_rms = job["result"]["errors"]["e_rms"];
  EXPECT_LT(e_rms, 10.0);
  // Predicted within the stops the recording's rig declared.
  EXPECT_EQ(job["result"]["joint_limits"]["min_angle_deg"], 10.0);
  EXPECT_EQ(job["result"]["joint_limits"]["max_angle_deg"], 110.0);
  std::cout << "[ figure ] imported recording predicted with the imported set: E_RMS " << e_rms
            << " deg\n";
  EXPECT_EQ(a.Terminate(), 0);
  EXPECT_EQ(b.Terminate(), 0);
}

// docs/SAFETY.md, which set gates stimulation: the rapid run's set is
// approved by its run; an imported set and an analyst's re-identification
// are candidates that change nothing until a clinician approves one, which
// is audited and switches what the daily check uses; a leg whose only sets
// await approval gets no ungated prediction run.
TEST(DataExchangeTest, OnlyAClinicianApprovedSetGatesStimulation) {
  ServerProcess server;
  auto c = server.Client();
  c.set_read_timeout(60);
  const std::string admin = server.admin_token();
  const std::string clinician = CreateUserToken(c, admin, "cora", "clinician");
  const std::string analyst = CreateUserToken(c, admin, "ana", "analyst");
  const std::int64_t session = NewSession(c, clinician, "APR-01");
  const json rapid = RunToEnd(c, clinician, session, {{"protocol", "rapid_parameterisation"}});
  ASSERT_EQ(rapid["state"], "done") << rapid.dump();
  const std::int64_t rapid_set = rapid["parameter_set_id"];
  const std::int64_t subject_id =
      Call(c, "GET", "/api/v1/sessions/" + std::to_string(session), clinician).body["subject_id"];
  const std::string approved_path =
      "/api/v1/subjects/" + std::to_string(subject_id) + "/legs/right/approved-parameter-set";
  const auto approved_id = [&] {
    auto r = Call(c, "GET", approved_path, analyst);
    EXPECT_EQ(r.status, 200) << r.text;
    EXPECT_EQ(r.body["approved"], true);
    return r.body.value("id", std::int64_t{0});
  };
  auto by_run = Call(c, "GET", approved_path, analyst);
  ASSERT_EQ(by_run.status, 200) << by_run.text;
  EXPECT_EQ(by_run.body["id"], rapid_set);
  EXPECT_EQ(by_run.body["approval"]["run_id"], rapid["run_id"]);
  EXPECT_EQ(by_run.body["approval"]["approved_by"], "cora");

  // A clinician imports the session's archive into another session of the
  // leg: its set is stored, a candidate.
  auto zip = c.Get("/api/v1/sessions/" + std::to_string(session) + "/export",
                   {{"Authorization", "Bearer " + clinician}});
  ASSERT_TRUE(zip);
  ASSERT_EQ(zip->status, 200);
  auto second = Call(
      c, "POST", "/api/v1/subjects/" + std::to_string(subject_id) + "/sessions", clinician,
      {{"leg", "right"}, {"date", "2026-11-26"}, {"threshold_ma", 14}, {"max_tolerated_ma", 45}});
  ASSERT_EQ(second.status, 201) << second.text;
  const std::int64_t second_id = second.body["id"];
  auto imported = PostBytes(c, "/api/v1/sessions/" + std::to_string(second_id) + "/trials",
                            clinician, zip->body, "application/zip");
  ASSERT_TRUE(imported);
  ASSERT_EQ(imported->status, 201) << imported->body.substr(0, 1000);
  const std::int64_t imported_set = json::parse(imported->body)["parameter_sets"][0]["id"];
  auto candidate =
      Call(c, "GET", "/api/v1/parameter-sets/" + std::to_string(imported_set), analyst);
  EXPECT_EQ(candidate.body["approved"], false) << candidate.text;
  EXPECT_TRUE(candidate.body["approval"].is_null());
  EXPECT_EQ(approved_id(), rapid_set) << "an import changed the gating set";

  // An analyst's re-identification: a newer set, still not the gating one.
  auto submitted = Call(c, "POST", "/api/v1/identifications", analyst,
                        {{"session_id", session}, {"method", "rapid"}});
  ASSERT_EQ(submitted.status, 202) << submitted.text;
  const json job = WaitForJob(c, analyst, submitted.body["id"]);
  ASSERT_EQ(job["state"], "done") << job.dump().substr(0, 1000);
  EXPECT_GT(job["result"]["parameter_sets"][0]["id"].get<std::int64_t>(), imported_set);
  EXPECT_EQ(approved_id(), rapid_set) << "a re-identification changed the gating set";

  auto gating = Call(c, "GET", "/api/v1/parameter-sets/" + std::to_string(rapid_set), analyst);
  EXPECT_EQ(gating.body["approved"], true) << gating.text;

  // Only a clinician approves, with a printable note.
  const std::string approve = "/api/v1/parameter-sets/" + std::to_string(imported_set) + "/approve";
  EXPECT_EQ(Call(c, "POST", approve, analyst, {{"note", "looks fine"}}).status, 403);
  auto blank = Call(c, "POST", approve, clinician, {{"note", " "}});
  EXPECT_EQ(blank.status, 400) << blank.text;
  EXPECT_EQ(blank.body["error"]["field"], "note");
  EXPECT_EQ(approved_id(), rapid_set);
  auto approved = Call(c, "POST", approve, clinician, {{"note", "reviewed: rig B's import"}});
  ASSERT_EQ(approved.status, 200) << approved.text;
  EXPECT_EQ(approved.body["approved"], true);
  EXPECT_EQ(approved.body["approval"]["approved_by"], "cora");
  EXPECT_EQ(approved.body["approval"]["note"], "reviewed: rig B's import");
  EXPECT_EQ(approved_id(), imported_set);
  // Both sets were read before the approval (the server keeps approvals
  // between changes): read again, each shows the approval as it now is.
  auto now_approved =
      Call(c, "GET", "/api/v1/parameter-sets/" + std::to_string(imported_set), analyst);
  EXPECT_EQ(now_approved.body["approved"], true) << now_approved.text;
  EXPECT_EQ(now_approved.body["approval"]["note"], "reviewed: rig B's import");
  auto listed = Call(c, "GET", "/api/v1/parameter-sets?subject_id=" + std::to_string(subject_id),
                     analyst);
  ASSERT_EQ(listed.status, 200) << listed.text;
  int approved_listed = 0;
  for (const json& s : listed.body["items"]) {
    if (s["approved"] == true) {
      EXPECT_EQ(s["id"], imported_set);
      ++approved_listed;
    }
  }
  EXPECT_EQ(approved_listed, 1) << listed.text;
  auto earlier = Call(c, "GET", "/api/v1/parameter-sets/" + std::to_string(rapid_set), analyst);
  EXPECT_EQ(earlier.body["approved"], false);
  EXPECT_EQ(earlier.body["approval"]["run_id"], rapid["run_id"]) << "the history stays";
  EXPECT_EQ(Call(c, "POST", approve, clinician, {{"note", "again"}}).status, 409);
  int audited = 0;
  const JsonResponse audit = Call(c, "GET", "/api/v1/audit?limit=500", admin);
  ASSERT_EQ(audit.status, 200);
  for (const json& e : audit.body["items"]) {
    if (e["action"] == "POST " + approve && e["outcome"] == "200") {
      EXPECT_EQ(e["actor"], "cora");
      EXPECT_NE(e["request_summary"].get<std::string>().find("rig B"), std::string::npos);
      ++audited;
    }
    if (e["action"] == "parameter_set.approve") {
      EXPECT_EQ(e["target"], "parameter-sets/" + std::to_string(rapid_set));
      ++audited;
    }
  }
  EXPECT_EQ(audited, 2);

  // The daily check now compares with the approved import.
  const json daily = RunToEnd(c, clinician, second_id, {{"protocol", "daily_check"}});
  ASSERT_EQ(daily["state"], "done") << daily.dump().substr(0, 1000);
  EXPECT_EQ(daily["result"]["base_parameter_set_id"], imported_set);

  // Another subject whose only set is an import: no ungated prediction.
  const std::int64_t other = NewSession(c, clinician, "APR-02");
  auto only = PostBytes(c, "/api/v1/sessions/" + std::to_string(other) + "/trials", clinician,
                        zip->body, "application/zip");
  ASSERT_TRUE(only);
  ASSERT_EQ(only->status, 201);
  auto refused = Call(c, "POST", "/api/v1/sessions/" + std::to_string(other) + "/runs", clinician,
                      {{"protocol", "prediction_step"}});
  EXPECT_EQ(refused.status, 409) << refused.text;
  EXPECT_NE(refused.text.find("no set is approved for the leg"), std::string::npos) << refused.text;
  for (const std::string& protocol : {std::string("tracking"), std::string("daily_check")}) {
    auto needs = Call(c, "POST", "/api/v1/sessions/" + std::to_string(other) + "/runs", clinician,
                      {{"protocol", protocol}});
    EXPECT_EQ(needs.status, 409) << needs.text;
    EXPECT_NE(needs.text.find(protocol + " needs the leg's approved parameter set"),
              std::string::npos)
        << needs.text;
    EXPECT_NE(needs.text.find("/approve"), std::string::npos) << "says how to approve one";
  }
  EXPECT_EQ(server.Terminate(), 0);
}

}  // namespace
}  // namespace fesbench::testing
