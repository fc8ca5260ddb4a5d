#pragma once

/// @file
/// Unit conversions. Every public quantity in fesbench carries its unit in its
/// name (docs/ARCHITECTURE.md, units); angles cross between degrees (the public unit) and
/// radians (used inside the equation of motion) only through these helpers.

#include <numbers>

namespace fesbench::model {

inline constexpr double kPi = std::numbers::pi;
inline constexpr double kRadPerDeg = kPi / 180.0;
inline constexpr double kDegPerRad = 180.0 / kPi;
inline constexpr double kStandardGravity_m_s2 = 9.80665;

/// Degrees to radians (also deg/s → rad/s, deg/s² → rad/s²).
constexpr double DegToRad(double deg) { return deg * kRadPerDeg; }
/// Radians to degrees (also rad/s → deg/s, rad/s² → deg/s²).
constexpr double RadToDeg(double rad) { return rad * kDegPerRad; }

}  // namespace fesbench::model
