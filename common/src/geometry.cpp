#include "common/geometry.hpp"

#include <algorithm>

namespace common {

const char* toString(TriangleFeature f) {
  switch (f) {
    case TriangleFeature::kFace: return "face";
    case TriangleFeature::kEdgeAB: return "edge ab";
    case TriangleFeature::kEdgeBC: return "edge bc";
    case TriangleFeature::kEdgeCA: return "edge ca";
    case TriangleFeature::kVertexA: return "vertex a";
    case TriangleFeature::kVertexB: return "vertex b";
    case TriangleFeature::kVertexC: return "vertex c";
  }
  return "?";
}

double closestParameterOnSegment(const Vec3& p, const Vec3& a, const Vec3& b) {
  const Vec3 ab = b - a;
  const double len2 = ab.squaredNorm();
  if (len2 == 0.0) return 0.0;
  return std::clamp((p - a).dot(ab) / len2, 0.0, 1.0);
}

namespace {

ClosestPoint make(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c, double u, double v, double w,
                  TriangleFeature f) {
  ClosestPoint r;
  r.point = u * a + v * b + w * c;
  r.bary = {u, v, w};
  r.feature = f;
  r.distanceSquared = (p - r.point).squaredNorm();
  return r;
}

// A zero-area triangle is its three edges; the feature is the edge or end vertex that is closest.
ClosestPoint closestOnDegenerate(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  struct Edge {
    const Vec3 *s, *e;
    int is, ie;
    TriangleFeature edge;
  };
  const Edge edges[3] = {{&a, &b, 0, 1, TriangleFeature::kEdgeAB},
                         {&b, &c, 1, 2, TriangleFeature::kEdgeBC},
                         {&c, &a, 2, 0, TriangleFeature::kEdgeCA}};
  const TriangleFeature vertex[3] = {TriangleFeature::kVertexA, TriangleFeature::kVertexB, TriangleFeature::kVertexC};
  ClosestPoint best;
  best.distanceSquared = std::numeric_limits<double>::infinity();
  for (const auto& e : edges) {
    const double t = closestParameterOnSegment(p, *e.s, *e.e);
    std::array<double, 3> w{0.0, 0.0, 0.0};
    w[e.is] += 1.0 - t;
    w[e.ie] += t;
    const TriangleFeature f = t <= 0.0 ? vertex[e.is] : t >= 1.0 ? vertex[e.ie] : e.edge;
    ClosestPoint cand = make(p, a, b, c, w[0], w[1], w[2], f);
    if (cand.distanceSquared < best.distanceSquared) best = cand;
  }
  return best;
}

}  // namespace

ClosestPoint closestPointOnTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a;
  const Vec3 ac = c - a;
  const double scale2 = std::max({ab.squaredNorm(), ac.squaredNorm(), (c - b).squaredNorm()});
  // Relative area test: |ab x ac|² against (edge²)²; below 1e-24 the face normal is round-off.
  if (ab.cross(ac).squaredNorm() <= 1e-24 * scale2 * scale2) return closestOnDegenerate(p, a, b, c);

  const Vec3 ap = p - a;
  const double d1 = ab.dot(ap);
  const double d2 = ac.dot(ap);
  if (d1 <= 0.0 && d2 <= 0.0) return make(p, a, b, c, 1, 0, 0, TriangleFeature::kVertexA);

  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp);
  const double d4 = ac.dot(bp);
  if (d3 >= 0.0 && d4 <= d3) return make(p, a, b, c, 0, 1, 0, TriangleFeature::kVertexB);

  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
    const double v = d1 / (d1 - d3);
    return make(p, a, b, c, 1 - v, v, 0, TriangleFeature::kEdgeAB);
  }

  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp);
  const double d6 = ac.dot(cp);
  if (d6 >= 0.0 && d5 <= d6) return make(p, a, b, c, 0, 0, 1, TriangleFeature::kVertexC);

  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
    const double w = d2 / (d2 - d6);
    return make(p, a, b, c, 1 - w, 0, w, TriangleFeature::kEdgeCA);
  }

  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return make(p, a, b, c, 0, 1 - w, w, TriangleFeature::kEdgeBC);
  }

  const double denom = 1.0 / (va + vb + vc);
  const double v = vb * denom;
  const double w = vc * denom;
  return make(p, a, b, c, 1 - v - w, v, w, TriangleFeature::kFace);
}

}  // namespace common
