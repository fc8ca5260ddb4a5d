#pragma once

/// @file
/// One protocol, one class (docs/PROTOCOLS.md, "Adding a protocol";
/// docs/ARCHITECTURE.md, protocols): a Protocol describes its parameters,
/// builds its plan from the generic step builders (plan_builder.h), with
/// what its run does after the last step (Plan::analysis), declares the
/// kinds of trial it records and concludes its runs' outcomes
/// (run_outcome.h). The registry
/// (catalog/registry.cc) lists every protocol, one line each, in catalogue
/// order; ProtocolCatalog() and FindProtocol() (protocol.h) read it.

#include <memory>
#include <string_view>
#include <vector>

#include "api/status.h"
#include "api/trial_kind.h"
#include "server/protocols/plan_builder.h"
#include "server/protocols/protocol.h"
#include "server/protocols/run_outcome.h"

namespace fesbench::server::protocols {

/// What a protocol's plan is built from.
struct PlanInputs {
  const ParameterValues& values;  ///< resolved (ResolveParameters).
  const SubjectContext& subject;
  /// tracking's uploaded target at 200 Hz, or empty.
  const std::vector<double>& uploaded_target;
  /// The values the client gave, before defaults (null: every value counts
  /// as given).
  const ParameterValues* given;
  double min_rest_s;  ///< the protocol's shortest rest, s.
};

class Protocol {
 public:
  virtual ~Protocol() = default;

  /// Its name, version, parameters and properties (GET /api/v1/protocols).
  virtual ProtocolDescription Describe() const = 0;
  /// The kinds of trial its runs record (api/trial_kind.h).
  virtual std::vector<api::TrialKind> Records() const = 0;
  /// Appends its trials and steps (the settings its run acts on, and its
  /// analysis after the last step, Plan::analysis) to builder.plan(). A
  /// refusal is the returned status (kInvalidArgument naming the parameter
  /// for values it cannot build); a model generator that refuses a value
  /// throws std::invalid_argument, which BuildPlan reports as
  /// kInvalidArgument.
  virtual api::Status BuildSteps(const PlanInputs& inputs, PlanBuilder& builder) const = 0;
  /// The outcome of its run (ConcludeRun): ConcludeCommon's state and
  /// reason, then its figures from what ran (the set it used, its family's
  /// figures). The default is ConcludeCommon alone.
  virtual api::RunOutcome Conclude(const RunConclusionInput& input, const RunResult& result) const;
};

/// One registered protocol: the class and the description it gave.
struct RegisteredProtocol {
  std::unique_ptr<const Protocol> protocol;
  ProtocolDescription description;
  std::vector<api::TrialKind> records;
};

/// Every protocol, in catalogue order (catalog/registry.cc).
const std::vector<RegisteredProtocol>& RegisteredProtocols();
/// The protocol called name, or nullptr.
const RegisteredProtocol* FindRegisteredProtocol(std::string_view name);
/// The name of the protocol that records trials of `kind`, or "" (a kind
/// only imports declare).
std::string_view RecordingProtocol(api::TrialKind kind);

}  // namespace fesbench::server::protocols
