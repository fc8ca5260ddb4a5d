#pragma once

/// @file
/// A session's trials laid out after BIDS (Brain Imaging Data Structure,
/// specification v1.11.0: the motion datatype, and the EMG datatype of
/// BEP042), as text files for an archive, and read back bit for bit.
///
/// Per trial, with S the subject label, N the session label, T the task
/// label (the trial kind in camel case) and R the trial's id:
///
///     sub-S/ses-N/motion/sub-S_ses-N_task-T_tracksys-kneebench_run-R_motion.tsv
///         every main channel, one column each, no header row (BIDS motion)
///     ..._channels.tsv   name, component, type, tracked_point, units, description
///     ..._motion.json    SamplingFrequency, TrackingSystemName, TaskName, channel
///                        counts, and FesbenchTrial {id, name, start_time_unix_ms}
///     ..._events.tsv     the delivered stimulation pulses: onset, duration,
///                        trial_type, amplitude_ma, width_us (with a header row)
///     ..._events.json    the columns described; PulseRateHz, PulseWidthUs
///     sub-S/ses-N/emg/sub-S_ses-N_task-T_run-R_emg.tsv   (if the trial has EMG)
///     ..._emg.json, ..._channels.tsv (name, type, units, sampling_frequency)
///
/// Numbers are written in the shortest form that reads back exactly, so a
/// trial read back equals the one written. One deviation from the
/// specification, stated: BIDS v1.11.0 stores EMG data as EDF/BDF; fesbench
/// writes it as TSV like the motion data (lossless float64 text).

#include <cstdint>
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "api/status.h"
#include "api/trial.h"

namespace fesbench::api {

inline constexpr std::string_view kBidsVersion = "1.11.0";

/// Files by path inside a dataset ("sub-01/ses-3/motion/..."); '/' separated.
using FileMap = std::map<std::string, std::string>;

/// A BIDS label: letters and digits only (other characters are dropped;
/// "x" if nothing is left).
std::string BidsLabel(std::string_view text);
/// The task label of a trial name: "free_swing_passive" → "freeSwingPassive".
std::string BidsTaskLabel(std::string_view trial_name);

struct BidsTrialPlace {
  std::string subject_label;  ///< BidsLabel of the subject's pseudonymous code.
  std::string session_label;  ///< e.g. the session id.
  std::string leg;            ///< "left" or "right": the tracked point.
  std::int64_t run = 1;       ///< the trial's id (BIDS run index).
};

/// Adds the files of one trial (above) to `files`. The trial must be valid
/// (ValidateTrial) and named.
void AddBidsTrial(const Trial& trial, const BidsTrialPlace& place, FileMap& files);

/// One trial read back, with the id it had where it was exported.
struct BidsTrial {
  Trial trial;  ///< id unset.
  std::optional<std::int64_t> original_id;
  std::string motion_path;  ///< where it was read from (for messages).
};

/// Reads every trial of a dataset (each *_motion.tsv with its sidecars), in
/// run order. Errors name the file and, inside it, the line and column.
Result<std::vector<BidsTrial>> ReadBidsTrials(const FileMap& files);

/// Checks the files and columns the specification requires, as far as it
/// states them: dataset_description.json (Name, BIDSVersion), a README;
/// per *_motion.tsv a *_channels.tsv whose rows match its columns (columns
/// name, component, type, tracked_point, units; types from the restricted
/// list) and a *_motion.json (SamplingFrequency, TrackingSystemName,
/// TaskName); per *_emg.* a *_emg.json (EMGPlacementScheme, EMGReference,
/// SamplingFrequency, PowerLineFrequency, SoftwareFilters, TaskName) and a
/// *_channels.tsv (name, type, units); per *_events.tsv the columns onset
/// and duration first; every entity label alphanumeric. kInvalidArgument
/// naming the file and what is missing.
Status ValidateBidsLayout(const FileMap& files);

}  // namespace fesbench::api
