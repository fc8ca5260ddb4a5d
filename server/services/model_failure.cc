#include "server/services/model_failure.h"

#include <stdexcept>
#include <string>

namespace fesbench::server::services {

api::Status ModelFailure(std::string_view what, const std::exception& e,
                         api::ErrorCode invalid_code) {
  const bool invalid = dynamic_cast<const std::invalid_argument*>(&e) != nullptr;
  return api::Status(invalid ? invalid_code : api::ErrorCode::kFailedPrecondition,
                     std::string(what) + ": " + e.what());
}

}  // namespace fesbench::server::services
