// The protocol registry (protocol_registry.h; docs/PROTOCOLS.md, "Adding a
// protocol"): one line per protocol, in catalogue order (GET
// /api/v1/protocols lists them so). Each protocol's class is in its own file
// of this folder and defines Make<Class>().

#include <memory>
#include <utility>

#include "server/protocols/protocol_registry.h"

// X(Class) for every protocol, in catalogue order; one line each, so that
// adding one changes no other line.
// clang-format off
#define FESBENCH_PROTOCOL_CATALOG(X) \
  X(ToleranceTest) \
  X(IsometricRampIrc) \
  X(IsometricStepIrc) \
  X(IsometricImpulseIrc) \
  X(IsometricPrediction) \
  X(PassiveSequential) \
  X(PassiveSimultaneous) \
  X(FreeSwingPassive) \
  X(PendulumTest) \
  X(ActiveRandomBinary) \
  X(PredictionStep) \
  X(PredictionRamp) \
  X(PredictionSine) \
  X(PredictionRandomBinary) \
  X(DailyCheck) \
  X(Tracking) \
  X(RapidParameterisation)
// clang-format on

namespace fesbench::server::protocols {
namespace catalog {
#define FESBENCH_DECLARE_PROTOCOL(Class) std::unique_ptr<const Protocol> Make##Class();
FESBENCH_PROTOCOL_CATALOG(FESBENCH_DECLARE_PROTOCOL)
#undef FESBENCH_DECLARE_PROTOCOL
}  // namespace catalog

namespace {

std::vector<RegisteredProtocol> MakeRegistry() {
  std::vector<RegisteredProtocol> registry;
  const auto add = [&registry](std::unique_ptr<const Protocol> protocol) {
    ProtocolDescription description = protocol->Describe();
    std::vector<api::TrialKind> records = protocol->Records();
    registry.push_back({std::move(protocol), std::move(description), std::move(records)});
  };
#define FESBENCH_REGISTER_PROTOCOL(Class) add(catalog::Make##Class());
  FESBENCH_PROTOCOL_CATALOG(FESBENCH_REGISTER_PROTOCOL)
#undef FESBENCH_REGISTER_PROTOCOL
  return registry;
}

}  // namespace

const std::vector<RegisteredProtocol>& RegisteredProtocols() {
  static const std::vector<RegisteredProtocol> registry = MakeRegistry();
  return registry;
}

const RegisteredProtocol* FindRegisteredProtocol(std::string_view name) {
  for (const RegisteredProtocol& r : RegisteredProtocols()) {
    if (r.description.name == name) return &r;
  }
  return nullptr;
}

std::string_view RecordingProtocol(api::TrialKind kind) {
  for (const RegisteredProtocol& r : RegisteredProtocols()) {
    for (api::TrialKind k : r.records) {
      if (k == kind) return r.description.name;
    }
  }
  return {};
}

const std::vector<ProtocolDescription>& ProtocolCatalog() {
  static const std::vector<ProtocolDescription> catalog = [] {
    std::vector<ProtocolDescription> c;
    for (const RegisteredProtocol& r : RegisteredProtocols()) c.push_back(r.description);
    return c;
  }();
  return catalog;
}

}  // namespace fesbench::server::protocols
