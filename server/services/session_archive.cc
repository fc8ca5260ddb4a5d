#include "server/services/session_archive.h"

#include <archive.h>
#include <archive_entry.h>

#include <algorithm>
#include <charconv>
#include <chrono>
#include <map>
#include <memory>
#include <set>

#include "api/json_fields.h"
#include "api/parameter_set_json.h"
#include "api/trial_kind.h"
#include "storage/parameter_sets.h"
#include "storage/predictions.h"
#include "storage/sessions.h"
#include "storage/subjects.h"
#include "api/time_utc.h"
#include "storage/trials.h"

namespace fesbench::server::services {
namespace {

using nlohmann::json;

struct ArchiveDeleter {
  void operator()(archive* a) const {
    if (a != nullptr) archive_write_free(a);
  }
};
struct EntryDeleter {
  void operator()(archive_entry* e) const { archive_entry_free(e); }
};

la_ssize_t AppendToString(archive*, void* client, const void* buffer, size_t length) {
  static_cast<std::string*>(client)->append(static_cast<const char*>(buffer), length);
  return static_cast<la_ssize_t>(length);
}

std::string ArchiveError(archive* a) {
  const char* message = archive_error_string(a);
  return message != nullptr ? message : "unknown archive error";
}

std::string ReadmeText(std::int64_t session_id, const std::string& subject_label) {
  const std::string id = std::to_string(session_id);
  const std::string ses = "sub-" + subject_label + "/ses-" + id;
  return "# fesbench session " + id +
         "\n\n"
         "Exported by fesbench: the trials of one session as a BIDS v" +
         std::string(api::kBidsVersion) +
         " dataset (motion datatype), with what BIDS\nhas no field for in the derivative "
         "`derivatives/fesbench/`.\n\n"
         "## Layout\n\n"
         "- `dataset_description.json`, `participants.tsv`: the dataset and its one "
         "participant,\n  `sub-" +
         subject_label +
         "` (the subject's pseudonymous code; no other identifying data).\n"
         "- `" +
         ses + "/sub-" + subject_label + "_ses-" + id +
         "_scans.tsv`: every data file and the UTC time its trial started.\n"
         "- `" +
         ses +
         "/motion/*_tracksys-kneebench_run-R_motion.tsv`: one trial (R is its "
         "fesbench id),\n  one column per channel and no header row; `*_channels.tsv` names the "
         "columns in order\n  with their units; `*_motion.json` gives the sampling frequency.\n"
         "- `" +
         ses +
         "/motion/*_events.tsv`: the stimulation pulses as delivered (onset s, "
         "amplitude_ma,\n  width_us); `*_events.json` describes the columns.\n"
         "- `derivatives/fesbench/" +
         ses +
         "/motion/*_trial.json`: the trial's name, id, start "
         "and pulse\n  clock (and, for a hardware stimulator, what the device was told and "
         "when);\n  `*_motion.mot`: the knee for OpenSim (`knee_angle_r`/`_l`, flexion "
         "negative, degrees).\n"
         "- `derivatives/fesbench/" +
         ses +
         "/emg/*_emg.edf`: EMG as EDF+ with its BIDS "
         "(BEP042) sidecars;\n  `*_desc-float64_emg.tsv`: the same samples exactly. (The "
         "validator of this\n  export's BIDS version does not know the emg datatype yet.)\n"
         "- `derivatives/fesbench/session.json`: subject, leg and session values "
         "(max tolerated amplitude, ...).\n"
         "- `derivatives/fesbench/runs.json`: every run, its protocol, parameters, states "
         "and reason.\n"
         "- `derivatives/fesbench/parameter_sets/paramset-<id>.json`: each parameter set "
         "identified\n  from these trials (docs/MODEL.md JSON under `parameter_set`).\n"
         "- `derivatives/fesbench/predictions.tsv`: each prediction of those sets on these "
         "trials\n  with its errors (e_rms, e_abs); `predictions/prediction-<id>.json` each "
         "whole;\n  `evaluations.json` the stored evaluations.\n\n"
         "Numbers are written in the shortest form that reads back exactly. Importing this "
         "archive\ninto a session (`fesbench trials import --session ID FILE`) reproduces "
         "the trials bit for bit.\n\n"
         "## Loading it (Python, pandas)\n\n"
         "    import pandas as pd\n"
         "    ch = pd.read_csv(prefix + '_channels.tsv', sep='\\t')\n"
         "    data = pd.read_csv(prefix + '_motion.tsv', sep='\\t', header=None, "
         "names=ch['name'])\n";
}

// A parameter set as the archive holds it (session_archive.h layout).
struct ArchivedSet {
  std::int64_t original_id = 0;
  std::optional<std::int64_t> supersedes_id;
  std::optional<api::UtcTime> created_at;
  model::ParameterSet params;
};

// A refusal inside the archive's file `path`: "path: field: message".
api::Status InFile(const std::string& path, const api::Status& s) {
  return api::Status::InvalidArgument(
      path + ": " + (s.field().empty() ? "" : s.field() + ": ") + s.message(), s.field());
}

// One derivatives/fesbench/parameter_sets/paramset-<id>.json, read
// strictly: {id, version, created_at, supersedes_id, parameter_set} as
// SessionExportFiles writes it, nothing else.
api::Result<ArchivedSet> ReadArchivedSet(const std::string& path, const std::string& text) {
  auto j = api::ParseJsonObject(text);
  if (!j.ok()) return InFile(path, j.status());
  api::JsonFields fields(*j);
  ArchivedSet set;
  const std::optional<std::int64_t> id = fields.Integer("id", true, 1);
  (void)fields.Integer("version", false, 1);
  const std::optional<std::string> created_at = fields.String("created_at", false);
  set.supersedes_id = fields.Integer("supersedes_id", false, 1);
  const json* params = fields.Object("parameter_set", true);
  if (api::Status s = fields.Finish(); !s.ok()) return InFile(path, s);
  set.original_id = *id;
  if (created_at) {
    set.created_at = api::ParseUtc(*created_at);
    if (!set.created_at) {
      return InFile(path, api::Status::InvalidArgument("must be a UTC time such as "
                                                       "2026-11-25T10:00:00.000000Z",
                                                       "created_at"));
    }
  }
  auto read = api::ParameterSetFromJson(*params);
  if (!read.ok()) {
    const std::string& field = read.status().field();
    return InFile(path, api::Status::InvalidArgument(
                            read.status().message(),
                            field.empty() ? "parameter_set" : "parameter_set." + field));
  }
  set.params = std::move(*read);
  return set;
}

std::string AcqTime(std::optional<std::int64_t> start_ms) {
  if (!start_ms) return "n/a";
  std::string t =
      api::FormatUtc(api::UtcTime(std::chrono::milliseconds(*start_ms)));  // ...ffffffZ
  if (!t.empty() && t.back() == 'Z') t.pop_back();
  return t;
}

std::string Number(const json& j) {
  if (!j.is_number()) return "n/a";
  char buffer[32];
  const double v = j.get<double>();
  const auto [ptr, ec] = std::to_chars(buffer, buffer + sizeof buffer, v);
  return ec == std::errc() ? std::string(buffer, ptr) : "n/a";
}

std::string Text(const json& j, const char* key) {
  return j.is_object() && j.contains(key) && j[key].is_string() ? j[key].get<std::string>() : "n/a";
}

// The predictions of the session's parameter sets on its trials, and the
// evaluations of those sets on them (session_archive.h layout): a table of
// their errors, and each prediction whole.
api::Status AddPredictions(storage::Database& db, const std::vector<std::int64_t>& set_ids,
                           const std::set<std::int64_t>& trial_ids, api::FileMap& files) {
  const std::string dir = std::string(api::kBidsDerivatives);
  storage::PredictionRepository repo(db);
  std::string table =
      "prediction_id\tparameter_set_id\ttrial_id\tcreated_at\tchannel\tunit\te_rms\te_abs\n";
  json evaluations = json::array();
  for (std::int64_t set_id : set_ids) {
    auto predictions = repo.PredictionsFor(set_id);
    if (!predictions.ok()) return predictions.status();
    for (const storage::Prediction& p : *predictions) {
      if (!p.prediction.trial_id || !trial_ids.contains(*p.prediction.trial_id)) continue;
      const json input = json::parse(p.prediction.input_json, nullptr, false);
      const json output = json::parse(p.prediction.output_json, nullptr, false);
      const json errors = output.is_object() ? output.value("errors", json::object()) : json();
      table += std::to_string(p.id) + "\t" + std::to_string(set_id) + "\t" +
               std::to_string(*p.prediction.trial_id) + "\t" + api::FormatUtc(p.created_at) +
               "\t" + Text(errors, "channel") + "\t" + Text(errors, "unit") + "\t" +
               Number(errors.value("e_rms", json())) + "\t" +
               Number(errors.value("e_abs", json())) + "\n";
      files[dir + "predictions/prediction-" + std::to_string(p.id) + ".json"] =
          json{{"id", p.id},
               {"parameter_set_id", set_id},
               {"trial_id", *p.prediction.trial_id},
               {"created_at", api::FormatUtc(p.created_at)},
               {"input", input.is_discarded() ? json(nullptr) : input},
               {"output", output.is_discarded() ? json(nullptr) : output}}
              .dump(2) +
          "\n";
    }
    auto evaluated = repo.EvaluationsFor(set_id);
    if (!evaluated.ok()) return evaluated.status();
    for (const storage::Evaluation& e : *evaluated) {
      if (!trial_ids.contains(e.evaluation.trial_id)) continue;
      const json details = json::parse(e.evaluation.details_json, nullptr, false);
      evaluations.push_back(
          {{"id", e.id},
           {"parameter_set_id", set_id},
           {"trial_id", e.evaluation.trial_id},
           {"prediction_id",
            e.evaluation.prediction_id ? json(*e.evaluation.prediction_id) : json(nullptr)},
           {"channel", e.evaluation.channel},
           {"unit", e.evaluation.unit},
           {"rms_error", e.evaluation.rms_error},
           {"max_abs_error", e.evaluation.max_abs_error},
           {"details", details.is_discarded() ? json(nullptr) : details},
           {"created_at", api::FormatUtc(e.created_at)}});
    }
  }
  files[dir + "predictions.tsv"] = std::move(table);
  files[dir + "evaluations.json"] = evaluations.dump(2) + "\n";
  return api::Status::Ok();
}

}  // namespace

std::optional<ArchiveFormat> ParseArchiveFormat(std::string_view name) {
  if (name == "zip") return ArchiveFormat::kZip;
  if (name == "tar.gz" || name == "tgz") return ArchiveFormat::kTarGz;
  return std::nullopt;
}

std::string_view ArchiveFormatName(ArchiveFormat format) {
  return format == ArchiveFormat::kZip ? "zip" : "tar.gz";
}

std::string_view ArchiveMediaType(ArchiveFormat format) {
  return format == ArchiveFormat::kZip ? "application/zip" : "application/gzip";
}

api::Result<std::string> PackArchive(const api::FileMap& files, ArchiveFormat format,
                                     std::string_view root) {
  std::unique_ptr<archive, ArchiveDeleter> a(archive_write_new());
  if (!a) return api::Status::Internal("libarchive: out of memory");
  if (format == ArchiveFormat::kZip) {
    archive_write_set_format_zip(a.get());
  } else {
    archive_write_set_format_pax_restricted(a.get());
    archive_write_add_filter_gzip(a.get());
  }
  archive_write_set_bytes_in_last_block(a.get(), 1);  // no padding after the data
  std::string out;
  if (archive_write_open(a.get(), &out, nullptr, AppendToString, nullptr) != ARCHIVE_OK) {
    return api::Status::Internal("archive: " + ArchiveError(a.get()));
  }
  const auto now = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
  for (const auto& [path, content] : files) {
    std::unique_ptr<archive_entry, EntryDeleter> entry(archive_entry_new());
    const std::string full = std::string(root) + "/" + path;
    archive_entry_set_pathname(entry.get(), full.c_str());
    archive_entry_set_size(entry.get(), static_cast<la_int64_t>(content.size()));
    archive_entry_set_filetype(entry.get(), AE_IFREG);
    archive_entry_set_perm(entry.get(), 0644);
    archive_entry_set_mtime(entry.get(), now, 0);
    if (archive_write_header(a.get(), entry.get()) != ARCHIVE_OK ||
        archive_write_data(a.get(), content.data(), content.size()) !=
            static_cast<la_ssize_t>(content.size())) {
      return api::Status::Internal("archive: " + ArchiveError(a.get()));
    }
  }
  if (archive_write_close(a.get()) != ARCHIVE_OK) {
    return api::Status::Internal("archive: " + ArchiveError(a.get()));
  }
  return out;
}

api::Result<api::FileMap> SessionExportFiles(storage::Database& db, const SessionExportInfo& info) {
  auto session = storage::SessionRepository(db).Get(info.session_id);
  if (!session.ok()) return session.status();
  storage::SubjectRepository subjects(db);
  auto subject = subjects.Get(session->subject_id);
  if (!subject.ok()) return subject.status();
  auto leg = subjects.GetLeg(session->leg_id);
  if (!leg.ok()) return leg.status();
  const std::string subject_label = api::BidsLabel(subject->code);
  const std::string session_label = std::to_string(info.session_id);
  const std::string leg_side(storage::SideName(leg->side));

  api::FileMap files;
  files["README.md"] = ReadmeText(info.session_id, subject_label);
  const json generated_by = json::array(
      {{{"Name", "fesbench"},
        {"Version", info.software_version},
        {"Description", "FES knee bench: trials, muscle-model identification, prediction"}}});
  files["dataset_description.json"] = json{{"Name", "fesbench session " + session_label},
                                           {"BIDSVersion", api::kBidsVersion},
                                           {"DatasetType", "raw"},
                                           {"GeneratedBy", generated_by}}
                                          .dump(2) +
                                      "\n";
  const json details = info.subject.value("details", json::object());
  auto field = [&](const char* key) {
    return details.contains(key) && !details[key].is_null()
               ? (details[key].is_string() ? details[key].get<std::string>() : details[key].dump())
               : std::string("n/a");
  };
  files["participants.tsv"] = "participant_id\tage\tsex\theight\tweight\nsub-" + subject_label +
                              "\t" + field("age_years") + "\t" + field("sex") + "\t" +
                              field("height_cm") + "\t" + field("weight_kg") + "\n";
  files["participants.json"] =
      json{{"age", {{"Description", "age at the session"}, {"Units", "year"}}},
           {"sex", {{"Description", "female, male, other or undisclosed"}}},
           {"height", {{"Description", "body height"}, {"Units", "cm"}}},
           {"weight", {{"Description", "body mass"}, {"Units", "kg"}}}}
          .dump(2) +
      "\n";

  storage::TrialRepository trials(db);
  auto summaries = trials.ListForSession(info.session_id);
  if (!summaries.ok()) return summaries.status();
  const std::string session_dir = "sub-" + subject_label + "/ses-" + session_label + "/";
  std::string scans = "filename\tacq_time\n";
  std::set<std::int64_t> trial_ids;
  for (const storage::TrialSummary& summary : *summaries) {
    trial_ids.insert(summary.id);
    auto trial = trials.Get(summary.id);
    if (!trial.ok()) return trial.status();
    if (!trial->name) trial->name = "trial";
    api::FileMap trial_files;
    api::AddBidsTrial(*trial, {subject_label, session_label, leg_side, summary.id}, trial_files);
    for (auto& [path, content] : trial_files) {
      if (path.ends_with("_motion.tsv")) {
        scans += path.substr(session_dir.size()) + "\t" + AcqTime(trial->start_time_unix_ms) + "\n";
      }
      files[path] = std::move(content);
    }
  }
  files[session_dir + "sub-" + subject_label + "_ses-" + session_label + "_scans.tsv"] = scans;

  const std::string derivatives = "derivatives/fesbench/";
  files[derivatives + "dataset_description.json"] =
      json{{"Name", "fesbench session " + session_label + ": parameter sets and run log"},
           {"BIDSVersion", api::kBidsVersion},
           {"DatasetType", "derivative"},
           {"GeneratedBy", generated_by}}
          .dump(2) +
      "\n";
  files[derivatives + "session.json"] =
      json{{"subject", info.subject}, {"leg", leg_side}, {"session", info.session}}.dump(2) + "\n";
  files[derivatives + "runs.json"] = info.runs.dump(2) + "\n";
  storage::ParameterSetRepository sets(db);
  auto set_ids = sets.IdsForSession(info.session_id);
  if (!set_ids.ok()) return set_ids.status();
  if (api::Status s = AddPredictions(db, *set_ids, trial_ids, files); !s.ok()) return s;
  for (std::int64_t id : *set_ids) {
    auto set = sets.Get(id);
    if (!set.ok()) return set.status();
    json j = {{"id", id},
              {"version", set->summary.version},
              {"created_at", api::FormatUtc(set->summary.created_at)},
              {"supersedes_id",
               set->summary.supersedes_id ? json(*set->summary.supersedes_id) : json(nullptr)},
              {"parameter_set", api::ParameterSetToJson(set->params)}};
    files[derivatives + "parameter_sets/paramset-" + std::to_string(id) + ".json"] =
        j.dump(2) + "\n";
  }
  return files;
}

api::Result<ImportResult> ImportRecording(storage::Database& db, std::int64_t session_id,
                                          std::string_view text, const api::ImportSpec& spec,
                                          std::string_view imported_by) {
  api::Result<api::Trial> trial = api::ImportTrialText(text, spec);
  if (!trial.ok()) {
    // One convention for the whole request: a spec field is "spec.<field>".
    const api::Status& s = trial.status();
    if (s.field().empty() || s.field().starts_with("spec")) return s;
    return api::Status(s.code(), s.message(), "spec." + s.field());
  }
  storage::TrialImport provenance{spec.format, spec.source, api::ImportSpecToJson(spec).dump(),
                                  std::string(imported_by), std::nullopt};
  auto id = storage::TrialRepository(db).Insert({session_id, std::nullopt}, *trial, provenance);
  if (!id.ok()) return id.status();
  ImportResult result;
  result.trials.push_back({*id, std::nullopt, spec.kind});
  return result;
}

api::Result<ImportResult> ImportArchive(storage::Database& db, std::int64_t session_id,
                                        const api::FileMap& files, std::string_view archive_name,
                                        std::string_view imported_by) {
  api::Result<std::vector<api::BidsTrial>> read = api::ReadBidsTrials(files);
  if (!read.ok()) return read.status();
  if (read->empty()) {
    return api::Status::InvalidArgument(
        "the archive holds no trial (no sub-*/ses-*/motion/*_motion.tsv file)");
  }
  for (const api::BidsTrial& t : *read) {
    if (api::Status s = api::ValidateTrialKindName(t.trial.name.value_or(""), "name"); !s.ok()) {
      return api::Status::InvalidArgument(t.motion_path + ": " + s.message());
    }
  }
  // Parameter sets, read before anything is written.
  std::vector<ArchivedSet> archived_sets;
  const std::string prefix = "derivatives/fesbench/parameter_sets/";
  for (const auto& [path, text] : files) {
    if (!path.starts_with(prefix) || !path.ends_with(".json")) continue;
    auto set = ReadArchivedSet(path, text);
    if (!set.ok()) return set.status();
    archived_sets.push_back(std::move(*set));
  }
  std::sort(
      archived_sets.begin(), archived_sets.end(),
      [](const ArchivedSet& a, const ArchivedSet& b) { return a.original_id < b.original_id; });

  auto session = storage::SessionRepository(db).Get(session_id);
  if (!session.ok()) return session.status();
  ImportResult result;
  // An archive imported twice into one session would double its trials.
  auto already = storage::TrialRepository(db).ImportedOriginals(session_id);
  if (!already.ok()) return already.status();
  for (const api::BidsTrial& t : *read) {
    if (!t.original_id) continue;
    if (const auto it = already->find(*t.original_id); it != already->end()) {
      return api::Status::Conflict(
          "trial " + std::to_string(*t.original_id) + " of this archive is already in session " +
          std::to_string(session_id) + " as trial " + std::to_string(it->second) +
          " (imported before); import it into another session");
    }
  }
  api::Status status = db.Write([&](storage::Connection&) -> api::Status {
    storage::TrialRepository trials(db);
    std::map<std::int64_t, std::int64_t> trial_ids;  // original → new
    for (const api::BidsTrial& t : *read) {
      storage::TrialImport provenance{"archive", std::string(archive_name), "{}",
                                      std::string(imported_by), t.original_id};
      auto id = trials.Insert({session_id, std::nullopt}, t.trial, provenance);
      if (!id.ok())
        return api::Status::InvalidArgument(t.motion_path + ": " + id.status().message());
      if (t.original_id) trial_ids[*t.original_id] = *id;
      result.trials.push_back({*id, t.original_id, t.trial.name.value_or("")});
    }
    storage::ParameterSetRepository sets(db);
    std::map<std::int64_t, std::int64_t> set_ids;
    for (ArchivedSet& set : archived_sets) {
      model::Provenance& p = set.params.provenance;
      std::string missing;
      for (std::int64_t& id : p.trial_ids) {
        const auto it = trial_ids.find(id);
        if (it == trial_ids.end()) {
          missing = std::to_string(id);
          break;
        }
        id = it->second;
      }
      if (missing.empty() && p.active_trial_id) {
        const auto it = trial_ids.find(*p.active_trial_id);
        if (it == trial_ids.end()) {
          missing = std::to_string(*p.active_trial_id);
        } else {
          p.active_trial_id = it->second;
        }
      }
      if (!missing.empty()) {
        result.notes.push_back("parameter set " + std::to_string(set.original_id) +
                               " left out: its trial " + missing + " is not in the archive");
        continue;
      }
      storage::NewParameterSet fresh{session->subject_id, session->leg_id, set.params, std::nullopt,
                                     set.created_at};
      if (set.supersedes_id) {
        const auto it = set_ids.find(*set.supersedes_id);
        if (it != set_ids.end()) fresh.supersedes_id = it->second;
      }
      auto stored = sets.Insert(fresh);
      if (!stored.ok()) return stored.status();
      set_ids[set.original_id] = stored->id;
      result.parameter_sets.push_back(
          {stored->id, set.original_id, std::string(model::ModelKindName(set.params.model))});
    }
    return api::Status::Ok();
  });
  if (!status.ok()) return status;
  return result;
}

}  // namespace fesbench::server::services
