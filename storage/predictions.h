#pragma once

/// @file
/// Predictions (a parameter set simulated on a stimulus or a stored trial)
/// and evaluations (errors of a prediction against a measured trial),
/// docs/ARCHITECTURE.md, storage; docs/API.md. Both are immutable records.

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "api/status.h"
#include "storage/database.h"

namespace fesbench::storage {

struct NewPrediction {
  std::int64_t parameter_set_id = 0;
  std::optional<std::int64_t> trial_id;  ///< the trial whose input was replayed, if any.
  std::string input_json = "{}";         ///< the request (stimulus, options); valid JSON.
  std::string output_json = "{}";        ///< the result (e.g. predicted channels); valid JSON.
};

struct Prediction {
  std::int64_t id = 0;
  NewPrediction prediction;
  api::UtcTime created_at;
};

struct NewEvaluation {
  std::int64_t parameter_set_id = 0;
  std::int64_t trial_id = 0;                  ///< the measured trial.
  std::optional<std::int64_t> prediction_id;  ///< the prediction compared, if stored.
  std::string channel;                        ///< e.g. "angle_deg".
  std::string unit;                           ///< unit of the errors, e.g. "deg".
  double rms_error = 0;                       ///< ≥ 0, in `unit`.
  double max_abs_error = 0;                   ///< ≥ 0, in `unit`.
  std::string details_json = "{}";            ///< further statistics; valid JSON.
};

struct Evaluation {
  std::int64_t id = 0;
  NewEvaluation evaluation;
  api::UtcTime created_at;
};

class PredictionRepository {
 public:
  explicit PredictionRepository(Database& db) : db_(db) {}

  /// kNotFound for an unknown parameter set or trial (field named);
  /// kInvalidArgument for invalid JSON.
  api::Result<Prediction> InsertPrediction(const NewPrediction& prediction);
  api::Result<Prediction> GetPrediction(std::int64_t id);
  api::Result<std::vector<Prediction>> PredictionsFor(std::int64_t parameter_set_id);

  /// kNotFound for an unknown parameter set, trial or prediction;
  /// kInvalidArgument for negative or non-finite errors, an empty channel,
  /// invalid JSON, or a prediction of another parameter set.
  api::Result<Evaluation> InsertEvaluation(const NewEvaluation& evaluation);
  api::Result<Evaluation> GetEvaluation(std::int64_t id);
  api::Result<std::vector<Evaluation>> EvaluationsFor(std::int64_t parameter_set_id);

 private:
  Database& db_;
};

}  // namespace fesbench::storage
