#pragma once

/// @file
/// Helpers shared by the analysis services: stored trials as identification
/// columns with the subject and leg they belong to, and the one place where
/// an exception from model/ becomes a Status (nothing throws past a service).

#include <cstdint>
#include <exception>
#include <string>
#include <string_view>

#include "api/status.h"
#include "api/trial.h"
#include "model/identify_common.h"
#include "model/signal.h"
#include "storage/database.h"

namespace fesbench::server::services {

/// A stored trial with its owner.
struct LoadedTrial {
  std::int64_t id = 0;
  std::int64_t session_id = 0;
  std::int64_t subject_id = 0;
  std::int64_t leg_id = 0;
  api::Trial trial;
};

/// Loads trial `trial_id` and its session's subject and leg, in one read
/// transaction. kNotFound ("trial <id>") for an unknown trial.
api::Result<LoadedTrial> LoadTrial(storage::Database& db, std::int64_t trial_id);

/// The pulses that drove a stored trial, on a time axis starting at its first
/// sample (t_s[0] = 0), as predictions replay them (docs/MODEL.md): the
/// delivered pulses it stores (trial.pulses), else those the pulse clock
/// makes of its `stim_ma` channel (model::PulsesFromEnvelope at
/// `default_rate_hz`, the continuous grid from the first sample).
/// `pulse_rate_hz` receives the rate of the pulses' weights R(u)/f: the
/// stored record's, else default_rate_hz.
/// @throws std::invalid_argument for columns PulsesFromEnvelope rejects.
model::PulseTrain TrialStimulation(const api::Trial& trial, const model::TrialColumns& columns,
                                   double default_rate_hz, double& pulse_rate_hz);

}  // namespace fesbench::server::services
