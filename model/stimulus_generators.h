#pragma once

/// @file
/// Stimulation envelope generators for the protocols of thesis §5.3–§5.4 and
/// Appendix F (docs/PROTOCOLS.md), with a name-based registry used by the command
/// line and the protocol runner.
///
/// Every generator returns a model::SampledSignal of stimulation amplitude
/// (stim_ma) at kStimulusRateHz, starting at t = 0. The stimulator turns it
/// into pulses with PulsesFromEnvelope (docs/MODEL.md): its pulse clock runs
/// continuously from t = 0 at the pulse rate (33 Hz), a run of non-zero
/// samples fires at the grid times inside it, and a run too short to hold
/// one (a single non-zero sample: an impulse) is exactly one pulse at its
/// start.
/// Amplitudes are scaled to the subject through threshold_ma (the torque
/// threshold) and max_ma (the maximum tolerated amplitude); "range" below
/// means [threshold_ma, max_ma] unless stated otherwise.
///
/// Generators (registry names) and their exact timing:
///  - conditioning: burst of duration_s (3 s) at threshold + 0.75·range
///    (§5.3), then rest_s (1 s) of zero.
///  - impulses: count (2) single-sample pulses at max_ma, interval_s (1 s)
///    apart, the first at t = 0; length count·interval_s (Fig. 5-7).
///  - cosine_ramps: count (2) cosine ramps, each ramp_duration_s (4 s: half
///    up, half down) from max(threshold − 5 mA, 0) to max_ma and back,
///    u = lo + (hi − lo)·(1 − cos(2π t / T))/2, each followed by rest_s (1 s)
///    of zero (§5.3.3).
///  - isometric_ramp_irc: conditioning, impulses, cosine_ramps concatenated
///    (Fig. 5-7, Appendix F part II): 3 s burst, 1 s rest, impulses at 4 s and
///    5 s, ramps at 6–10 s and 11–15 s, 1 s final rest: 16 s by default.
///  - step_bursts: levels (10) amplitudes evenly spaced threshold → max; each
///    a burst_s (3 s) burst that ramps linearly over ramp_s (0.5 s; the first
///    sample already at level/ramp_samples) and holds, followed by rest_s
///    (30 s) of zero (§5.3.1): 330 s by default.
///  - impulse_series: count (30) single-sample pulses, interval_s (1 s)
///    apart from t = 0, amplitudes evenly spaced from
///    max(threshold − below_threshold_ma, 1 mA) to max_ma (§5.3.2).
///  - plateau_profile: the 11 s staircase of Fig. 5-8 (isometric
///    prediction). Levels L0..L4 at 0, 25, 50, 75, 100 % of the range
///    [threshold + above_threshold_ma, max_ma] (Appendix F part IV sets the
///    minimum stimulation to threshold + 5 mA). Timing: lead_s (0.5 s) off;
///    then nine steps, each a linear ramp of ramp_s (0.25 s) from the
///    previous level followed by hold_s (0.75 s): L0 L1 L2 L3 L4 L3 L2 L1 L0
///    (0.5–9.5 s); a ramp_s ramp to 0 (9.5–9.75 s); tail_s (1.25 s) off.
///  - prediction_step: 0 until onset_s (0.5 s), threshold + 0.75·range for
///    on_s (3 s), then off_s (1.5 s) of zero (§5.4.5): 5 s.
///  - prediction_ramp: max_ma·t/up_s over up_s (5 s), then back to 0 over
///    down_s (5 s) (§5.4.5): 10 s.
///  - prediction_sine: one cosine cycle each of period 5, 2 and 1 s between
///    lo = threshold + above_threshold_ma (5 mA) and max_ma,
///    u = lo + (hi − lo)·(1 − cos(2π τ / P))/2 (starting and ending each cycle
///    at lo), then tail_s (1 s) of zero (§5.4.5): 9 s.
///  - random_binary_sparse / random_binary_dense: seeded random binary
///    trains (0 or amplitude_ma) of duration_s (10 s) (§5.4.3 Fig. 5-10,
///    §5.4.4 Fig. 5-11). Time after lead_s (0.5 s) is cut into slots of
///    min_switch_s; the state is a two-state Markov chain over slots that
///    starts ON in the first slot, leaves ON with probability
///    min_switch_s / mean_on_s and leaves OFF with probability
///    min_switch_s / mean_off_s per slot, so dwell times are multiples of
///    min_switch_s with the given means; the last tail_s is forced OFF.
///    Sparse (free swing passive, "RB1"-like): slots 0.25 s, mean ON 0.5 s,
///    mean OFF 2 s, tail 2 s. Dense (active identification): slots 0.1 s,
///    mean ON 0.4 s, mean OFF 0.4 s, tail 1 s. The random numbers come from
///    std::mt19937_64 seeded with seed, converted to [0, 1) with 53-bit
///    arithmetic, so the same seed gives the same train on every platform.

#include <functional>
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "model/signal.h"

namespace fesbench::model {

/// Sample rate of every generated envelope, Hz (docs/ARCHITECTURE.md, units).
inline constexpr double kStimulusRateHz = 200.0;

/// One numeric parameter of a generator. The name carries the unit suffix
/// (`_ma`, `_s`, `_deg`, `_deg_s`, `_hz`); unitless names are counts,
/// fractions or seeds.
struct GeneratorParameter {
  std::string name;
  std::string description;
  double default_value = 0.0;
  double min_value = 0.0;  ///< inclusive
  double max_value = 0.0;  ///< inclusive
  bool integer = false;    ///< value must be a whole number
};

/// A named generator and its parameters (registry entry).
struct GeneratorDescription {
  std::string name;
  std::string description;
  std::vector<GeneratorParameter> parameters;

  /// The parameter called name, or nullptr.
  const GeneratorParameter* FindParameter(std::string_view name) const;
};

/// Parameter values by name; missing names take their defaults.
using GeneratorParams = std::map<std::string, double, std::less<>>;

/// Fills defaults and validates params against description: every key must
/// be a parameter of the generator, finite, inside [min, max] and whole if
/// integer. Returns the complete map.
/// @throws std::invalid_argument naming the generator and the offending
///   parameter.
GeneratorParams ResolveParameters(const GeneratorDescription& description,
                                  const GeneratorParams& params);

/// Every stimulus generator, in a fixed order (see the file comment).
const std::vector<GeneratorDescription>& StimulusGenerators();

/// The stimulus generator called name, or nullptr.
const GeneratorDescription* FindStimulusGenerator(std::string_view name);

/// Builds the stimulation envelope (stim_ma at kStimulusRateHz, t0 = 0) of
/// generator name with params (defaults for missing ones).
/// @throws std::invalid_argument for an unknown generator name, an unknown,
///   non-finite, out-of-range or non-integer parameter, or inconsistent
///   values (e.g. threshold_ma >= max_ma); the message names the parameter.
SampledSignal MakeStimulus(std::string_view name, const GeneratorParams& params = {});

}  // namespace fesbench::model
