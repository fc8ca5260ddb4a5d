#pragma once

/// @file
/// fesbench-dds-monitor's functions (docs/API.md, "DDS"), usable from tests: list
/// live benches and their state, print or record a run's samples, show the
/// latest parameter set of a subject and leg, send an e-stop. Each waits at
/// most `timeout_s` for a server and fails with kUnavailable ("no fesbench
/// server found on DDS domain N within T s") when none answers.

#include <cstdint>
#include <iosfwd>
#include <string>

#include "api/dds/participant.h"
#include "api/status.h"

namespace fesbench::dds_monitor {

struct MonitorOptions {
  dds::ParticipantOptions participant;
  double timeout_s = 5.0;  ///< how long to wait for a server.
};

/// Prints one line per live bench (its latest state) to `out`; the number of benches.
api::Result<int> ListBenches(const MonitorOptions& options, std::ostream& out);

/// Prints (or with `csv` true, writes as CSV with a header) every sample of
/// run `run_id` to `out` until the run's end event, or until `max_samples`
/// (0 = no limit). Checks block sequence numbers: kDataLoss naming the gap
/// if blocks were lost. Returns the number of samples.
api::Result<std::uint64_t> StreamSamples(const MonitorOptions& options, std::int64_t run_id,
                                         bool csv, std::uint64_t max_samples, std::ostream& out);

/// Prints the latest parameter set of the subject's leg (summary, then its
/// JSON). kNotFound if servers answer but none has a set for that leg.
api::Status ShowParameterSet(const MonitorOptions& options, std::int64_t subject_id,
                             std::int64_t leg_id, std::ostream& out);

/// Sends an e-stop with `token` to `bench_id` ("" = every bench) and prints
/// the reply. The refusal's Status (code and reason) if refused.
api::Status SendEStop(const MonitorOptions& options, const std::string& token,
                      const std::string& bench_id, std::ostream& out);

}  // namespace fesbench::dds_monitor
