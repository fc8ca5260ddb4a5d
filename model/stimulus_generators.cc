#include "model/stimulus_generators.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <stdexcept>
#include <string>

#include "model/units.h"

namespace fesbench::model {
namespace {

using Builder = SampledSignal (*)(const GeneratorParams&);

struct Entry {
  GeneratorDescription description;
  Builder build;
};

std::size_t Samples(double duration_s) {
  return static_cast<std::size_t>(std::llround(duration_s * kStimulusRateHz));
}

[[noreturn]] void Fail(std::string_view generator, std::string_view parameter,
                       const std::string& why) {
  throw std::invalid_argument("stimulus '" + std::string(generator) + "': parameter '" +
                              std::string(parameter) + "' " + why);
}

// Appends segments of a 200 Hz envelope; sample i of a segment is at local
// time tau = i / rate.
class Envelope {
 public:
  void Constant(double duration_s, double stim_ma) {
    values_.insert(values_.end(), Samples(duration_s), stim_ma);
  }
  template <typename F>
  void Function(double duration_s, F f) {
    const std::size_t n = Samples(duration_s);
    for (std::size_t i = 0; i < n; ++i)
      values_.push_back(f(static_cast<double>(i) / kStimulusRateHz));
  }
  // Linear ramp from `from` to `to` over duration_s, reaching `to` on its last
  // sample (so a ramp up from 0 is non-zero from its first sample).
  void Ramp(double duration_s, double from, double to) {
    const std::size_t n = Samples(duration_s);
    for (std::size_t i = 0; i < n; ++i) {
      values_.push_back(from + (to - from) * static_cast<double>(i + 1) / static_cast<double>(n));
    }
  }
  // One non-zero sample (one stimulator pulse), then zeros up to window_s.
  void Impulse(double stim_ma, double window_s) {
    const std::size_t n = std::max<std::size_t>(Samples(window_s), 1);
    values_.push_back(stim_ma);
    values_.insert(values_.end(), n - 1, 0.0);
  }
  SampledSignal Take() { return SampledSignal{kStimulusRateHz, 0.0, std::move(values_)}; }

 private:
  std::vector<double> values_;
};

// Subject scaling shared by most generators.
struct Subject {
  double threshold_ma;
  double max_ma;
  double range_ma() const { return max_ma - threshold_ma; }
};

Subject GetSubject(std::string_view generator, const GeneratorParams& p) {
  const Subject s{p.at("threshold_ma"), p.at("max_ma")};
  if (!(s.threshold_ma < s.max_ma)) {
    Fail(generator, "threshold_ma", "must be below max_ma (" + std::to_string(s.max_ma) + " mA)");
  }
  return s;
}

GeneratorParameter Threshold() {
  return {"threshold_ma", "subject's stimulation threshold for torque, mA", 20.0, 0.0, 100.0,
          false};
}
GeneratorParameter Max() {
  return {"max_ma", "subject's maximum tolerated stimulation, mA", 45.0, 1.0, 100.0, false};
}

// --- §5.3 conditioning burst ---------------------------------------------
void AppendConditioning(Envelope& e, const Subject& s, double duration_s, double fraction,
                        double rest_s) {
  e.Constant(duration_s, s.threshold_ma + fraction * s.range_ma());
  e.Constant(rest_s, 0.0);
}

SampledSignal BuildConditioning(const GeneratorParams& p) {
  const Subject s = GetSubject("conditioning", p);
  Envelope e;
  AppendConditioning(e, s, p.at("duration_s"), p.at("level_fraction"), p.at("rest_s"));
  return e.Take();
}

// --- Fig. 5-7 impulses at max ----------------------------------------------
void AppendImpulses(Envelope& e, double stim_ma, int count, double interval_s) {
  for (int k = 0; k < count; ++k) e.Impulse(stim_ma, interval_s);
}

SampledSignal BuildImpulses(const GeneratorParams& p) {
  const Subject s = GetSubject("impulses", p);
  Envelope e;
  AppendImpulses(e, s.max_ma, static_cast<int>(p.at("count")), p.at("interval_s"));
  return e.Take();
}

// --- §5.3.3 cosine ramps ---------------------------------------------------
void AppendCosineRamps(Envelope& e, const Subject& s, double below_ma, double duration_s, int count,
                       double rest_s) {
  const double lo = std::max(s.threshold_ma - below_ma, 0.0);
  const double hi = s.max_ma;
  for (int k = 0; k < count; ++k) {
    e.Function(duration_s, [&](double tau) {
      return lo + (hi - lo) * 0.5 * (1.0 - std::cos(2.0 * kPi * tau / duration_s));
    });
    e.Constant(rest_s, 0.0);
  }
}

SampledSignal BuildCosineRamps(const GeneratorParams& p) {
  const Subject s = GetSubject("cosine_ramps", p);
  Envelope e;
  AppendCosineRamps(e, s, p.at("below_threshold_ma"), p.at("ramp_duration_s"),
                    static_cast<int>(p.at("count")), p.at("rest_s"));
  return e.Take();
}

// --- Fig. 5-7 / Appendix F II: the whole ramp IRC sequence ------------------
SampledSignal BuildIsometricRampIrc(const GeneratorParams& p) {
  const Subject s = GetSubject("isometric_ramp_irc", p);
  const double rest_s = p.at("rest_s");
  Envelope e;
  AppendConditioning(e, s, p.at("conditioning_s"), p.at("conditioning_fraction"), rest_s);
  AppendImpulses(e, s.max_ma, static_cast<int>(p.at("impulses")), rest_s);
  AppendCosineRamps(e, s, p.at("below_threshold_ma"), p.at("ramp_duration_s"),
                    static_cast<int>(p.at("ramps")), rest_s);
  return e.Take();
}

// --- §5.3.1 step bursts ----------------------------------------------------
SampledSignal BuildStepBursts(const GeneratorParams& p) {
  const Subject s = GetSubject("step_bursts", p);
  const int levels = static_cast<int>(p.at("levels"));
  const double burst_s = p.at("burst_s");
  const double ramp_s = p.at("ramp_s");
  if (ramp_s >= burst_s) Fail("step_bursts", "ramp_s", "must be shorter than burst_s");
  Envelope e;
  for (int k = 0; k < levels; ++k) {
    const double level = s.threshold_ma + s.range_ma() * k / (levels - 1);
    e.Ramp(ramp_s, 0.0, level);
    e.Constant(burst_s - ramp_s, level);
    e.Constant(p.at("rest_s"), 0.0);
  }
  return e.Take();
}

// --- §5.3.2 impulse series -------------------------------------------------
SampledSignal BuildImpulseSeries(const GeneratorParams& p) {
  const Subject s = GetSubject("impulse_series", p);
  const int count = static_cast<int>(p.at("count"));
  // A zero-amplitude pulse would be no pulse at all: start at >= 1 mA.
  const double lo = std::max(s.threshold_ma - p.at("below_threshold_ma"), 1.0);
  Envelope e;
  for (int k = 0; k < count; ++k) {
    e.Impulse(lo + (s.max_ma - lo) * k / (count - 1), p.at("interval_s"));
  }
  return e.Take();
}

// --- §5.3.4 / Fig. 5-8 plateau profile --------------------------------------
SampledSignal BuildPlateauProfile(const GeneratorParams& p) {
  const Subject s = GetSubject("plateau_profile", p);
  const double lo = s.threshold_ma + p.at("above_threshold_ma");
  if (!(lo < s.max_ma)) {
    Fail("plateau_profile", "above_threshold_ma", "puts the lowest plateau at or above max_ma");
  }
  const double ramp_s = p.at("ramp_s");
  const double hold_s = p.at("hold_s");
  const double fractions[] = {0.0, 0.25, 0.5, 0.75, 1.0, 0.75, 0.5, 0.25, 0.0};
  Envelope e;
  e.Constant(p.at("lead_s"), 0.0);
  double previous = 0.0;
  for (const double f : fractions) {
    const double level = lo + f * (s.max_ma - lo);
    e.Ramp(ramp_s, previous, level);
    e.Constant(hold_s, level);
    previous = level;
  }
  e.Ramp(ramp_s, previous, 0.0);
  e.Constant(p.at("tail_s"), 0.0);
  return e.Take();
}

// --- §5.4.5 prediction inputs ----------------------------------------------
SampledSignal BuildPredictionStep(const GeneratorParams& p) {
  const Subject s = GetSubject("prediction_step", p);
  Envelope e;
  e.Constant(p.at("onset_s"), 0.0);
  e.Constant(p.at("on_s"), s.threshold_ma + p.at("level_fraction") * s.range_ma());
  e.Constant(p.at("off_s"), 0.0);
  return e.Take();
}

SampledSignal BuildPredictionRamp(const GeneratorParams& p) {
  const double max_ma = p.at("max_ma");
  const double up_s = p.at("up_s");
  const double down_s = p.at("down_s");
  Envelope e;
  e.Function(up_s, [&](double tau) { return max_ma * tau / up_s; });
  e.Function(down_s, [&](double tau) { return max_ma * (1.0 - tau / down_s); });
  return e.Take();
}

SampledSignal BuildPredictionSine(const GeneratorParams& p) {
  const Subject s = GetSubject("prediction_sine", p);
  const double lo = s.threshold_ma + p.at("above_threshold_ma");
  if (!(lo < s.max_ma)) {
    Fail("prediction_sine", "above_threshold_ma", "puts the lower level at or above max_ma");
  }
  Envelope e;
  for (const double period_s : {5.0, 2.0, 1.0}) {
    e.Function(period_s, [&](double tau) {
      return lo + (s.max_ma - lo) * 0.5 * (1.0 - std::cos(2.0 * kPi * tau / period_s));
    });
  }
  e.Constant(p.at("tail_s"), 0.0);
  return e.Take();
}

// --- §5.4.3–5.4.4 random binary trains ---------------------------------------
double Uniform01(std::mt19937_64& rng) {
  return static_cast<double>(rng() >> 11) * 0x1.0p-53;  // portable, unlike std distributions
}

SampledSignal BuildRandomBinary(std::string_view name, const GeneratorParams& p) {
  const double amplitude_ma = p.at("amplitude_ma");
  const double duration_s = p.at("duration_s");
  const double slot_s = p.at("min_switch_s");
  const double lead_s = p.at("lead_s");
  const double tail_s = p.at("tail_s");
  if (lead_s + tail_s + slot_s > duration_s) {
    Fail(name, "duration_s", "leaves no room for one slot after lead_s and before tail_s");
  }
  if (p.at("mean_on_s") < slot_s) Fail(name, "mean_on_s", "must be >= min_switch_s");
  if (p.at("mean_off_s") < slot_s) Fail(name, "mean_off_s", "must be >= min_switch_s");
  const double p_leave_on = slot_s / p.at("mean_on_s");
  const double p_leave_off = slot_s / p.at("mean_off_s");

  std::mt19937_64 rng(static_cast<std::uint64_t>(p.at("seed")));
  const std::size_t n_total = Samples(duration_s);
  const std::size_t n_lead = Samples(lead_s);
  const std::size_t n_active_end = n_total - Samples(tail_s);
  const std::size_t n_slot = std::max<std::size_t>(Samples(slot_s), 1);
  std::vector<double> values(n_total, 0.0);
  bool on = true;
  for (std::size_t start = n_lead; start < n_active_end; start += n_slot) {
    if (start != n_lead) {
      const double u = Uniform01(rng);
      if (u < (on ? p_leave_on : p_leave_off)) on = !on;
    }
    const std::size_t end = std::min(start + n_slot, n_active_end);
    if (on)
      std::fill(values.begin() + static_cast<std::ptrdiff_t>(start),
                values.begin() + static_cast<std::ptrdiff_t>(end), amplitude_ma);
  }
  return SampledSignal{kStimulusRateHz, 0.0, std::move(values)};
}

SampledSignal BuildRandomBinarySparse(const GeneratorParams& p) {
  return BuildRandomBinary("random_binary_sparse", p);
}
SampledSignal BuildRandomBinaryDense(const GeneratorParams& p) {
  return BuildRandomBinary("random_binary_dense", p);
}

std::vector<GeneratorParameter> RandomBinaryParameters(double slot_s, double on_s, double off_s,
                                                       double tail_s) {
  return {
      {"amplitude_ma", "ON amplitude (lowest level giving full extension), mA", 35.0, 1.0, 100.0,
       false},
      {"duration_s", "train length, s", 10.0, 1.0, 120.0, false},
      {"min_switch_s", "minimum switching interval (slot length), s", slot_s, 0.01, 5.0, false},
      {"mean_on_s", "mean ON dwell, s", on_s, 0.01, 20.0, false},
      {"mean_off_s", "mean OFF dwell, s", off_s, 0.01, 20.0, false},
      {"lead_s", "OFF time before the first slot, s", 0.5, 0.0, 10.0, false},
      {"tail_s", "OFF time at the end, s", tail_s, 0.0, 20.0, false},
      {"seed", "random seed", 1.0, 0.0, 4294967295.0, true},
  };
}

const std::vector<Entry>& Registry() {
  static const std::vector<Entry> entries = [] {
    std::vector<Entry> r;
    r.push_back(
        {{"conditioning",
          "3 s conditioning burst at 75 % of the threshold-max range (§5.3)",
          {Threshold(),
           Max(),
           {"duration_s", "burst length, s", 3.0, 0.1, 10.0, false},
           {"level_fraction", "level as fraction of threshold->max range", 0.75, 0.0, 1.0, false},
           {"rest_s", "zero stimulation after the burst, s", 1.0, 0.0, 60.0, false}}},
         &BuildConditioning});
    r.push_back({{"impulses",
                  "single pulses at max_ma, one per interval (Fig. 5-7)",
                  {Threshold(),
                   Max(),
                   {"count", "number of pulses", 2.0, 1.0, 100.0, true},
                   {"interval_s", "time between pulses, s", 1.0, 0.2, 10.0, false}}},
                 &BuildImpulses});
    r.push_back({{"cosine_ramps",
                  "cosine ramps threshold-5 mA -> max -> back, rest between (§5.3.3)",
                  {Threshold(),
                   Max(),
                   {"below_threshold_ma", "ramp start below threshold, mA", 5.0, 0.0, 50.0, false},
                   {"ramp_duration_s", "whole ramp (half up, half down), s", 4.0, 0.5, 30.0, false},
                   {"count", "number of ramps", 2.0, 1.0, 10.0, true},
                   {"rest_s", "zero stimulation after each ramp, s", 1.0, 0.0, 60.0, false}}},
                 &BuildCosineRamps});
    r.push_back({{"isometric_ramp_irc",
                  "conditioning, 2 impulses at max, 2 cosine ramps with rests (Fig. 5-7)",
                  {Threshold(),
                   Max(),
                   {"conditioning_s", "conditioning burst length, s", 3.0, 0.0, 10.0, false},
                   {"conditioning_fraction", "conditioning level, fraction of range", 0.75, 0.0,
                    1.0, false},
                   {"impulses", "number of impulses", 2.0, 0.0, 20.0, true},
                   {"ramps", "number of cosine ramps", 2.0, 1.0, 10.0, true},
                   {"below_threshold_ma", "ramp start below threshold, mA", 5.0, 0.0, 50.0, false},
                   {"ramp_duration_s", "whole ramp (half up, half down), s", 4.0, 0.5, 30.0, false},
                   {"rest_s", "zero stimulation after each element, s", 1.0, 0.2, 60.0, false}}},
                 &BuildIsometricRampIrc});
    r.push_back({{"step_bursts",
                  "10 bursts threshold -> max, 0.5 s ramp + 2.5 s hold, 30 s rest (§5.3.1)",
                  {Threshold(),
                   Max(),
                   {"levels", "number of amplitudes", 10.0, 2.0, 50.0, true},
                   {"burst_s", "burst length incl. ramp, s", 3.0, 0.2, 20.0, false},
                   {"ramp_s", "linear ramp at burst start, s", 0.5, 0.0, 10.0, false},
                   {"rest_s", "zero stimulation after each burst, s", 30.0, 0.0, 300.0, false}}},
                 &BuildStepBursts});
    r.push_back({{"impulse_series",
                  "30 single pulses from below threshold to max, 1 s apart (§5.3.2)",
                  {Threshold(),
                   Max(),
                   {"count", "number of pulses", 30.0, 2.0, 200.0, true},
                   {"below_threshold_ma", "first pulse below threshold, mA", 5.0, 0.0, 50.0, false},
                   {"interval_s", "time between pulses, s", 1.0, 0.2, 10.0, false}}},
                 &BuildImpulseSeries});
    r.push_back(
        {{"plateau_profile",
          "11 s staircase of Fig. 5-8 (threshold+5 mA, 25/50/75 %, max and back)",
          {Threshold(),
           Max(),
           {"above_threshold_ma", "lowest plateau above threshold, mA", 5.0, 0.0, 50.0, false},
           {"lead_s", "zero stimulation before the first ramp, s", 0.5, 0.0, 10.0, false},
           {"ramp_s", "linear ramp between plateaus, s", 0.25, 0.005, 5.0, false},
           {"hold_s", "plateau hold, s", 0.75, 0.0, 10.0, false},
           {"tail_s", "zero stimulation at the end, s", 1.25, 0.0, 10.0, false}}},
         &BuildPlateauProfile});
    r.push_back(
        {{"prediction_step",
          "step at 75 % of range from 0.5 s for 3 s, then 1.5 s off (§5.4.5)",
          {Threshold(),
           Max(),
           {"level_fraction", "level as fraction of threshold->max range", 0.75, 0.0, 1.0, false},
           {"onset_s", "zero stimulation before the step, s", 0.5, 0.0, 10.0, false},
           {"on_s", "step length, s", 3.0, 0.1, 30.0, false},
           {"off_s", "zero stimulation after the step, s", 1.5, 0.0, 30.0, false}}},
         &BuildPredictionStep});
    r.push_back({{"prediction_ramp",
                  "linear ramp 0 -> max in 5 s and back to 0 in 5 s (§5.4.5)",
                  {Max(),
                   {"up_s", "ramp-up time, s", 5.0, 0.1, 60.0, false},
                   {"down_s", "ramp-down time, s", 5.0, 0.1, 60.0, false}}},
                 &BuildPredictionRamp});
    r.push_back({{"prediction_sine",
                  "swept sine threshold+5 mA <-> max, periods 5, 2, 1 s, then 1 s off (§5.4.5)",
                  {Threshold(),
                   Max(),
                   {"above_threshold_ma", "lower level above threshold, mA", 5.0, 0.0, 50.0, false},
                   {"tail_s", "zero stimulation at the end, s", 1.0, 0.0, 10.0, false}}},
                 &BuildPredictionSine});
    r.push_back({{"random_binary_sparse",
                  "sparse seeded random binary train for free swing passive (§5.4.3, Fig. 5-10)",
                  RandomBinaryParameters(0.25, 0.5, 2.0, 2.0)},
                 &BuildRandomBinarySparse});
    r.push_back({{"random_binary_dense",
                  "dense seeded random binary train for active identification (§5.4.4, Fig. 5-11)",
                  RandomBinaryParameters(0.1, 0.4, 0.4, 1.0)},
                 &BuildRandomBinaryDense});
    return r;
  }();
  return entries;
}

}  // namespace

const GeneratorParameter* GeneratorDescription::FindParameter(std::string_view wanted) const {
  for (const auto& p : parameters) {
    if (p.name == wanted) return &p;
  }
  return nullptr;
}

GeneratorParams ResolveParameters(const GeneratorDescription& d, const GeneratorParams& params) {
  GeneratorParams out;
  for (const auto& [key, value] : params) {
    const GeneratorParameter* spec = d.FindParameter(key);
    if (spec == nullptr) {
      throw std::invalid_argument("generator '" + d.name + "': unknown parameter '" + key + "'");
    }
    const std::string where = "generator '" + d.name + "': parameter '" + key + "' ";
    if (!std::isfinite(value)) throw std::invalid_argument(where + "must be finite");
    if (value < spec->min_value || value > spec->max_value) {
      throw std::invalid_argument(where + "= " + std::to_string(value) + " is outside [" +
                                  std::to_string(spec->min_value) + ", " +
                                  std::to_string(spec->max_value) + "]");
    }
    if (spec->integer && value != std::floor(value)) {
      throw std::invalid_argument(where + "must be a whole number");
    }
    out[key] = value;
  }
  for (const auto& spec : d.parameters) out.try_emplace(spec.name, spec.default_value);
  return out;
}

const std::vector<GeneratorDescription>& StimulusGenerators() {
  static const std::vector<GeneratorDescription> list = [] {
    std::vector<GeneratorDescription> r;
    for (const auto& e : Registry()) r.push_back(e.description);
    return r;
  }();
  return list;
}

const GeneratorDescription* FindStimulusGenerator(std::string_view name) {
  for (const auto& e : Registry()) {
    if (e.description.name == name) return &e.description;
  }
  return nullptr;
}

SampledSignal MakeStimulus(std::string_view name, const GeneratorParams& params) {
  for (const auto& e : Registry()) {
    if (e.description.name == name) return e.build(ResolveParameters(e.description, params));
  }
  throw std::invalid_argument("unknown stimulus generator '" + std::string(name) + "'");
}

}  // namespace fesbench::model
