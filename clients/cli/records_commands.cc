// `fesbench subjects list|show|create|edit` and `sessions
// list|show|create|edit`: the records a clinician keeps (docs/ARCHITECTURE.md,
// "Storage"; docs/API.md).
// `edit` records a correction as a new revision with a reason (docs/API.md, "Corrections").

#include <memory>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include "clients/cli/commands.h"
#include "clients/cli/output.h"

namespace fesbench::cli {

namespace {

using nlohmann::json;

void PrintSubjects(CliContext& context, const json& items) {
  std::vector<std::vector<std::string>> rows;
  for (const auto& s : items) {
    std::string legs;
    for (const auto& leg : s["legs"]) legs += (legs.empty() ? "" : ",") + Cell(leg["side"]);
    rows.push_back({Cell(s["id"]), Cell(s["code"]), legs.empty() ? "-" : legs,
                    Cell(s["details"].value("sex", json(nullptr))),
                    Cell(s["details"].value("age_years", json(nullptr))),
                    Cell(s["created_at_utc"])});
  }
  PrintTable(context.out, {"id", "code", "legs", "sex", "age_years", "created_at_utc"}, rows);
}

void PrintSessions(CliContext& context, const json& items) {
  std::vector<std::vector<std::string>> rows;
  for (const auto& s : items) {
    const json& d = s["details"];
    rows.push_back({Cell(s["id"]), Cell(s["subject_id"]), Cell(s["leg"]), Cell(s["date"]),
                    Cell(d.value("threshold_ma", json(nullptr))),
                    Cell(d.value("max_tolerated_ma", json(nullptr))), Cell(d.value("notes", ""))});
  }
  PrintTable(context.out,
             {"id", "subject_id", "leg", "date", "threshold_ma", "max_tolerated_ma", "notes"},
             rows);
}

// A subject's details as flags, shared by `subjects create` and `edit`.
struct SubjectDetailsFlags {
  std::optional<int> age_years;
  std::optional<std::string> sex;
  std::optional<double> height_cm, weight_kg, shank_length_cm, calf_circumference_cm;
  std::optional<double> rom_min_deg, rom_max_deg;

  void Register(CLI::App* app) {
    app->add_option("--age-years", age_years, "age, years (0-130)");
    app->add_option("--age", age_years, "old spelling of --age-years")->group("");
    app->add_option("--sex", sex, "female, male, other or undisclosed")
        ->check(CLI::IsMember({"female", "male", "other", "undisclosed"}));
    app->add_option("--height-cm", height_cm, "height, cm (30-250)");
    app->add_option("--weight-kg", weight_kg, "body mass, kg (1-400)");
    app->add_option("--shank-length-cm", shank_length_cm,
                    "shank length, cm (10-80; femoral condyle to medial malleolus)");
    app->add_option("--calf-circumference-cm", calf_circumference_cm,
                    "calf circumference, cm (10-100)");
    app->add_option("--rom-min-deg", rom_min_deg,
                    "range of motion, extension end, deg (-30 to 60; hyperextension negative)");
    app->add_option("--rom-max-deg", rom_max_deg, "range of motion, flexion end, deg (60-180)");
  }

  // The given flags into `details` (API field names).
  void AddTo(json& details) const {
    if (age_years) details["age_years"] = *age_years;
    if (sex) details["sex"] = *sex;
    if (height_cm) details["height_cm"] = *height_cm;
    if (weight_kg) details["weight_kg"] = *weight_kg;
    if (shank_length_cm) details["shank_length_cm"] = *shank_length_cm;
    if (calf_circumference_cm) details["calf_circumference_cm"] = *calf_circumference_cm;
    if (rom_min_deg) details["rom_min_deg"] = *rom_min_deg;
    if (rom_max_deg) details["rom_max_deg"] = *rom_max_deg;
  }
};

struct SubjectForm {
  std::string code;
  std::vector<std::string> legs;
  SubjectDetailsFlags details;
};

// A correction: --reason and the fields to change; "--clear FIELD" clears one.
struct SubjectEditForm {
  std::string subject;
  std::string reason;
  std::vector<std::string> clear;
  SubjectDetailsFlags details;
};

struct SessionEditForm {
  std::string session;
  std::string reason;
  std::vector<std::string> clear;
  std::optional<std::string> date, notes, placement;
  std::optional<double> threshold_ma, max_tolerated_ma;
};

// Prints a correction's result: the revision and the current details.
void PrintCorrected(CliContext& context, const std::string& what, const json& record) {
  if (context.options.json) {
    context.out << record.dump(2) << "\n";
    return;
  }
  context.out << what << " " << Cell(record["id"]) << " corrected: revision "
              << Cell(record["revision"]) << "\n";
  PrintObject(context.out, record["details"]);
}

void PrintRevisions(CliContext& context, const json& items) {
  std::vector<std::vector<std::string>> rows;
  for (const auto& r : items) {
    rows.push_back({Cell(r["revision"]), Cell(r["changed_at_utc"]),
                    Cell(r.value("changed_by", json(nullptr))), Cell(r["reason"])});
  }
  context.out << "revisions:\n";
  PrintTable(context.out, {"revision", "changed_at_utc", "changed_by", "reason"}, rows);
}

struct SessionForm {
  std::string subject;
  std::string leg;
  std::string date;
  std::optional<double> threshold_ma, max_tolerated_ma;
  std::optional<std::string> notes, placement;
};

}  // namespace

void RegisterRecordCommands(CLI::App& app, CliContext& context) {
  // --- subjects ---------------------------------------------------------------
  CLI::App* subjects = app.add_subcommand("subjects", "Subjects: list, show, create, edit.");
  subjects->require_subcommand(1);
  subjects->add_subcommand("list", "List every subject (a table, or --json).")
      ->callback([&context] {
        context.action = [&context] {
          auto client = Connect(context);
          const json items = client->GetAllPages("/subjects", "");
          if (context.options.json) {
            context.out << items.dump(2) << "\n";
          } else {
            PrintSubjects(context, items);
          }
        };
      });
  {
    auto id = std::make_shared<std::string>();
    CLI::App* show = subjects->add_subcommand("show", "One subject (by id or code).");
    show->add_option("subject", *id, "subject id or code")->required();
    show->callback([id, &context] {
      context.action = [id, &context] {
        auto client = Connect(context);
        const std::string path = "/subjects/" + std::to_string(ResolveSubject(*client, *id));
        json subject = client->Get(path);
        const json revisions = client->Get(path + "/revisions")["items"];
        if (context.options.json) {
          subject["revisions"] = revisions;
          context.out << subject.dump(2) << "\n";
          return;
        }
        PrintObject(context.out, subject);
        PrintRevisions(context, revisions);
      };
    });
  }
  {
    auto form = std::make_shared<SubjectForm>();
    CLI::App* create = subjects->add_subcommand("create", "Create a subject (clinician or admin).");
    create->add_option("code", form->code, "pseudonymous code, [A-Za-z0-9_-]{1,32}")->required();
    create->add_option("--leg", form->legs, "a leg to record (left, right; repeatable)")
        ->check(CLI::IsMember({"left", "right"}));
    form->details.Register(create);
    create->callback([form, &context] {
      context.action = [form, &context] {
        json details = json::object();
        form->details.AddTo(details);
        json body = {{"code", form->code}, {"legs", form->legs}};
        if (!details.empty()) body["details"] = details;
        auto client = Connect(context);
        const json created = client->Post("/subjects", body);
        if (context.options.json) {
          context.out << created.dump(2) << "\n";
        } else {
          context.out << "created subject " << Cell(created["id"]) << " (" << Cell(created["code"])
                      << ")\n";
        }
      };
    });
  }

  {
    auto form = std::make_shared<SubjectEditForm>();
    CLI::App* edit = subjects->add_subcommand(
        "edit", "Correct a subject's details: a new revision with a reason (clinician or admin).");
    edit->add_option("subject", form->subject, "subject id or code")->required();
    edit->add_option("--reason", form->reason, "why the record is corrected")->required();
    form->details.Register(edit);
    edit->add_option("--clear", form->clear, "a field to clear (repeatable), e.g. height_cm")
        ->check(CLI::IsMember({"age_years", "sex", "height_cm", "weight_kg", "shank_length_cm",
                               "calf_circumference_cm", "rom_min_deg", "rom_max_deg"}));
    edit->callback([form, &context] {
      context.action = [form, &context] {
        json details = json::object();
        for (const std::string& field : form->clear) details[field] = nullptr;
        form->details.AddTo(details);
        if (details.empty()) throw CliError::Usage("name at least one field to correct");
        auto client = Connect(context);
        const std::int64_t id = ResolveSubject(*client, form->subject);
        PrintCorrected(context, "subject",
                       client->Patch("/subjects/" + std::to_string(id),
                                     {{"reason", form->reason}, {"details", details}}));
      };
    });
  }

  // --- sessions ---------------------------------------------------------------
  CLI::App* sessions = app.add_subcommand("sessions", "Sessions: list, show, create, edit.");
  sessions->require_subcommand(1);
  {
    auto subject = std::make_shared<std::string>();
    CLI::App* list = sessions->add_subcommand("list", "A subject's sessions.");
    list->add_option("--subject", *subject, "subject id or code")->required();
    list->callback([subject, &context] {
      context.action = [subject, &context] {
        auto client = Connect(context);
        const std::int64_t id = ResolveSubject(*client, *subject);
        const json items = client->GetAllPages("/subjects/" + std::to_string(id) + "/sessions", "");
        if (context.options.json) {
          context.out << items.dump(2) << "\n";
        } else {
          PrintSessions(context, items);
        }
      };
    });
  }
  {
    auto id = std::make_shared<std::string>();
    CLI::App* show = sessions->add_subcommand("show", "One session with its runs and trials.");
    show->add_option("session", *id, "session id")->required();
    show->callback([id, &context] {
      context.action = [id, &context] {
        const std::string path = "/sessions/" + std::to_string(ParseId(*id, "session"));
        auto client = Connect(context);
        json session = client->Get(path);
        session["runs"] = client->GetAllPages(path + "/runs", "");
        session["trials"] = client->GetAllPages(path + "/trials", "");
        session["revisions"] = client->Get(path + "/revisions")["items"];
        if (context.options.json) {
          context.out << session.dump(2) << "\n";
          return;
        }
        // The current values first: what the protocols are scaled to.
        const json& d = session["details"];
        context.out << "session " << Cell(session["id"]) << " (subject "
                    << Cell(session["subject_id"]) << ", " << Cell(session["leg"]) << " leg, "
                    << Cell(session["date"]) << "), revision " << Cell(session["revision"]) << "\n"
                    << "threshold_ma: " << Cell(d.value("threshold_ma", json(nullptr))) << "\n"
                    << "max_tolerated_ma: " << Cell(d.value("max_tolerated_ma", json(nullptr)))
                    << "\n";
        json head = session;
        head.erase("runs");
        head.erase("trials");
        head.erase("revisions");
        PrintObject(context.out, head);
        PrintRevisions(context, session["revisions"]);
        std::vector<std::vector<std::string>> runs;
        for (const auto& r : session["runs"]) {
          runs.push_back({Cell(r["run_id"]), Cell(r["protocol"]), Cell(r["state"]),
                          Cell(r["started_at_utc"]), Cell(r["reason"])});
        }
        context.out << "runs:\n";
        PrintTable(context.out, {"run_id", "protocol", "state", "started_at_utc", "reason"}, runs);
        std::vector<std::vector<std::string>> trials;
        for (const auto& t : session["trials"]) {
          trials.push_back({Cell(t["id"]), Cell(t["run_id"]), Cell(t["name"]),
                            Cell(t["num_samples"]), Cell(t["sample_rate_hz"])});
        }
        context.out << "trials:\n";
        PrintTable(context.out, {"id", "run_id", "name", "num_samples", "sample_rate_hz"}, trials);
      };
    });
  }
  {
    auto form = std::make_shared<SessionForm>();
    CLI::App* create =
        sessions->add_subcommand("create", "Open a session for one leg (clinician or admin).");
    create->add_option("--subject", form->subject, "subject id or code")->required();
    create->add_option("--leg", form->leg, "left or right")
        ->required()
        ->check(CLI::IsMember({"left", "right"}));
    create->add_option("--date", form->date, "session date YYYY-MM-DD")->required();
    create->add_option("--threshold-ma", form->threshold_ma, "torque threshold, mA (0-100)");
    create->add_option("--max-tolerated-ma", form->max_tolerated_ma,
                       "maximum tolerated stimulation, mA (0-100)");
    create->add_option("--notes", form->notes, "free text");
    create->add_option("--accelerometer-placement", form->placement, "free text");
    create->callback([form, &context] {
      context.action = [form, &context] {
        json body = {{"leg", form->leg}, {"date", form->date}};
        if (form->threshold_ma) body["threshold_ma"] = *form->threshold_ma;
        if (form->max_tolerated_ma) body["max_tolerated_ma"] = *form->max_tolerated_ma;
        if (form->notes) body["notes"] = *form->notes;
        if (form->placement) body["accelerometer_placement"] = *form->placement;
        auto client = Connect(context);
        const std::int64_t subject = ResolveSubject(*client, form->subject);
        const json created =
            client->Post("/subjects/" + std::to_string(subject) + "/sessions", body);
        if (context.options.json) {
          context.out << created.dump(2) << "\n";
        } else {
          context.out << "created session " << Cell(created["id"]) << " (subject "
                      << Cell(created["subject_id"]) << ", " << Cell(created["leg"]) << " leg, "
                      << Cell(created["date"]) << ")\n";
        }
      };
    });
  }
  {
    auto form = std::make_shared<SessionEditForm>();
    CLI::App* edit = sessions->add_subcommand(
        "edit", "Correct a session's details: a new revision with a reason (clinician or admin).");
    edit->add_option("session", form->session, "session id")->required();
    edit->add_option("--reason", form->reason, "why the record is corrected")->required();
    edit->add_option("--date", form->date, "session date YYYY-MM-DD");
    edit->add_option("--threshold-ma", form->threshold_ma, "torque threshold, mA (0-100)");
    edit->add_option("--max-tolerated-ma", form->max_tolerated_ma,
                     "maximum tolerated stimulation, mA (0-100)");
    edit->add_option("--notes", form->notes, "free text");
    edit->add_option("--accelerometer-placement", form->placement, "free text");
    edit->add_option("--clear", form->clear, "a field to clear (repeatable), e.g. notes")
        ->check(CLI::IsMember(
            {"threshold_ma", "max_tolerated_ma", "notes", "accelerometer_placement"}));
    edit->callback([form, &context] {
      context.action = [form, &context] {
        json details = json::object();
        for (const std::string& field : form->clear) details[field] = nullptr;
        if (form->date) details["date"] = *form->date;
        if (form->threshold_ma) details["threshold_ma"] = *form->threshold_ma;
        if (form->max_tolerated_ma) details["max_tolerated_ma"] = *form->max_tolerated_ma;
        if (form->notes) details["notes"] = *form->notes;
        if (form->placement) details["accelerometer_placement"] = *form->placement;
        if (details.empty()) throw CliError::Usage("name at least one field to correct");
        auto client = Connect(context);
        PrintCorrected(
            context, "session",
            client->Patch("/sessions/" + std::to_string(ParseId(form->session, "session")),
                          {{"reason", form->reason}, {"details", details}}));
      };
    });
  }
}

}  // namespace fesbench::cli
