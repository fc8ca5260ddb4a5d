#pragma once

/// @file
/// Comparison of parameter sets or models across subjects (docs/MODEL.md,
/// "Evaluation"; docs/API.md `comparisons`; thesis §6.1.2, Eq. 6.3, Tables 6.5–6.8):
/// each pair is one subject's leg with two parameter sets (e.g. fitted by
/// two methods, or two model variants) evaluated on the same stored trials
/// of that leg; the per-pair errors (mean over its trials of the chosen
/// metric) enter a paired Student's t-test (model::PairedTTest). Nothing is
/// stored. Thread-safe.

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "api/analysis_requests.h"
#include "api/analysis_results.h"
#include "api/status.h"
#include "model/evaluation.h"
#include "server/services/prediction_service.h"
#include "storage/database.h"

namespace fesbench::server::services {

/// One subject's (leg's) pair: the same trials predicted by set a and set b.
/// The request's wire form (api/analysis_requests.h).
using ComparisonPair = api::ComparisonPair;
using ComparisonRequest = api::ComparisonRequest;

/// The errors of one trial under both sets.
/// The result's wire form (api/analysis_results.h).
using TrialComparison = api::TrialComparison;
using PairComparison = api::PairComparison;
using ComparisonResult = api::ComparisonResult;

/// Checks the request alone: kInvalidArgument naming the field ("pairs"
/// when none, "pairs[1].trial_ids[0]", "metric", "confidence").
api::Status ValidateComparisonRequest(const ComparisonRequest& request);

class ComparisonService {
 public:
  /// `db` must outlive the service; predictions use `config`.
  explicit ComparisonService(storage::Database& db, PredictionConfig config = {});

  /// kNotFound for an unknown set or trial; kInvalidArgument when a pair's
  /// sets or trials belong to different legs, or a trial's mode differs
  /// between pairs' channels; kFailedPrecondition when a metric is
  /// undefined on a trial. One pair, or pairs whose differences are all
  /// equal, give the errors without a t-test (`test` unset, `test_note`).
  api::Result<ComparisonResult> Compare(const ComparisonRequest& request) const;

 private:
  storage::Database& db_;
  PredictionService predictions_;
};

}  // namespace fesbench::server::services
