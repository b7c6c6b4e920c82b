#pragma once
// The zone a bridging domain shares between a continuum and particles (Xiao & Belytschko 2004;
// docs/validation/bridging.md): along `axis`, a participant's energy weight is 1 at the coordinate `full`
// and falls to 0 at `none`, linearly or (`shape: cubic`) as 3s² − 2s³ of the linear s, which leaves the
// zone with zero slope at both ends. Both shapes satisfy w(1 − s) = 1 − w(s), so both participants' scenes
// give the same zone, each with its own `full` end (the continuum's α and the particles' β = 1 − α); the
// coupler checks that they sum to one.
//
//   bridging: {axis: x, full: 0.40, none: 0.60, shape: linear, min_weight: 0.01}
//
// A weight below `min_weight` is raised to it where a mass is scaled: an element or a particle at the
// far end of the zone keeps a mass of its own (its stable step stays its unweighted one), at an energy
// error of at most that share in the last cell.
#include <algorithm>
#include <string>
#include <string_view>

#include <Eigen/Core>

#include "common/config.hpp"

namespace common {

struct BridgingZone {
  enum class Shape { kLinear = 0, kCubic = 1 };
  Eigen::Vector3d axis = Eigen::Vector3d::UnitX();
  double full = 0.0, none = 1.0, minWeight = 0.01;
  Shape shape = Shape::kLinear;

  /// The weight of the linear coordinate s ∈ [0, 1].
  static double shaped(Shape shape, double s) { return shape == Shape::kCubic ? s * s * (3.0 - 2.0 * s) : s; }

  /// The linear function that is 1 at `full` and 0 at `none`, not clamped: interpolated from a mesh's
  /// nodes it is exact anywhere in its elements (the clamped weight has kinks at the zone's ends).
  double linear(const Eigen::Vector3d& x) const { return (axis.dot(x) - none) / (full - none); }
  /// The weight at x: 1 at `full` and beyond, 0 at `none` and beyond.
  double weight(const Eigen::Vector3d& x) const { return shaped(shape, std::clamp(linear(x), 0.0, 1.0)); }
  /// The weight a mass or an element is scaled by.
  double massWeight(const Eigen::Vector3d& x) const { return std::max(weight(x), minWeight); }
  /// In the overlap: the weight is below one.
  bool overlaps(const Eigen::Vector3d& x) const { return weight(x) < 1.0; }
};

/// A coordinate axis named by the key (`x`, `y` or `z`; `fallback` when the key is absent, if given).
inline Eigen::Vector3d readAxis(const Config& c, std::string_view key, const char* fallback = nullptr) {
  const std::string axis = fallback ? c.choice(key, {"x", "y", "z"}, fallback) : c.choice(key, {"x", "y", "z"});
  return axis == "x" ? Eigen::Vector3d::UnitX() : axis == "y" ? Eigen::Vector3d::UnitY() : Eigen::Vector3d::UnitZ();
}

inline BridgingZone readBridgingZone(const Config& c) {
  BridgingZone z;
  z.axis = readAxis(c, "axis");
  z.full = c.get<double>("full");
  z.none = c.get<double>("none");
  if (!(z.full != z.none)) c.failAt("none", "must differ from `full`: the zone has a width over which the weight falls");
  z.minWeight = c.get("min_weight", 0.01, Interval::open(0.0, 1.0));
  if (c.choice("shape", {"linear", "cubic"}, "linear") == "cubic") z.shape = BridgingZone::Shape::kCubic;
  c.checkUnknownKeys();
  return z;
}

}  // namespace common
