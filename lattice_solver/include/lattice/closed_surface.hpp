#pragma once
// A closed triangle surface — the boundary of a specimen volume — with the queries specimen generation
// needs: is a point inside, is a ball clear of the surface, the enclosed volume. Pure geometry: the gmsh
// reading is in volume_geometry.hpp.
//
// Inside test: parity of the crossings of a ray from the point (a fixed, deliberately non-axis-aligned
// direction, so rays do not run along faces of boxes and prisms; a hit within 1e-9 of a triangle's edge
// or vertex retries with the next of three directions). Points within tolerance() of a triangle count as
// inside (points on the surface: face nodes, midpoints of rods along a face). gmsh's own
// gmsh::model::isInside (4.8) takes parametric coordinates of curves and surfaces only, not volumes.
// Triangles are binned in a uniform 3-D grid (distance queries) and a 2-D grid across each ray
// direction (crossings), so a query costs O(triangles near the point or its ray), not O(triangles).
//
// Thread safe for concurrent queries (const, no caches). Units SI.

#include <array>
#include <cstdint>
#include <vector>

#include "lattice/specimen.hpp"

namespace lattice {

using Triangle = std::array<std::uint32_t, 3>;

class ClosedSurface {
 public:
  /// `triangles` index `vertices`. They must close (every edge shared by exactly two triangles, shared
  /// vertices shared by index); throws std::invalid_argument naming the open edges otherwise. Their
  /// orientation does not matter (volume() orients them).
  ClosedSurface(std::vector<Vec3> vertices, std::vector<Triangle> triangles);

  const std::vector<Vec3>& vertices() const { return vertices_; }
  const std::vector<Triangle>& triangles() const { return triangles_; }
  /// Bounding box of the vertices.
  const Box& bounds() const { return bounds_; }
  /// Enclosed volume [m³] (divergence theorem over the consistently oriented triangles).
  double volume() const { return volume_; }
  /// Distance under which a point counts as on the surface [m]: 1e-9 of the box's size and position.
  double tolerance() const { return tolerance_; }

  /// True for p inside the surface or within tolerance() of it.
  bool contains(const Vec3& p) const { return contains(p, tolerance_); }
  /// True for p inside the surface or within `margin` [m] of it.
  bool contains(const Vec3& p, double margin) const;
  /// True when no triangle comes closer to p than r.
  bool clearOf(const Vec3& p, double r) const;

 private:
  struct Grid2 {  // triangles binned by their projection on the plane normal to the ray direction
    Vec3 dir, u, v;
    double lo[2]{}, cell = 1;
    long dims[2]{1, 1};
    std::vector<std::uint32_t> start, items;
  };
  Grid2 buildGrid2(const Vec3& dir) const;
  // Crossings of the ray p + t·dir (t > 0); -1 when a hit is too close to an edge to count.
  int crossings(const Grid2& g, const Vec3& p) const;
  template <class F>
  bool forTrianglesNear(const Vec3& lo, const Vec3& hi, F&& f) const;

  std::vector<Vec3> vertices_;
  std::vector<Triangle> triangles_;
  Box bounds_;
  double volume_ = 0.0, tolerance_ = 0.0, cell_ = 1.0;
  std::array<long, 3> dims_{};
  std::vector<std::uint32_t> start_, items_;  // 3-D grid: triangles per cell (CSR)
  std::array<Grid2, 3> rays_;
};

}  // namespace lattice
