#include "storage/export.h"

#include "api/trial.h"
#include "storage/parameter_sets.h"
#include "storage/trials.h"

namespace fesbench::storage {

api::Result<std::string> ExportTrialCsv(Database& db, std::int64_t trial_id) {
  auto trial = TrialRepository(db).Get(trial_id);
  if (!trial.ok()) return trial.status();
  return api::TrialToCsv(*trial);
}

api::Result<std::string> ExportTrialSto(Database& db, std::int64_t trial_id) {
  auto trial = TrialRepository(db).Get(trial_id);
  if (!trial.ok()) return trial.status();
  return api::TrialToSto(*trial);
}

api::Result<std::string> ExportParameterSetJson(Database& db, std::int64_t parameter_set_id) {
  return ParameterSetRepository(db).ExportJson(parameter_set_id);
}

}  // namespace fesbench::storage
