// `fesbench users list|create|deactivate|tokens|issue-token|revoke-token`:
// an admin's accounts and bearer tokens (docs/API.md, `/users`, `/tokens`).
// A token's secret is in the issuing answer only: `issue-token` prints it
// once (or writes it to a 0600 file) and nothing can show it again.

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
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

// A user by id or by name (looked up in GET /users).
std::int64_t ResolveUser(ApiClient& client, const std::string& id_or_name) {
  if (!id_or_name.empty() && id_or_name.find_first_not_of("0123456789") == std::string::npos) {
    return ParseId(id_or_name, "user");
  }
  for (const auto& user : client.GetAllPages("/users", "")) {
    if (user.value("name", "") == id_or_name) return user["id"].get<std::int64_t>();
  }
  throw CliError::Server("no user named " + id_or_name + " (fesbench users list names them)");
}

// A new file readable by its owner only, for a token's secret; created
// before the token is issued, so a secret is never issued that could not be
// kept. An existing file is refused (a token must not land in a file others
// could have made readable).
class SecretFile {
 public:
  explicit SecretFile(const std::string& path) : path_(path) {
    fd_ = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL, 0600);
    if (fd_ < 0) {
      throw CliError::Server("cannot create " + path + ": " + std::strerror(errno) +
                             " (an existing file is never overwritten)");
    }
  }
  ~SecretFile() {
    if (fd_ >= 0) {
      ::close(fd_);
      ::unlink(path_.c_str());  // nothing was written: no empty token file left
    }
  }
  SecretFile(const SecretFile&) = delete;
  SecretFile& operator=(const SecretFile&) = delete;

  void Write(const std::string& secret) {
    const std::string line = secret + "\n";
    const bool ok = ::write(fd_, line.data(), line.size()) == static_cast<ssize_t>(line.size());
    const bool closed = ::close(fd_) == 0;
    fd_ = -1;
    if (!ok || !closed) throw CliError::Server("cannot write " + path_);
  }

 private:
  std::string path_;
  int fd_ = -1;
};

struct IssueForm {
  std::string user;
  std::string label;
  std::optional<std::int64_t> expires_in_s;
  std::string out;
};

// Issues a token and shows its secret once: on stdout, or in `form.out`.
void IssueToken(CliContext& context, ApiClient& client, std::int64_t user_id,
                const IssueForm& form) {
  json body = {{"user_id", user_id}};
  if (!form.label.empty()) body["label"] = form.label;
  if (form.expires_in_s) body["expires_in_s"] = *form.expires_in_s;
  std::unique_ptr<SecretFile> file;
  if (!form.out.empty()) file = std::make_unique<SecretFile>(form.out);
  json issued = client.Post("/tokens", body);
  const std::string secret = issued.value("token", "");
  if (file) {
    file->Write(secret);
    issued.erase("token");
    issued["out"] = form.out;
  }
  if (context.options.json) {
    context.out << issued.dump(2) << "\n";
    return;
  }
  context.out << "token " << Cell(issued["id"]) << " for user " << user_id
              << " (expires: " << Cell(issued.value("expires_at_utc", json(nullptr))) << ")\n";
  if (form.out.empty()) {
    context.out << secret << "\n"
                << "shown once: the server keeps only its digest\n";
  } else {
    context.out << "written to " << form.out << " (mode 0600); the server keeps only its digest\n";
  }
}

void AddIssueOptions(CLI::App* app, IssueForm& form) {
  app->add_option("--label", form.label, "what the token is for (at most 128 characters)");
  app->add_option("--expires-in-s", form.expires_in_s,
                  "lifetime, seconds (60 s to 10 years; default: no expiry)");
  app->add_option("--out", form.out,
                  "write the secret to this new file (mode 0600) instead of standard output");
}

struct CreateForm {
  std::string name;
  std::string role;
  bool token = false;
  IssueForm issue;
};

}  // namespace

void RegisterUserCommands(CLI::App& app, CliContext& context) {
  CLI::App* users = app.add_subcommand(
      "users", "Users and their tokens (admin): list, create, deactivate, tokens, issue-token, "
               "revoke-token.");
  users->require_subcommand(1);

  users->add_subcommand("list", "Every user: id, name, role, active.")->callback([&context] {
    context.action = [&context] {
      auto client = Connect(context);
      const json items = client->GetAllPages("/users", "");
      if (context.options.json) {
        context.out << items.dump(2) << "\n";
        return;
      }
      std::vector<std::vector<std::string>> rows;
      for (const auto& u : items) {
        rows.push_back({Cell(u["id"]), Cell(u["name"]), Cell(u["role"]),
                        u.value("active", false) ? "yes" : "no", Cell(u["created_at_utc"])});
      }
      PrintTable(context.out, {"id", "name", "role", "active", "created_at_utc"}, rows);
    };
  });

  {
    auto form = std::make_shared<CreateForm>();
    CLI::App* create = users->add_subcommand(
        "create", "Create a user; --token also issues their first token (shown once).");
    create->add_option("name", form->name, "user name (1-64 characters)")->required();
    create->add_option("--role", form->role, "clinician, analyst or admin")
        ->required()
        ->check(CLI::IsMember({"clinician", "analyst", "admin"}));
    create->add_flag("--token", form->token, "issue a token for the new user at once");
    AddIssueOptions(create, form->issue);
    create->callback([form, &context] {
      context.action = [form, &context] {
        if (!form->token && (!form->issue.label.empty() || form->issue.expires_in_s ||
                             !form->issue.out.empty())) {
          throw CliError::Usage("--label, --expires-in-s and --out need --token");
        }
        auto client = Connect(context);
        const json user = client->Post("/users", {{"name", form->name}, {"role", form->role}});
        if (!form->token) {
          if (context.options.json) {
            context.out << user.dump(2) << "\n";
          } else {
            context.out << "user " << Cell(user["id"]) << " " << Cell(user["name"]) << " ("
                        << Cell(user["role"]) << ")\n";
          }
          return;
        }
        if (!context.options.json) {
          context.out << "user " << Cell(user["id"]) << " " << Cell(user["name"]) << " ("
                      << Cell(user["role"]) << ")\n";
        }
        IssueToken(context, *client, user["id"].get<std::int64_t>(), form->issue);
      };
    });
  }

  {
    auto user = std::make_shared<std::string>();
    auto reason = std::make_shared<std::string>();
    CLI::App* deactivate = users->add_subcommand(
        "deactivate", "Deactivate a user: every token of theirs stops working.");
    deactivate->add_option("user", *user, "user id or name")->required();
    deactivate->add_option("--reason", *reason, "why (audited)")->required();
    deactivate->callback([user, reason, &context] {
      context.action = [user, reason, &context] {
        auto client = Connect(context);
        const std::int64_t id = ResolveUser(*client, *user);
        const json done =
            client->Post("/users/" + std::to_string(id) + "/deactivate", {{"reason", *reason}});
        if (context.options.json) {
          context.out << done.dump(2) << "\n";
          return;
        }
        context.out << "user " << Cell(done["id"]) << " " << Cell(done["name"])
                    << " deactivated\n";
      };
    });
  }

  {
    auto user = std::make_shared<std::string>();
    CLI::App* tokens =
        users->add_subcommand("tokens", "Tokens (metadata only: a secret is never shown again).");
    tokens->add_option("--user", *user, "only this user's (id or name)");
    tokens->callback([user, &context] {
      context.action = [user, &context] {
        auto client = Connect(context);
        json items = client->GetAllPages("/tokens", "");
        if (!user->empty()) {
          const std::int64_t id = ResolveUser(*client, *user);
          json kept = json::array();
          for (auto& t : items) {
            if (t.value("user_id", std::int64_t{0}) == id) kept.push_back(std::move(t));
          }
          items = std::move(kept);
        }
        if (context.options.json) {
          context.out << items.dump(2) << "\n";
          return;
        }
        std::vector<std::vector<std::string>> rows;
        for (const auto& t : items) {
          rows.push_back({Cell(t["id"]), Cell(t["user_name"]), Cell(t["label"]),
                          Cell(t["created_at_utc"]), Cell(t["expires_at_utc"]),
                          t.value("revoked", false) ? "yes" : "no"});
        }
        PrintTable(context.out,
                   {"id", "user", "label", "created_at_utc", "expires_at_utc", "revoked"}, rows);
      };
    });
  }

  {
    auto form = std::make_shared<IssueForm>();
    CLI::App* issue = users->add_subcommand(
        "issue-token", "Issue a bearer token for a user; its secret is shown once.");
    issue->add_option("user", form->user, "user id or name")->required();
    AddIssueOptions(issue, *form);
    issue->callback([form, &context] {
      context.action = [form, &context] {
        auto client = Connect(context);
        IssueToken(context, *client, ResolveUser(*client, form->user), *form);
      };
    });
  }

  {
    auto token = std::make_shared<std::string>();
    CLI::App* revoke =
        users->add_subcommand("revoke-token", "Revoke a token (by its id, `users tokens`).");
    revoke->add_option("token_id", *token, "token id")->required();
    revoke->callback([token, &context] {
      context.action = [token, &context] {
        const std::int64_t id = ParseId(*token, "token");
        auto client = Connect(context);
        const json done = client->Delete("/tokens/" + std::to_string(id));
        if (context.options.json) {
          context.out << done.dump(2) << "\n";
          return;
        }
        context.out << "token " << id << " revoked\n";
      };
    });
  }
}

}  // namespace fesbench::cli
