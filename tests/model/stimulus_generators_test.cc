#include "model/stimulus_generators.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <stdexcept>
#include <string>

namespace fesbench::model {
namespace {

constexpr double kThr = 20.0;
constexpr double kMax = 45.0;
constexpr double kDt = 1.0 / kStimulusRateHz;

// A run of non-zero samples [begin, end).
struct NonZeroRun {
  std::size_t begin, end;
  double seconds() const { return static_cast<double>(end - begin) * kDt; }
};

std::vector<NonZeroRun> Runs(const SampledSignal& s) {
  std::vector<NonZeroRun> runs;
  for (std::size_t i = 0; i < s.size();) {
    if (s.values[i] == 0.0) {
      ++i;
      continue;
    }
    std::size_t j = i;
    while (j < s.size() && s.values[j] != 0.0) ++j;
    runs.push_back({i, j});
    i = j;
  }
  return runs;
}

double MaxOf(const SampledSignal& s) { return *std::max_element(s.values.begin(), s.values.end()); }

TEST(StimulusRegistry, ListsEveryGeneratorWithValidDefaults) {
  const std::set<std::string> expected = {
      "conditioning",    "impulses",        "cosine_ramps",         "isometric_ramp_irc",
      "step_bursts",     "impulse_series",  "plateau_profile",      "prediction_step",
      "prediction_ramp", "prediction_sine", "random_binary_sparse", "random_binary_dense"};
  std::set<std::string> names;
  for (const auto& d : StimulusGenerators()) {
    names.insert(d.name);
    EXPECT_FALSE(d.description.empty()) << d.name;
    for (const auto& p : d.parameters) {
      EXPECT_LE(p.min_value, p.default_value) << d.name << "." << p.name;
      EXPECT_GE(p.max_value, p.default_value) << d.name << "." << p.name;
    }
    const SampledSignal s = MakeStimulus(d.name);
    EXPECT_DOUBLE_EQ(s.rate_hz, 200.0);
    EXPECT_GT(s.size(), 0u) << d.name;
    EXPECT_GT(MaxOf(s), 0.0) << d.name;
    EXPECT_TRUE(std::all_of(s.values.begin(), s.values.end(), [](double v) { return v >= 0.0; }));
  }
  EXPECT_EQ(names, expected);
  EXPECT_NE(FindStimulusGenerator("step_bursts"), nullptr);
  EXPECT_EQ(FindStimulusGenerator("nope"), nullptr);
}

TEST(StimulusRegistry, ValidatesNamesAndRanges) {
  EXPECT_THROW(MakeStimulus("nope"), std::invalid_argument);
  auto message = [](const GeneratorParams& p) {
    try {
      MakeStimulus("step_bursts", p);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_NE(message({{"bogus_s", 1.0}}).find("bogus_s"), std::string::npos);
  EXPECT_NE(message({{"rest_s", -1.0}}).find("rest_s"), std::string::npos);
  EXPECT_NE(message({{"levels", 2.5}}).find("levels"), std::string::npos);
  EXPECT_NE(message({{"max_ma", NAN}}).find("max_ma"), std::string::npos);
  EXPECT_NE(message({{"threshold_ma", 50.0}, {"max_ma", 40.0}}).find("threshold_ma"),
            std::string::npos);
  EXPECT_NE(message({{"ramp_s", 3.0}}).find("ramp_s"), std::string::npos);
  EXPECT_THROW(MakeStimulus("plateau_profile", {{"threshold_ma", 38.0}, {"max_ma", 40.0}}),
               std::invalid_argument);
  EXPECT_THROW(MakeStimulus("random_binary_dense", {{"mean_on_s", 0.05}}), std::invalid_argument);
}

TEST(StimulusGenerators, ConditioningIs3sAt75PercentOfRange) {
  const SampledSignal s = MakeStimulus("conditioning", {{"threshold_ma", kThr}, {"max_ma", kMax}});
  const auto runs = Runs(s);
  ASSERT_EQ(runs.size(), 1u);
  EXPECT_EQ(runs[0].begin, 0u);
  EXPECT_DOUBLE_EQ(runs[0].seconds(), 3.0);
  EXPECT_DOUBLE_EQ(s.values[10], 20.0 + 0.75 * 25.0);
  EXPECT_DOUBLE_EQ(s.EndTime(), 4.0);
  // At 33 Hz a 3 s burst is ceil(3 * 33) = 99 pulses.
  EXPECT_EQ(PulsesFromEnvelope(s, 33.0).size(), 99u);
}

TEST(StimulusGenerators, CosineRampsRiseFromThresholdMinus5ToMax) {
  const SampledSignal s = MakeStimulus("cosine_ramps", {{"threshold_ma", kThr}, {"max_ma", kMax}});
  const auto runs = Runs(s);
  ASSERT_EQ(runs.size(), 2u);
  EXPECT_DOUBLE_EQ(runs[0].seconds(), 4.0);
  EXPECT_DOUBLE_EQ(runs[1].seconds(), 4.0);
  EXPECT_DOUBLE_EQ((runs[1].begin - runs[0].end) * kDt, 1.0);  // 1 s rest between
  EXPECT_DOUBLE_EQ(s.values[0], 15.0);                         // threshold - 5 mA
  EXPECT_DOUBLE_EQ(s.values[400], 45.0);                       // max at 2 s (half of 4 s)
  EXPECT_NEAR(s.values[200], 30.0, 1e-12);                     // midpoint of the cosine at 1 s
  EXPECT_DOUBLE_EQ(MaxOf(s), 45.0);
  EXPECT_DOUBLE_EQ(s.EndTime(), 10.0);
  // Ramp duration is a parameter (thesis tested 2, 4 and 10 s).
  const SampledSignal s10 = MakeStimulus("cosine_ramps", {{"ramp_duration_s", 10.0}});
  EXPECT_DOUBLE_EQ(Runs(s10)[0].seconds(), 10.0);
  EXPECT_DOUBLE_EQ(s10.values[1000], 45.0);
}

TEST(StimulusGenerators, IsometricRampIrcSequenceOfFig5_7) {
  const SampledSignal s =
      MakeStimulus("isometric_ramp_irc", {{"threshold_ma", kThr}, {"max_ma", kMax}});
  const auto runs = Runs(s);
  ASSERT_EQ(runs.size(), 5u);  // conditioning, 2 impulses, 2 ramps
  EXPECT_DOUBLE_EQ(runs[0].seconds(), 3.0);
  EXPECT_DOUBLE_EQ(s.values[runs[0].begin], 38.75);
  EXPECT_EQ(runs[1].end - runs[1].begin, 1u);  // one sample = one pulse
  EXPECT_EQ(runs[2].end - runs[2].begin, 1u);
  EXPECT_DOUBLE_EQ(runs[1].begin * kDt, 4.0);
  EXPECT_DOUBLE_EQ(runs[2].begin * kDt, 5.0);
  EXPECT_DOUBLE_EQ(s.values[runs[1].begin], kMax);
  EXPECT_DOUBLE_EQ(runs[3].begin * kDt, 6.0);
  EXPECT_DOUBLE_EQ(runs[4].begin * kDt, 11.0);
  EXPECT_DOUBLE_EQ(runs[3].seconds(), 4.0);
  EXPECT_DOUBLE_EQ(s.EndTime(), 16.0);
  const PulseTrain pulses = PulsesFromEnvelope(s, 33.0);
  EXPECT_EQ(pulses.size(), 99u + 2u + 2u * 132u);
}

TEST(StimulusGenerators, StepBurstsAre10BurstsOf3sWith30sRest) {
  const SampledSignal s = MakeStimulus("step_bursts", {{"threshold_ma", kThr}, {"max_ma", kMax}});
  const auto runs = Runs(s);
  ASSERT_EQ(runs.size(), 10u);
  for (std::size_t k = 0; k < runs.size(); ++k) {
    EXPECT_DOUBLE_EQ(runs[k].seconds(), 3.0) << k;
    EXPECT_DOUBLE_EQ(runs[k].begin * kDt, 33.0 * k) << k;
    const double level = kThr + 25.0 * k / 9.0;
    // 0.5 s linear ramp: first sample level/100, halfway level/2, then hold.
    EXPECT_NEAR(s.values[runs[k].begin], level / 100.0, 1e-12);
    EXPECT_NEAR(s.values[runs[k].begin + 49], level / 2.0, 1e-12);
    EXPECT_DOUBLE_EQ(s.values[runs[k].begin + 99], level);
    EXPECT_DOUBLE_EQ(s.values[runs[k].end - 1], level);
  }
  EXPECT_DOUBLE_EQ(s.values[runs[0].end - 1], kThr);
  EXPECT_DOUBLE_EQ(s.values[runs[9].end - 1], kMax);
  EXPECT_DOUBLE_EQ(s.EndTime(), 330.0);
}

TEST(StimulusGenerators, ImpulseSeriesGives30Pulses1sApart) {
  const SampledSignal s =
      MakeStimulus("impulse_series", {{"threshold_ma", kThr}, {"max_ma", kMax}});
  const PulseTrain p = PulsesFromEnvelope(s, 33.0);
  ASSERT_EQ(p.size(), 30u);
  for (std::size_t k = 0; k < p.size(); ++k) {
    EXPECT_NEAR(p[k].t_s, static_cast<double>(k), 1e-12);
    EXPECT_NEAR(p[k].stim_ma, 15.0 + 30.0 * k / 29.0, 1e-12);
  }
  EXPECT_LT(p.front().stim_ma, kThr);
  EXPECT_DOUBLE_EQ(p.back().stim_ma, kMax);
  EXPECT_DOUBLE_EQ(s.EndTime(), 30.0);
}

TEST(StimulusGenerators, PlateauProfileIs11sStaircase) {
  const SampledSignal s =
      MakeStimulus("plateau_profile", {{"threshold_ma", kThr}, {"max_ma", kMax}});
  EXPECT_DOUBLE_EQ(s.EndTime(), 11.0);
  const double lo = 25.0;  // threshold + 5 mA
  const double expected[] = {lo,        lo + 5.0,  lo + 10.0, lo + 15.0, kMax,
                             lo + 15.0, lo + 10.0, lo + 5.0,  lo};
  for (int k = 0; k < 9; ++k) {
    // Plateau k holds over [0.5 + k + 0.25, 0.5 + k + 1) s.
    const auto first = static_cast<std::size_t>(std::lround((0.75 + k) * 200.0));
    const auto last = static_cast<std::size_t>(std::lround((1.5 + k) * 200.0)) - 1;
    EXPECT_DOUBLE_EQ(s.values[first - 1], expected[k]) << k;  // the ramp ends on the level
    EXPECT_DOUBLE_EQ(s.values[last], expected[k]) << k;
  }
  EXPECT_DOUBLE_EQ(s.values[99], 0.0);  // off until 0.5 s
  EXPECT_GT(s.values[100], 0.0);
  const auto runs = Runs(s);
  ASSERT_EQ(runs.size(), 1u);
  EXPECT_DOUBLE_EQ(runs[0].end * kDt, 9.75 - kDt);  // the last ramp sample is 0
}

TEST(StimulusGenerators, PredictionInputsOf5_4_5) {
  const GeneratorParams subject{{"threshold_ma", kThr}, {"max_ma", kMax}};
  const SampledSignal step = MakeStimulus("prediction_step", subject);
  auto runs = Runs(step);
  ASSERT_EQ(runs.size(), 1u);
  EXPECT_DOUBLE_EQ(runs[0].begin * kDt, 0.5);
  EXPECT_DOUBLE_EQ(runs[0].seconds(), 3.0);
  EXPECT_DOUBLE_EQ(step.values[runs[0].begin], 38.75);
  EXPECT_DOUBLE_EQ(step.EndTime(), 5.0);

  const SampledSignal ramp = MakeStimulus("prediction_ramp", {{"max_ma", kMax}});
  EXPECT_DOUBLE_EQ(ramp.EndTime(), 10.0);
  EXPECT_DOUBLE_EQ(ramp.values[0], 0.0);
  EXPECT_DOUBLE_EQ(ramp.values[1000], kMax);  // at 5 s
  EXPECT_NEAR(ramp.values[500], kMax / 2, 1e-12);
  EXPECT_NEAR(ramp.values[1500], kMax / 2, 1e-12);
  EXPECT_NEAR(ramp.values[1999], kMax / 1000.0, 1e-12);
  EXPECT_DOUBLE_EQ(MaxOf(ramp), kMax);

  const SampledSignal sine = MakeStimulus("prediction_sine", subject);
  EXPECT_DOUBLE_EQ(sine.EndTime(), 9.0);
  EXPECT_DOUBLE_EQ(sine.values[0], 25.0);     // threshold + 5 mA
  EXPECT_DOUBLE_EQ(sine.values[500], kMax);   // peak of the 5 s cycle at 2.5 s
  EXPECT_DOUBLE_EQ(sine.values[1000], 25.0);  // start of the 2 s cycle
  EXPECT_DOUBLE_EQ(sine.values[1200], kMax);  // its peak at 6 s
  EXPECT_DOUBLE_EQ(sine.values[1500], kMax);  // peak of the 1 s cycle at 7.5 s
  runs = Runs(sine);
  ASSERT_EQ(runs.size(), 1u);
  EXPECT_DOUBLE_EQ(runs[0].seconds(), 8.0);
}

TEST(StimulusGenerators, RandomBinaryIsSeededAndRespectsSwitchInterval) {
  for (const char* name : {"random_binary_sparse", "random_binary_dense"}) {
    const GeneratorParams p1{{"amplitude_ma", 30.0}, {"seed", 7.0}};
    const GeneratorParams p2{{"amplitude_ma", 30.0}, {"seed", 8.0}};
    const SampledSignal a = MakeStimulus(name, p1);
    const SampledSignal b = MakeStimulus(name, p1);
    const SampledSignal c = MakeStimulus(name, p2);
    EXPECT_EQ(a.values, b.values) << name;
    EXPECT_NE(a.values, c.values) << name;
    EXPECT_DOUBLE_EQ(a.EndTime(), 10.0);
    const double slot_s = FindStimulusGenerator(name)->FindParameter("min_switch_s")->default_value;
    const auto slot = static_cast<std::size_t>(std::lround(slot_s * 200.0));
    for (const SampledSignal* s : {&a, &c}) {
      const auto runs = Runs(*s);
      ASSERT_FALSE(runs.empty());
      EXPECT_EQ(runs[0].begin, 100u);  // starts ON right after the 0.5 s lead
      for (const NonZeroRun& r : runs) {
        EXPECT_EQ((r.begin - 100) % slot, 0u);  // switching only on slot boundaries
        EXPECT_GE(r.end - r.begin, slot);
        EXPECT_DOUBLE_EQ(s->values[r.begin], 30.0);
      }
      for (std::size_t k = 1; k < runs.size(); ++k)
        EXPECT_GE(runs[k].begin - runs[k - 1].end, slot);
    }
  }
}

TEST(StimulusGenerators, RandomBinaryDutyCyclesMatchMeans) {
  // Over many seeds the ON fraction of the active part approaches
  // mean_on / (mean_on + mean_off): 0.2 sparse, 0.5 dense. With ~40 000
  // slot samples per generator the standard error is < 0.02; 0.05 is safe.
  for (const auto& [name, expected] :
       {std::pair{"random_binary_sparse", 0.2}, std::pair{"random_binary_dense", 0.5}}) {
    double on = 0.0, total = 0.0;
    for (int seed = 1; seed <= 200; ++seed) {
      const SampledSignal s = MakeStimulus(name, {{"seed", seed}, {"duration_s", 60.0}});
      const double tail_s = FindStimulusGenerator(name)->FindParameter("tail_s")->default_value;
      const auto end = s.size() - static_cast<std::size_t>(std::lround(tail_s * 200.0));
      for (std::size_t i = 100; i < end; ++i) on += s.values[i] > 0.0 ? 1.0 : 0.0;
      total += static_cast<double>(end - 100);
    }
    EXPECT_NEAR(on / total, expected, 0.05) << name;
  }
}

}  // namespace
}  // namespace fesbench::model
