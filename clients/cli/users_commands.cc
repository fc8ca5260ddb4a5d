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

#include "api/json_fields.h"
#include "api/time_utc.h"
#include "api/user.h"
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
  for (const api::User& user : client.GetAllPagesOf("/users", "", &api::UserFromJson, "user")) {
    if (user.name == id_or_name) return user.id;
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
  const api::NewTokenRequest request{user_id, form.label, form.expires_in_s};
  std::unique_ptr<SecretFile> file;
  if (!form.out.empty()) file = std::make_unique<SecretFile>(form.out);
  json answer = client.Post("/tokens", api::NewTokenRequestToJson(request));
  const api::IssuedTokenView issued = FromServer(api::IssuedTokenFromJson(answer), "token");
  const std::string& secret = issued.token;
  if (file) {
    file->Write(secret);
    answer.erase("token");
    answer.emplace("out", form.out);
  }
  if (context.options.json) {
    context.out << answer.dump(2) << "\n";
    return;
  }
  context.out << "token " << issued.id << " for user " << user_id << " (expires: "
              << (issued.expires_at ? api::FormatUtc(*issued.expires_at) : "-") << ")\n";
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
      for (const api::User& u : ItemsFromServer(items, &api::UserFromJson, "user")) {
        rows.push_back({Cell(u.id), u.name, std::string(api::RoleName(u.role)),
                        u.active ? "yes" : "no", api::FormatUtc(u.created_at)});
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
        const api::NewUserRequest request{
            form->name, api::ParseRole(form->role).value_or(api::Role::kAnalyst)};
        const json answer = client->Post("/users", api::NewUserRequestToJson(request));
        const api::User user = FromServer(api::UserFromJson(answer), "user");
        if (context.options.json && !form->token) {
          context.out << answer.dump(2) << "\n";
          return;
        }
        if (!context.options.json) {
          context.out << "user " << user.id << " " << user.name << " ("
                      << api::RoleName(user.role) << ")\n";
        }
        if (form->token) IssueToken(context, *client, user.id, form->issue);
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
        const api::User deactivated = FromServer(api::UserFromJson(done), "user");
        context.out << "user " << deactivated.id << " " << deactivated.name << " deactivated\n";
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
        const json items = client->GetAllPages("/tokens", "");
        const std::vector<api::TokenInfo> tokens =
            ItemsFromServer(items, &api::TokenInfoFromJson, "token");
        const std::optional<std::int64_t> only =
            user->empty() ? std::nullopt : std::optional(ResolveUser(*client, *user));
        json kept = json::array();
        std::vector<std::vector<std::string>> rows;
        for (std::size_t i = 0; i < tokens.size(); ++i) {
          const api::TokenInfo& t = tokens[i];
          if (only && t.user_id != *only) continue;
          kept.push_back(items[i]);
          rows.push_back({Cell(t.id), t.user_name, t.label, t.created_at_utc,
                          Cell(api::OrNull(t.expires_at_utc)), t.revoked_at_utc ? "yes" : "no"});
        }
        if (context.options.json) {
          context.out << kept.dump(2) << "\n";
          return;
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
