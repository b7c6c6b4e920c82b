#pragma once
// Small geometry shared by the solvers and the coupler: axis-aligned boxes and the closest point on a
// triangle with the feature it lies on (used by DEM mesh walls for face/edge/vertex contact rules and
// by the coupler's nearest-projection mapping). Double precision, SI units, no allocation.

#include <array>
#include <limits>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace common {

using Vec3 = Eigen::Vector3d;

/// Axis-aligned bounding box. A default-constructed box is empty (min = +inf, max = -inf).
struct Aabb {
  Vec3 min = Vec3::Constant(std::numeric_limits<double>::infinity());
  Vec3 max = Vec3::Constant(-std::numeric_limits<double>::infinity());

  bool empty() const { return (min.array() > max.array()).any(); }
  void expand(const Vec3& p) {
    min = min.cwiseMin(p);
    max = max.cwiseMax(p);
  }
  void expand(const Aabb& b) {
    min = min.cwiseMin(b.min);
    max = max.cwiseMax(b.max);
  }
  /// Grows the box by `margin` on every side (a Verlet skin, a sphere radius).
  Aabb inflated(double margin) const { return {min.array() - margin, max.array() + margin}; }
  bool contains(const Vec3& p) const { return (p.array() >= min.array()).all() && (p.array() <= max.array()).all(); }
  /// Closed-interval overlap: boxes that touch overlap.
  bool overlaps(const Aabb& b) const {
    return (min.array() <= b.max.array()).all() && (b.min.array() <= max.array()).all();
  }
  /// Euclidean distance from p to the box (0 inside).
  double distance(const Vec3& p) const {
    const Vec3 d = (min - p).cwiseMax(p - max).cwiseMax(Vec3::Zero());
    return d.norm();
  }
  Vec3 center() const { return 0.5 * (min + max); }
  Vec3 extent() const { return max - min; }
};

/// The feature of triangle (a, b, c) a closest point lies on. Edges are named by their vertices:
/// kEdgeAB = edge a-b, and so on. The barycentric weights are those of the closest point.
enum class TriangleFeature { kFace, kEdgeAB, kEdgeBC, kEdgeCA, kVertexA, kVertexB, kVertexC };

const char* toString(TriangleFeature f);

struct ClosestPoint {
  Vec3 point;                 ///< closest point on the triangle [m]
  std::array<double, 3> bary; ///< barycentric weights of point w.r.t. (a, b, c), summing to 1
  TriangleFeature feature;
  double distanceSquared;     ///< |p - point|² [m²]
};

/// Closest point of the triangle (a, b, c) to p, by Voronoi regions of the features (Ericson,
/// Real-Time Collision Detection, 2005, §5.1.5). Degenerate triangles (zero area: coincident or
/// collinear vertices) are handled as segments or points: the feature then names the edge or vertex
/// that realises the distance, never kFace.
ClosestPoint closestPointOnTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c);

/// Closest point on segment a-b, as the parameter t in [0, 1] (point = a + t (b - a)).
double closestParameterOnSegment(const Vec3& p, const Vec3& a, const Vec3& b);

}  // namespace common
