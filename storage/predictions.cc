#include "storage/predictions.h"

#include <cmath>
#include <nlohmann/json.hpp>

#include "storage/row_helpers.h"

namespace fesbench::storage {
namespace {

api::Status RequireField(Connection& c, std::string_view sql, std::int64_t id,
                         std::string_view what, std::string field) {
  return internal::WithField(internal::RequireRow(c, sql, id, what), std::move(field));
}

api::Result<std::vector<Prediction>> QueryPredictions(Connection& c, std::string_view where,
                                                      std::int64_t id) {
  return internal::QueryRows(
      c,
      "SELECT id, parameter_set_id, trial_id, input_json, output_json, created_at_utc"
      " FROM predictions " +
          std::string(where) + " ORDER BY id",
      [](const Statement& s) -> api::Result<Prediction> {
        Prediction p;
        p.id = s.Int64(0);
        p.prediction.parameter_set_id = s.Int64(1);
        p.prediction.trial_id = s.OptionalInt64(2);
        p.prediction.input_json = s.Text(3);
        p.prediction.output_json = s.Text(4);
        const auto created = api::ParseUtc(s.Text(5));
        if (!created) return internal::BadStoredValue("prediction");
        p.created_at = *created;
        return p;
      },
      id);
}

api::Result<std::vector<Evaluation>> QueryEvaluations(Connection& c, std::string_view where,
                                                      std::int64_t id) {
  return internal::QueryRows(
      c,
      "SELECT id, parameter_set_id, trial_id, prediction_id, channel, unit, rms_error,"
      " max_abs_error, details_json, created_at_utc FROM evaluations " +
          std::string(where) + " ORDER BY id",
      [](const Statement& s) -> api::Result<Evaluation> {
        Evaluation e;
        e.id = s.Int64(0);
        e.evaluation.parameter_set_id = s.Int64(1);
        e.evaluation.trial_id = s.Int64(2);
        e.evaluation.prediction_id = s.OptionalInt64(3);
        e.evaluation.channel = s.Text(4);
        e.evaluation.unit = s.Text(5);
        e.evaluation.rms_error = s.Double(6);
        e.evaluation.max_abs_error = s.Double(7);
        e.evaluation.details_json = s.Text(8);
        const auto created = api::ParseUtc(s.Text(9));
        if (!created) return internal::BadStoredValue("evaluation");
        e.created_at = *created;
        return e;
      },
      id);
}

using internal::One;

}  // namespace

api::Result<Prediction> PredictionRepository::InsertPrediction(const NewPrediction& p) {
  if (!nlohmann::json::accept(p.input_json)) {
    return api::Status::InvalidArgument("input_json is not valid JSON", "input_json");
  }
  if (!nlohmann::json::accept(p.output_json)) {
    return api::Status::InvalidArgument("output_json is not valid JSON", "output_json");
  }
  return db_.Write([&](Connection& c) -> api::Result<Prediction> {
    if (auto s = RequireField(c, "SELECT 1 FROM parameter_sets WHERE id = ?1", p.parameter_set_id,
                              "parameter set", "parameter_set_id");
        !s.ok()) {
      return s;
    }
    if (p.trial_id) {
      if (auto s = RequireField(c, "SELECT 1 FROM trials WHERE id = ?1", *p.trial_id, "trial",
                                "trial_id");
          !s.ok()) {
        return s;
      }
    }
    auto id = internal::InsertRow(
        c,
        "INSERT INTO predictions (parameter_set_id, trial_id, input_json, output_json,"
        " created_at_utc) VALUES (?1, ?2, ?3, ?4, ?5)",
        p.parameter_set_id, p.trial_id, p.input_json, p.output_json, api::FormatUtc(db_.Now()));
    if (!id.ok()) return id.status();
    return One(QueryPredictions(c, "WHERE id = ?1", *id), "prediction", *id);
  });
}

api::Result<Prediction> PredictionRepository::GetPrediction(std::int64_t id) {
  return db_.Read([&](Connection& c) {
    return One(QueryPredictions(c, "WHERE id = ?1", id), "prediction", id);
  });
}

api::Result<std::vector<Prediction>> PredictionRepository::PredictionsFor(
    std::int64_t parameter_set_id) {
  return db_.Read([&](Connection& c) -> api::Result<std::vector<Prediction>> {
    if (auto s = internal::RequireRow(c, "SELECT 1 FROM parameter_sets WHERE id = ?1",
                                      parameter_set_id, "parameter set");
        !s.ok()) {
      return s;
    }
    return QueryPredictions(c, "WHERE parameter_set_id = ?1", parameter_set_id);
  });
}

api::Result<Evaluation> PredictionRepository::InsertEvaluation(const NewEvaluation& e) {
  if (e.channel.empty())
    return api::Status::InvalidArgument("channel must not be empty", "channel");
  if (!std::isfinite(e.rms_error) || e.rms_error < 0) {
    return api::Status::InvalidArgument("rms_error must be finite and >= 0", "rms_error");
  }
  if (!std::isfinite(e.max_abs_error) || e.max_abs_error < 0) {
    return api::Status::InvalidArgument("max_abs_error must be finite and >= 0", "max_abs_error");
  }
  if (!nlohmann::json::accept(e.details_json)) {
    return api::Status::InvalidArgument("details_json is not valid JSON", "details_json");
  }
  return db_.Write([&](Connection& c) -> api::Result<Evaluation> {
    if (auto s = RequireField(c, "SELECT 1 FROM parameter_sets WHERE id = ?1", e.parameter_set_id,
                              "parameter set", "parameter_set_id");
        !s.ok()) {
      return s;
    }
    if (auto s =
            RequireField(c, "SELECT 1 FROM trials WHERE id = ?1", e.trial_id, "trial", "trial_id");
        !s.ok()) {
      return s;
    }
    if (e.prediction_id) {
      auto prediction = One(QueryPredictions(c, "WHERE id = ?1", *e.prediction_id), "prediction",
                            *e.prediction_id);
      if (!prediction.ok()) return internal::WithField(prediction.status(), "prediction_id");
      if (prediction->prediction.parameter_set_id != e.parameter_set_id) {
        return api::Status::InvalidArgument(
            "prediction " + std::to_string(*e.prediction_id) + " is of another parameter set",
            "prediction_id");
      }
    }
    auto id = internal::InsertRow(
        c,
        "INSERT INTO evaluations (parameter_set_id, trial_id, prediction_id, channel, unit,"
        " rms_error, max_abs_error, details_json, created_at_utc)"
        " VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9)",
        e.parameter_set_id, e.trial_id, e.prediction_id, e.channel, e.unit, e.rms_error,
        e.max_abs_error, e.details_json, api::FormatUtc(db_.Now()));
    if (!id.ok()) return id.status();
    return One(QueryEvaluations(c, "WHERE id = ?1", *id), "evaluation", *id);
  });
}

api::Result<Evaluation> PredictionRepository::GetEvaluation(std::int64_t id) {
  return db_.Read([&](Connection& c) {
    return One(QueryEvaluations(c, "WHERE id = ?1", id), "evaluation", id);
  });
}

api::Result<std::vector<Evaluation>> PredictionRepository::EvaluationsFor(
    std::int64_t parameter_set_id) {
  return db_.Read([&](Connection& c) -> api::Result<std::vector<Evaluation>> {
    if (auto s = internal::RequireRow(c, "SELECT 1 FROM parameter_sets WHERE id = ?1",
                                      parameter_set_id, "parameter set");
        !s.ok()) {
      return s;
    }
    return QueryEvaluations(c, "WHERE parameter_set_id = ?1", parameter_set_id);
  });
}

}  // namespace fesbench::storage
