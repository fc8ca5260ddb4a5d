#pragma once

/// @file
/// A session's trials laid out after BIDS (Brain Imaging Data Structure,
/// specification v1.11.0: the motion datatype, and the EMG datatype of
/// BEP042), for an archive, and read back bit for bit (docs/API.md
/// "Session archives").
///
/// Per trial, with S the subject label, N the session label, T the task
/// label (the trial kind in camel case) and R the trial's id; D is the
/// derivative, derivatives/fesbench/:
///
///     sub-S/ses-N/motion/sub-S_ses-N_task-T_tracksys-kneebench_run-R_motion.tsv
///         every main channel, one column each, no header row (BIDS motion)
///     ..._channels.tsv   name, component, type, tracked_point, units, description
///     ..._motion.json    SamplingFrequency, TrackingSystemName, TaskName,
///                        channel counts (BIDS fields only)
///     ..._events.tsv     the delivered stimulation pulses: onset, duration,
///                        trial_type, amplitude_ma, width_us (with a header row)
///     ..._events.json    the columns described
///     D/sub-S/ses-N/motion/..._trial.json   {name, id, start_time_unix_ms,
///                        pulses {pulse_rate_hz, pulse_width_us}, device_commands}
///     D/sub-S/ses-N/motion/..._motion.mot   the knee for OpenSim (TrialToOpenSimMotion)
///     D/sub-S/ses-N/emg/sub-S_ses-N_task-T_run-R_emg.edf   (if the trial has EMG)
///     ..._emg.json, ..._channels.tsv        its BEP042 sidecars (EmgToEdf)
///     ..._desc-float64_emg.tsv, ..._desc-float64_channels.tsv
///                        the exact EMG samples, t_s first, which an import reads
///
/// Numbers are written in the shortest form that reads back exactly, so a
/// trial read back equals the one written. The EMG stays in the derivative
/// because bids-validator 1.15.0 predates the emg datatype.

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "api/status.h"
#include "api/trial.h"

namespace fesbench::api {

inline constexpr std::string_view kBidsVersion = "1.11.0";

/// Where a dataset's fesbench derivative lies: what no BIDS field holds.
inline constexpr std::string_view kBidsDerivatives = "derivatives/fesbench/";

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

/// The group with its knee channels as OpenSim's gait models name them:
/// angle_deg becomes knee_angle_r (knee_angle_l for the left leg) and
/// velocity_deg_s knee_angle_r_speed, both negated (flexion negative);
/// other channels unchanged.
ChannelGroup ToOpenSimCoordinates(ChannelGroup group, std::string_view leg);

/// The trial's knee as an OpenSim motion (.mot, Storage version 1):
/// header `name`, `version=1`, `nRows`, `nColumns` (time included),
/// `inDegrees=yes`, `endheader`; columns `time`, `knee_angle_r` (or `_l`
/// for the left leg: OpenSim's gait-model coordinate, flexion negative, so
/// −angle_deg) and, if the trial has velocity_deg_s, `knee_angle_r_speed`.
/// Empty for a trial without t_s.
std::string TrialToOpenSimMotion(const Trial& trial, std::string_view leg);

/// The EMG group's channels other than t_s as EDF+ (16-bit, one-second
/// records, the last padded with zeros; each channel's physical range
/// symmetric around 0 and holding its samples; start date and time from
/// `start_time_unix_ms`, else 1985-01-01 00:00:00). nullopt if the rate is
/// not a whole number of hertz, there is no channel, or EDFlib fails.
std::optional<std::string> EmgToEdf(const ChannelGroup& emg,
                                    std::optional<std::int64_t> start_time_unix_ms);

/// One trial read back, with the id it had where it was exported.
struct BidsTrial {
  Trial trial;  ///< id unset.
  std::optional<std::int64_t> original_id;
  std::string motion_path;  ///< where it was read from (for messages).
};

/// Reads every trial of a dataset (each *_motion.tsv with its sidecars and
/// its derivative files above), in run order; a trial without a _trial.json
/// is named by its TaskName and has no original id. Errors name the file and, inside it, the line
/// and column.
Result<std::vector<BidsTrial>> ReadBidsTrials(const FileMap& files);

/// Checks the files and columns the specification requires, as far as it
/// states them: dataset_description.json (Name, BIDSVersion), a README;
/// per *_motion.tsv a *_channels.tsv whose rows match its columns (columns
/// name, component, type, tracked_point, units; types from the restricted
/// list) and a *_motion.json (SamplingFrequency, TrackingSystemName,
/// TaskName); per *_emg.edf or .bdf a *_emg.json (EMGPlacementScheme, EMGReference,
/// SamplingFrequency, PowerLineFrequency, SoftwareFilters, TaskName) and a
/// *_channels.tsv (name, type, units); per *_events.tsv the columns onset
/// and duration first; every entity label alphanumeric. Files under
/// derivatives/ are the derivative's own and not checked, but for EMG as
/// EDF/BDF and its sidecars (the BEP042 layout kept there). kInvalidArgument
/// naming the file and what is missing.
Status ValidateBidsLayout(const FileMap& files);

}  // namespace fesbench::api
