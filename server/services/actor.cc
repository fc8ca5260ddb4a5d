#include "server/services/actor.h"

namespace fesbench::server::services {

Actor SystemActor() { return Actor{0, "system", Role::kAdmin}; }

bool MayOperateBench(const Actor& actor) {
  return actor.role == Role::kClinician || actor.role == Role::kAdmin;
}

}  // namespace fesbench::server::services
