#include "server/services/stored_trials.h"

#include <stdexcept>
#include <vector>

#include "storage/sessions.h"
#include "storage/trials.h"

namespace fesbench::server::services {

api::Result<LoadedTrial> LoadTrial(storage::Database& db, std::int64_t trial_id) {
  return db.Read([&](storage::Connection&) -> api::Result<LoadedTrial> {
    storage::TrialRepository trials(db);
    api::Result<api::Trial> trial = trials.Get(trial_id);
    if (!trial.ok()) return trial.status();
    api::Result<storage::TrialOwner> owner = trials.Owner(trial_id);
    if (!owner.ok()) return owner.status();
    api::Result<storage::Session> session = storage::SessionRepository(db).Get(owner->session_id);
    if (!session.ok()) return session.status();
    LoadedTrial out;
    out.id = trial_id;
    out.session_id = session->id;
    out.subject_id = session->subject_id;
    out.leg_id = session->leg_id;
    out.trial = std::move(trial).value();
    return out;
  });
}

api::Status ModelFailure(std::string_view what, const std::exception& e,
                         api::ErrorCode invalid_code) {
  const bool invalid = dynamic_cast<const std::invalid_argument*>(&e) != nullptr;
  return api::Status(invalid ? invalid_code : api::ErrorCode::kFailedPrecondition,
                     std::string(what) + ": " + e.what());
}

}  // namespace fesbench::server::services
