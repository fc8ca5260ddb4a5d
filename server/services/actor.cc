#include "server/services/actor.h"

namespace fesbench::server::services {

std::string_view RoleName(Role role) {
  switch (role) {
    case Role::kClinician:
      return "clinician";
    case Role::kAnalyst:
      return "analyst";
    case Role::kAdmin:
      return "admin";
  }
  return "clinician";
}

std::optional<Role> ParseRole(std::string_view name) {
  if (name == "clinician") return Role::kClinician;
  if (name == "analyst") return Role::kAnalyst;
  if (name == "admin") return Role::kAdmin;
  return std::nullopt;
}

Actor SystemActor() { return Actor{0, "system", Role::kAdmin}; }

bool MayOperateBench(const Actor& actor) {
  return actor.role == Role::kClinician || actor.role == Role::kAdmin;
}

}  // namespace fesbench::server::services
