// `fesbench subjects list|show|create|edit` and `sessions
// list|show|create|edit`: the records a clinician keeps (docs/ARCHITECTURE.md,
// "Storage"; docs/API.md).
// `edit` records a correction as a new revision with a reason (docs/API.md, "Corrections").

#include <memory>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include "api/json_fields.h"
#include "api/run.h"
#include "api/session.h"
#include "api/subject.h"
#include "api/time_utc.h"
#include "api/trial_summary.h"
#include "clients/cli/commands.h"
#include "clients/cli/output.h"

namespace fesbench::cli {

namespace {

using nlohmann::json;

void PrintSubjects(CliContext& context, const std::vector<api::Subject>& subjects) {
  std::vector<std::vector<std::string>> rows;
  for (const api::Subject& s : subjects) {
    std::string legs;
    for (const api::SubjectLeg& leg : s.legs) {
      legs += (legs.empty() ? "" : ",") + std::string(api::SideName(leg.side));
    }
    rows.push_back({Cell(s.id), s.code, legs.empty() ? "-" : legs,
                    std::string(api::SexName(s.details.sex)),
                    Cell(api::OrNull(s.details.age_years)), api::FormatUtc(s.created_at)});
  }
  PrintTable(context.out, {"id", "code", "legs", "sex", "age_years", "created_at_utc"}, rows);
}

void PrintSessions(CliContext& context, const std::vector<api::Session>& sessions) {
  std::vector<std::vector<std::string>> rows;
  for (const api::Session& s : sessions) {
    const api::SessionDetails& d = s.details;
    rows.push_back({Cell(s.id), Cell(s.subject_id), std::string(api::SideName(s.leg)), d.date,
                    Cell(api::OrNull(d.threshold_ma)), Cell(api::OrNull(d.max_tolerated_ma)),
                    d.notes});
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

  // The given flags into `details` (--sex is checked against the wire's names).
  void AddTo(api::SubjectDetails& details) const {
    if (age_years) details.age_years = *age_years;
    if (sex) details.sex = api::ParseSex(*sex).value_or(api::Sex::kUndisclosed);
    if (height_cm) details.height_cm = *height_cm;
    if (weight_kg) details.weight_kg = *weight_kg;
    if (shank_length_cm) details.shank_length_cm = *shank_length_cm;
    if (calf_circumference_cm) details.calf_circumference_cm = *calf_circumference_cm;
    if (rom_min_deg) details.rom_min_deg = *rom_min_deg;
    if (rom_max_deg) details.rom_max_deg = *rom_max_deg;
  }

  // The wire names of the given flags.
  std::vector<std::string> Given() const {
    std::vector<std::string> given;
    if (age_years) given.push_back("age_years");
    if (sex) given.push_back("sex");
    if (height_cm) given.push_back("height_cm");
    if (weight_kg) given.push_back("weight_kg");
    if (shank_length_cm) given.push_back("shank_length_cm");
    if (calf_circumference_cm) given.push_back("calf_circumference_cm");
    if (rom_min_deg) given.push_back("rom_min_deg");
    if (rom_max_deg) given.push_back("rom_max_deg");
    return given;
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
template <typename Record>
void PrintCorrected(CliContext& context, const std::string& what, const json& answer,
                    api::Result<Record> (*from)(const json&), json (*details_to_json)(
                        const decltype(Record::details)&)) {
  if (context.options.json) {
    context.out << answer.dump(2) << "\n";
    return;
  }
  const Record record = FromServer(from(answer), what);
  context.out << what << " " << record.id << " corrected: revision " << record.revision << "\n";
  PrintObject(context.out, details_to_json(record.details));
}

template <typename Revision>
void PrintRevisions(CliContext& context, const std::vector<Revision>& revisions) {
  std::vector<std::vector<std::string>> rows;
  for (const Revision& r : revisions) {
    rows.push_back({Cell(r.revision), api::FormatUtc(r.changed_at), Cell(api::OrNull(r.changed_by)),
                    r.reason});
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
            PrintSubjects(context, ItemsFromServer(items, &api::SubjectFromJson, "subject"));
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
        const json revisions = PageItems(client->Get(path + "/revisions"), path + "/revisions");
        if (context.options.json) {
          subject.update(json{{"revisions", revisions}});
          context.out << subject.dump(2) << "\n";
          return;
        }
        PrintObject(context.out, subject);
        PrintRevisions(context,
                       ItemsFromServer(revisions, &api::SubjectRevisionFromJson, "revision"));
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
        api::NewSubjectRequest request;
        request.code = form->code;
        for (const std::string& leg : form->legs) {
          request.legs.push_back(api::ParseSide(leg).value_or(api::Side::kRight));
        }
        form->details.AddTo(request.details);
        auto client = Connect(context);
        const json created = client->Post("/subjects", api::NewSubjectRequestToJson(request));
        if (context.options.json) {
          context.out << created.dump(2) << "\n";
        } else {
          const api::Subject subject = FromServer(api::SubjectFromJson(created), "subject");
          context.out << "created subject " << subject.id << " (" << subject.code << ")\n";
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
        api::CorrectionRequest<api::SubjectDetails> request{form->reason, {}, {}, form->clear};
        form->details.AddTo(request.details);
        request.set = form->details.Given();
        if (request.set.empty() && request.clear.empty()) {
          throw CliError::Usage("name at least one field to correct");
        }
        auto client = Connect(context);
        const std::int64_t id = ResolveSubject(*client, form->subject);
        PrintCorrected(context, "subject",
                       client->Patch("/subjects/" + std::to_string(id),
                                     api::CorrectionRequestToJson(request,
                                                                  &api::SubjectDetailsToJson)),
                       &api::SubjectFromJson, &api::SubjectDetailsToJson);
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
          PrintSessions(context, ItemsFromServer(items, &api::SessionFromJson, "session"));
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
        const json head = client->Get(path);
        const json runs_json = client->GetAllPages(path + "/runs", "");
        const json trials_json = client->GetAllPages(path + "/trials", "");
        const json revisions_json =
            PageItems(client->Get(path + "/revisions"), path + "/revisions");
        if (context.options.json) {
          json session = head;
          session.update(
              json{{"runs", runs_json}, {"trials", trials_json}, {"revisions", revisions_json}});
          context.out << session.dump(2) << "\n";
          return;
        }
        // The current values first: what the protocols are scaled to.
        const api::Session session = FromServer(api::SessionFromJson(head), "session");
        const api::SessionDetails& d = session.details;
        context.out << "session " << session.id << " (subject " << session.subject_id << ", "
                    << api::SideName(session.leg) << " leg, " << d.date << "), revision "
                    << session.revision << "\n"
                    << "threshold_ma: " << Cell(api::OrNull(d.threshold_ma)) << "\n"
                    << "max_tolerated_ma: " << Cell(api::OrNull(d.max_tolerated_ma)) << "\n";
        PrintObject(context.out, head);
        PrintRevisions(context,
                       ItemsFromServer(revisions_json, &api::SessionRevisionFromJson, "revision"));
        std::vector<std::vector<std::string>> runs;
        for (const api::RunView& r : ItemsFromServer(runs_json, &api::RunViewFromJson, "run")) {
          runs.push_back({Cell(r.run_id), r.protocol, std::string(api::RunStateName(r.state)),
                          r.started_at ? api::FormatUtc(*r.started_at) : "-", Cell(r.reason)});
        }
        context.out << "runs:\n";
        PrintTable(context.out, {"run_id", "protocol", "state", "started_at_utc", "reason"}, runs);
        std::vector<std::vector<std::string>> trials;
        for (const api::TrialSummary& t :
             ItemsFromServer(trials_json, &api::TrialSummaryFromJson, "trial")) {
          trials.push_back({Cell(t.id), Cell(api::OrNull(t.run_id)), Cell(api::OrNull(t.name)),
                            Cell(t.num_samples), Cell(t.sample_rate_hz)});
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
        api::NewSessionRequest request;
        request.leg = api::ParseSide(form->leg).value_or(api::Side::kRight);
        request.details.date = form->date;
        request.details.threshold_ma = form->threshold_ma;
        request.details.max_tolerated_ma = form->max_tolerated_ma;
        request.details.notes = form->notes.value_or("");
        request.details.accelerometer_placement = form->placement.value_or("");
        auto client = Connect(context);
        const std::int64_t subject = ResolveSubject(*client, form->subject);
        const json created = client->Post("/subjects/" + std::to_string(subject) + "/sessions",
                                          api::NewSessionRequestToJson(request));
        if (context.options.json) {
          context.out << created.dump(2) << "\n";
        } else {
          const api::Session session = FromServer(api::SessionFromJson(created), "session");
          context.out << "created session " << session.id << " (subject " << session.subject_id
                      << ", " << api::SideName(session.leg) << " leg, " << session.details.date
                      << ")\n";
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
        api::CorrectionRequest<api::SessionDetails> request{form->reason, {}, {}, form->clear};
        api::SessionDetails& d = request.details;
        if (form->date) request.set.push_back("date");
        d.date = form->date.value_or("");
        if (form->threshold_ma) request.set.push_back("threshold_ma");
        d.threshold_ma = form->threshold_ma;
        if (form->max_tolerated_ma) request.set.push_back("max_tolerated_ma");
        d.max_tolerated_ma = form->max_tolerated_ma;
        if (form->notes) request.set.push_back("notes");
        d.notes = form->notes.value_or("");
        if (form->placement) request.set.push_back("accelerometer_placement");
        d.accelerometer_placement = form->placement.value_or("");
        if (request.set.empty() && request.clear.empty()) {
          throw CliError::Usage("name at least one field to correct");
        }
        auto client = Connect(context);
        PrintCorrected(
            context, "session",
            client->Patch("/sessions/" + std::to_string(ParseId(form->session, "session")),
                          api::CorrectionRequestToJson(request, &api::SessionDetailsToJson)),
            &api::SessionFromJson, &api::SessionDetailsToJson);
      };
    });
  }
}

}  // namespace fesbench::cli
