#include "model/trajectory.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <string>

#include "model/units.h"

namespace fesbench::model {
namespace {

[[noreturn]] void Fail(std::string_view where, std::string_view parameter, std::string_view why) {
  throw std::invalid_argument(std::string(where) + ": parameter '" + std::string(parameter) + "' " +
                              std::string(why));
}

double Uniform01(std::mt19937_64& rng) { return static_cast<double>(rng() >> 11) * 0x1.0p-53; }

// Quintic smoothstep S(u) = 10u³ − 15u⁴ + 6u⁵ and its first two derivatives
// with respect to u.
std::array<double, 3> Smoothstep5(double u) {
  const double u2 = u * u;
  return {u2 * u * (10.0 - 15.0 * u + 6.0 * u2), 30.0 * u2 * (1.0 - 2.0 * u + u2),
          60.0 * u * (1.0 - 3.0 * u + 2.0 * u2)};
}

}  // namespace

// --- sum of sines (§4.2.2) ------------------------------------------------

SumOfSinesTrajectory::SumOfSinesTrajectory(const SumOfSinesOptions& o) : options_(o) {
  constexpr const char* kWhere = "SumOfSinesTrajectory";
  if (!std::isfinite(o.min_deg) || !std::isfinite(o.max_deg) || !(o.min_deg < o.max_deg)) {
    Fail(kWhere, "min_deg", "must be finite and below max_deg");
  }
  if (!(o.max_velocity_deg_s > 0.0) || !std::isfinite(o.max_velocity_deg_s)) {
    Fail(kWhere, "max_velocity_deg_s", "must be positive");
  }
  if (!(o.fade_s > 0.0)) Fail(kWhere, "fade_s", "must be positive");
  if (!(o.duration_s > 2.0 * o.fade_s) || !std::isfinite(o.duration_s)) {
    Fail(kWhere, "duration_s", "must exceed 2 * fade_s");
  }
  if (o.sines < 1) Fail(kWhere, "sines", "must be at least 1");
  if (!(o.min_frequency_hz > 0.0)) Fail(kWhere, "min_frequency_hz", "must be positive");
  if (!(o.max_frequency_hz >= o.min_frequency_hz) || !std::isfinite(o.max_frequency_hz)) {
    Fail(kWhere, "max_frequency_hz", "must be finite and >= min_frequency_hz");
  }

  std::mt19937_64 rng(o.seed);
  for (int i = 0; i < o.sines; ++i) {
    SineComponent c;
    c.frequency_hz =
        o.min_frequency_hz + (o.max_frequency_hz - o.min_frequency_hz) * Uniform01(rng);
    c.phase_rad = 2.0 * kPi * Uniform01(rng);
    c.amplitude = 0.5 + 0.5 * Uniform01(rng);
    components_.push_back(c);
  }

  // Extremes of x and |ẋ| on a 10 kHz grid.
  const auto n = static_cast<std::size_t>(std::ceil(o.duration_s * 1e4));
  double x_min = 0.0, x_max = 0.0, v_peak = 0.0;
  for (std::size_t k = 0; k <= n; ++k) {
    const auto x = Unscaled(o.duration_s * static_cast<double>(k) / static_cast<double>(n));
    x_min = std::min(x_min, x[0]);
    x_max = std::max(x_max, x[0]);
    v_peak = std::max(v_peak, std::abs(x[1]));
  }
  const double range_deg = o.max_deg - o.min_deg;
  scale_deg_ = 0.999 * std::min(range_deg / (x_max - x_min), o.max_velocity_deg_s / v_peak);
  centre_deg_ = 0.5 * (o.min_deg + o.max_deg) - scale_deg_ * 0.5 * (x_min + x_max);
}

std::array<double, 3> SumOfSinesTrajectory::Unscaled(double t_s) const {
  double g = 0.0, dg = 0.0, ddg = 0.0;
  for (const auto& c : components_) {
    const double w = 2.0 * kPi * c.frequency_hz;
    const double arg = w * t_s + c.phase_rad;
    const double s = std::sin(arg), co = std::cos(arg);
    g += c.amplitude * s;
    dg += c.amplitude * w * co;
    ddg -= c.amplitude * w * w * s;
  }
  // Fade window w(t): smoothstep over [0, fade] and mirrored over the end.
  const double fade = options_.fade_s;
  std::array<double, 3> win{1.0, 0.0, 0.0};
  if (t_s < fade) {
    const auto s = Smoothstep5(t_s / fade);
    win = {s[0], s[1] / fade, s[2] / (fade * fade)};
  } else if (t_s > options_.duration_s - fade) {
    const auto s = Smoothstep5((options_.duration_s - t_s) / fade);
    win = {s[0], -s[1] / fade, s[2] / (fade * fade)};
  }
  // x = w·g, ẋ = ẇg + wġ, ẍ = ẅg + 2ẇġ + wg̈.
  return {win[0] * g, win[1] * g + win[0] * dg, win[2] * g + 2.0 * win[1] * dg + win[0] * ddg};
}

Kinematics SumOfSinesTrajectory::At(double t_s) const {
  const double t = std::clamp(t_s, 0.0, options_.duration_s);
  const auto x = Unscaled(t);
  if (t != t_s) return {centre_deg_ + scale_deg_ * x[0], 0.0, 0.0};
  return {centre_deg_ + scale_deg_ * x[0], scale_deg_ * x[1], scale_deg_ * x[2]};
}

// --- piecewise polynomial --------------------------------------------------

PiecewisePolynomialTrajectory::PiecewisePolynomialTrajectory(std::vector<Piece> pieces)
    : pieces_(std::move(pieces)) {
  if (pieces_.empty()) throw std::invalid_argument("PiecewisePolynomialTrajectory: no pieces");
  if (std::abs(pieces_.front().start_s) > 1e-6) {
    throw std::invalid_argument("PiecewisePolynomialTrajectory: first piece must start at 0");
  }
  for (std::size_t i = 0; i < pieces_.size(); ++i) {
    if (!(pieces_[i].duration_s > 0.0)) {
      throw std::invalid_argument("PiecewisePolynomialTrajectory: piece " + std::to_string(i) +
                                  " has a non-positive duration");
    }
    if (i > 0 &&
        std::abs(pieces_[i].start_s - pieces_[i - 1].start_s - pieces_[i - 1].duration_s) > 1e-6) {
      throw std::invalid_argument("PiecewisePolynomialTrajectory: piece " + std::to_string(i) +
                                  " is not contiguous with the previous one");
    }
  }
}

double PiecewisePolynomialTrajectory::duration_s() const {
  return pieces_.back().start_s + pieces_.back().duration_s;
}

Kinematics PiecewisePolynomialTrajectory::At(double t_s) const {
  auto eval = [](const Piece& p, double tau) {
    const auto& c = p.coefficients;
    double a = 0.0, v = 0.0, acc = 0.0;
    for (int j = 5; j >= 0; --j) a = a * tau + c[static_cast<std::size_t>(j)];
    for (int j = 5; j >= 1; --j) v = v * tau + j * c[static_cast<std::size_t>(j)];
    for (int j = 5; j >= 2; --j) acc = acc * tau + j * (j - 1) * c[static_cast<std::size_t>(j)];
    return Kinematics{a, v, acc};
  };
  if (t_s <= 0.0) return {pieces_.front().coefficients[0], 0.0, 0.0};
  if (t_s >= duration_s()) {
    const Piece& last = pieces_.back();
    return {eval(last, last.duration_s).angle_deg, 0.0, 0.0};
  }
  // Last piece whose start is <= t.
  const auto it = std::upper_bound(pieces_.begin(), pieces_.end(), t_s,
                                   [](double t, const Piece& p) { return t < p.start_s; });
  const Piece& p = *std::prev(it);
  return eval(p, t_s - p.start_s);
}

// --- §5.4.1 sequential plans ------------------------------------------------
namespace {

class PlanBuilder {
 public:
  explicit PlanBuilder(double angle_deg) : angle_(angle_deg) {}
  double t() const { return t_; }
  double angle() const { return angle_; }

  void Hold(double d) {
    if (d > 0.0) Add(d, {angle_, 0, 0, 0, 0, 0});
  }
  // Minimum-jerk move: θ = θa + Δ(10u³ − 15u⁴ + 6u⁵), u = τ/T.
  void Move(double to_deg, double d) {
    const double delta = to_deg - angle_;
    Add(d, {angle_, 0, 0, 10 * delta / std::pow(d, 3), -15 * delta / std::pow(d, 4),
            6 * delta / std::pow(d, 5)});
    angle_ = to_deg;
  }
  // Velocity 0 → v as v(3u² − 2u³): θ = θ0 + v·Ta·(u³ − u⁴/2).
  void Accelerate(double v, double d) {
    Add(d, {angle_, 0, 0, v / (d * d), -v / (2 * d * d * d), 0});
    angle_ += v * d / 2;
  }
  void Cruise(double v, double d) {
    Add(d, {angle_, v, 0, 0, 0, 0});
    angle_ += v * d;
  }
  // Velocity v → 0 as v(1 − 3u² + 2u³): θ = θ0 + v·Td·(u − u³ + u⁴/2).
  void Decelerate(double v, double d) {
    Add(d, {angle_, v, 0, -v / (d * d), v / (2 * d * d * d), 0});
    angle_ += v * d / 2;
  }
  PiecewisePolynomialTrajectory Build() && {
    return PiecewisePolynomialTrajectory(std::move(pieces_));
  }

 private:
  void Add(double d, std::array<double, 6> c) {
    pieces_.push_back({t_, d, c});
    t_ += d;
  }
  double t_ = 0.0;
  double angle_;
  std::vector<PiecewisePolynomialTrajectory::Piece> pieces_;
};

}  // namespace

SequentialPlan PassivePositions(const PassivePositionsOptions& o) {
  constexpr const char* kWhere = "PassivePositions";
  for (const auto& [name, v] : {std::pair{"start_deg", o.start_deg},
                                std::pair{"max_deg", o.max_deg}, std::pair{"min_deg", o.min_deg}}) {
    if (!std::isfinite(v)) Fail(kWhere, name, "must be finite");
  }
  if (!(o.min_deg < o.max_deg)) Fail(kWhere, "min_deg", "must be below max_deg");
  if (o.positions < 2) Fail(kWhere, "positions", "must be at least 2");
  if (!(o.hold_s > 0.0)) Fail(kWhere, "hold_s", "must be positive");
  if (!(o.move_s > 0.0)) Fail(kWhere, "move_s", "must be positive");
  if (!(o.reference_s >= 0.0)) Fail(kWhere, "reference_s", "must be >= 0");

  std::vector<double> angles;
  for (int k = 0; k < o.positions; ++k) {
    angles.push_back(o.max_deg - (o.max_deg - o.min_deg) * k / (o.positions - 1));
  }
  for (int k = o.positions - 1; k >= 0; --k) angles.push_back(angles[static_cast<std::size_t>(k)]);

  PlanBuilder b(o.start_deg);
  std::vector<MeasurementWindow> windows;
  b.Hold(o.reference_s);
  for (const double a : angles) {
    if (a == b.angle()) {
      b.Hold(o.move_s);
    } else {
      b.Move(a, o.move_s);
    }
    windows.push_back({b.t(), b.t() + o.hold_s, a, 0.0});
    b.Hold(o.hold_s);
  }
  b.Move(o.start_deg, o.move_s);
  return {std::move(b).Build(), std::move(windows)};
}

SequentialPlan PassiveVelocities(const PassiveVelocitiesOptions& o) {
  constexpr const char* kWhere = "PassiveVelocities";
  if (!std::isfinite(o.reference_deg)) Fail(kWhere, "reference_deg", "must be finite");
  if (!(o.min_deg < o.reference_deg)) Fail(kWhere, "min_deg", "must be below reference_deg");
  if (o.speeds < 1) Fail(kWhere, "speeds", "must be at least 1");
  if (!(o.max_speed_deg_s > 0.0)) Fail(kWhere, "max_speed_deg_s", "must be positive");
  if (!(o.accel_s > 0.0)) Fail(kWhere, "accel_s", "must be positive");
  if (!(o.constant_s > 0.0)) Fail(kWhere, "constant_s", "must be positive");
  if (!(o.decel_s > 0.0)) Fail(kWhere, "decel_s", "must be positive");
  if (!(o.pause_s >= 0.0)) Fail(kWhere, "pause_s", "must be >= 0");
  const double travel_per_speed = 0.5 * o.accel_s + o.constant_s + 0.5 * o.decel_s;
  if (o.reference_deg - o.max_speed_deg_s * travel_per_speed < o.min_deg - 1e-9) {
    Fail(kWhere, "max_speed_deg_s",
         "moves the limb below min_deg (travel = speed * " + std::to_string(travel_per_speed) +
             " s)");
  }

  PlanBuilder b(o.reference_deg);
  std::vector<MeasurementWindow> windows;
  for (int k = 1; k <= o.speeds; ++k) {
    const double speed = o.max_speed_deg_s * k / o.speeds;
    for (const double v : {-speed, speed}) {
      b.Hold(o.pause_s);
      b.Accelerate(v, o.accel_s);
      windows.push_back({b.t(), b.t() + o.constant_s, b.angle(), v});
      b.Cruise(v, o.constant_s);
      b.Decelerate(v, o.decel_s);
    }
  }
  return {std::move(b).Build(), std::move(windows)};
}

// --- registry ---------------------------------------------------------------
namespace {

struct Entry {
  GeneratorDescription description;
  std::unique_ptr<Trajectory> (*build)(const GeneratorParams&);
};

std::unique_ptr<Trajectory> BuildSumOfSines(const GeneratorParams& p) {
  SumOfSinesOptions o;
  o.min_deg = p.at("min_deg");
  o.max_deg = p.at("max_deg");
  o.max_velocity_deg_s = p.at("max_velocity_deg_s");
  o.duration_s = p.at("duration_s");
  o.fade_s = p.at("fade_s");
  o.sines = static_cast<int>(p.at("sines"));
  o.min_frequency_hz = p.at("min_frequency_hz");
  o.max_frequency_hz = p.at("max_frequency_hz");
  o.seed = static_cast<std::uint64_t>(p.at("seed"));
  return std::make_unique<SumOfSinesTrajectory>(o);
}

std::unique_ptr<Trajectory> BuildPassivePositions(const GeneratorParams& p) {
  PassivePositionsOptions o;
  o.start_deg = p.at("start_deg");
  o.max_deg = p.at("max_deg");
  o.min_deg = p.at("min_deg");
  o.positions = static_cast<int>(p.at("positions"));
  o.hold_s = p.at("hold_s");
  o.move_s = p.at("move_s");
  o.reference_s = p.at("reference_s");
  return std::make_unique<PiecewisePolynomialTrajectory>(PassivePositions(o).trajectory);
}

std::unique_ptr<Trajectory> BuildPassiveVelocities(const GeneratorParams& p) {
  PassiveVelocitiesOptions o;
  o.reference_deg = p.at("reference_deg");
  o.min_deg = p.at("min_deg");
  o.speeds = static_cast<int>(p.at("speeds"));
  o.max_speed_deg_s = p.at("max_speed_deg_s");
  o.accel_s = p.at("accel_s");
  o.constant_s = p.at("constant_s");
  o.decel_s = p.at("decel_s");
  o.pause_s = p.at("pause_s");
  return std::make_unique<PiecewisePolynomialTrajectory>(PassiveVelocities(o).trajectory);
}

const std::vector<Entry>& Registry() {
  static const std::vector<Entry> entries = [] {
    const SumOfSinesOptions s;
    const PassivePositionsOptions pp;
    const PassiveVelocitiesOptions pv;
    std::vector<Entry> r;
    r.push_back(
        {{"sum_of_sines",
          "seeded pseudo-random sum of six sines scaled to the subject's range (§4.2.2, §5.4.2)",
          {{"min_deg", "lower angle limit, deg", s.min_deg, 0.0, 180.0, false},
           {"max_deg", "upper angle limit, deg", s.max_deg, 0.0, 180.0, false},
           {"max_velocity_deg_s", "velocity limit, deg/s", s.max_velocity_deg_s, 1.0, 1000.0,
            false},
           {"duration_s", "length, s", s.duration_s, 1.0, 600.0, false},
           {"fade_s", "fade-in/out at each end, s", s.fade_s, 0.05, 10.0, false},
           {"sines", "number of sine components", 6.0, 1.0, 32.0, true},
           {"min_frequency_hz", "lowest component frequency, Hz", s.min_frequency_hz, 0.01, 10.0,
            false},
           {"max_frequency_hz", "highest component frequency, Hz", s.max_frequency_hz, 0.01, 10.0,
            false},
           {"seed", "random seed", 1.0, 0.0, 4294967295.0, true}}},
         &BuildSumOfSines});
    r.push_back(
        {{"passive_positions",
          "20 holds 110 deg -> extension and back, 10 s each, minimum-jerk moves (§5.4.1)",
          {{"start_deg", "reference angle at start and end, deg", pp.start_deg, 0.0, 180.0, false},
           {"max_deg", "first (largest flexion) angle, deg", pp.max_deg, 0.0, 180.0, false},
           {"min_deg", "full extension angle, deg", pp.min_deg, 0.0, 180.0, false},
           {"positions", "number of angles per pass", 20.0, 2.0, 200.0, true},
           {"hold_s", "hold at each angle, s", pp.hold_s, 0.1, 120.0, false},
           {"move_s", "move between angles, s", pp.move_s, 0.05, 60.0, false},
           {"reference_s", "hold at start_deg before the first move, s", pp.reference_s, 0.0, 120.0,
            false}}},
         &BuildPassivePositions});
    r.push_back(
        {{"passive_velocities",
          "8 speeds x 2 directions of constant-velocity moves from 90 deg, 10 s pauses (§5.4.1)",
          {{"reference_deg", "reference angle, deg", pv.reference_deg, 0.0, 180.0, false},
           {"min_deg", "extension limit for the moves, deg", pv.min_deg, 0.0, 180.0, false},
           {"speeds", "number of speeds", 8.0, 1.0, 50.0, true},
           {"max_speed_deg_s", "fastest speed, deg/s", pv.max_speed_deg_s, 0.1, 1000.0, false},
           {"accel_s", "acceleration phase, s", pv.accel_s, 0.01, 10.0, false},
           {"constant_s", "constant-velocity phase, s", pv.constant_s, 0.01, 10.0, false},
           {"decel_s", "deceleration phase, s", pv.decel_s, 0.01, 10.0, false},
           {"pause_s", "pause before each move, s", pv.pause_s, 0.0, 120.0, false}}},
         &BuildPassiveVelocities});
    return r;
  }();
  return entries;
}

}  // namespace

const std::vector<GeneratorDescription>& TrajectoryGenerators() {
  static const std::vector<GeneratorDescription> list = [] {
    std::vector<GeneratorDescription> r;
    for (const auto& e : Registry()) r.push_back(e.description);
    return r;
  }();
  return list;
}

const GeneratorDescription* FindTrajectoryGenerator(std::string_view name) {
  for (const auto& e : Registry()) {
    if (e.description.name == name) return &e.description;
  }
  return nullptr;
}

std::unique_ptr<Trajectory> MakeTrajectory(std::string_view name, const GeneratorParams& params) {
  for (const auto& e : Registry()) {
    if (e.description.name != name) continue;
    const GeneratorParams resolved = ResolveParameters(e.description, params);
    try {
      return e.build(resolved);
    } catch (const std::invalid_argument& err) {
      throw std::invalid_argument("trajectory '" + std::string(name) + "': " + err.what());
    }
  }
  throw std::invalid_argument("unknown trajectory generator '" + std::string(name) + "'");
}

TrajectorySamples SampleTrajectory(const Trajectory& trajectory, double rate_hz) {
  if (!(rate_hz > 0.0) || !std::isfinite(rate_hz)) {
    throw std::invalid_argument("SampleTrajectory: rate_hz must be positive");
  }
  TrajectorySamples out;
  out.rate_hz = rate_hz;
  const auto n = static_cast<std::size_t>(std::floor(trajectory.duration_s() * rate_hz + 1e-9)) + 1;
  out.angle_deg.reserve(n);
  out.velocity_deg_s.reserve(n);
  out.accel_deg_s2.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    const Kinematics k = trajectory.At(static_cast<double>(i) / rate_hz);
    out.angle_deg.push_back(k.angle_deg);
    out.velocity_deg_s.push_back(k.velocity_deg_s);
    out.accel_deg_s2.push_back(k.accel_deg_s2);
  }
  return out;
}

}  // namespace fesbench::model
