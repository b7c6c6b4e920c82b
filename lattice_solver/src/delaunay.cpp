// gmsh's Delaunay: the tetrahedralisation of the node cloud (and the triangulation of a face's nodes for
// participant mode). The other gmsh use of liblattice is reading volumes (volume_geometry.cpp).
#include <algorithm>

#include <fmt/format.h>
#include <gmsh.h>

#include "common/errors.hpp"
#include "common/gmsh_session.hpp"
#include "lattice/specimen.hpp"

namespace lattice {

std::vector<Tetrahedron> delaunayTetrahedra(const std::vector<Vec3>& nodes) {
  std::vector<double> coords;
  coords.reserve(3 * nodes.size());
  for (const auto& p : nodes) coords.insert(coords.end(), {p.x(), p.y(), p.z()});
  std::vector<std::size_t> tets;
  {
    common::GmshSession session;
    try {
      gmsh::model::mesh::tetrahedralize(coords, tets);
    } catch (const std::exception& e) {
      throw common::SimulationError(fmt::format("gmsh could not tetrahedralise the {} lattice nodes: {}", nodes.size(), e.what()));
    }
  }
  std::vector<Tetrahedron> out(tets.size() / 4);
  for (std::size_t t = 0; t < out.size(); ++t)
    for (std::size_t k = 0; k < 4; ++k) out[t][k] = static_cast<std::uint32_t>(tets[4 * t + k] - 1);
  return out;
}

std::vector<Rod> tetrahedronEdges(const std::vector<Tetrahedron>& tets) {
  // Each edge keyed as a·2³² + b (a < b, 0-based): one sort makes them unique.
  std::vector<std::uint64_t> keys;
  keys.reserve(tets.size() * 6);
  constexpr int kEdges[6][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};
  for (const auto& tet : tets)
    for (const auto& e : kEdges) {
      std::uint64_t a = tet[static_cast<std::size_t>(e[0])], b = tet[static_cast<std::size_t>(e[1])];
      if (a > b) std::swap(a, b);
      if (a != b) keys.push_back((a << 32) | b);
    }
  std::sort(keys.begin(), keys.end());
  keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
  std::vector<Rod> rods(keys.size());
  for (std::size_t i = 0; i < keys.size(); ++i)
    rods[i] = {static_cast<std::uint32_t>(keys[i] >> 32), static_cast<std::uint32_t>(keys[i] & 0xffffffffu)};
  return rods;
}

std::vector<Rod> delaunayRods(const std::vector<Vec3>& nodes) { return tetrahedronEdges(delaunayTetrahedra(nodes)); }

std::vector<std::array<std::uint32_t, 3>> delaunayTriangles(const std::vector<Eigen::Vector2d>& points) {
  std::vector<double> coords;
  coords.reserve(2 * points.size());
  for (const auto& p : points) coords.insert(coords.end(), {p.x(), p.y()});
  std::vector<std::size_t> tri;
  {
    common::GmshSession session;
    try {
      gmsh::model::mesh::triangulate(coords, tri);
    } catch (const std::exception& e) {
      throw common::SimulationError(fmt::format("gmsh could not triangulate the {} face nodes: {}", points.size(), e.what()));
    }
  }
  std::vector<std::array<std::uint32_t, 3>> out;
  out.reserve(tri.size() / 3);
  for (std::size_t t = 0; t + 2 < tri.size(); t += 3)
    out.push_back({static_cast<std::uint32_t>(tri[t] - 1), static_cast<std::uint32_t>(tri[t + 1] - 1),
                   static_cast<std::uint32_t>(tri[t + 2] - 1)});
  return out;
}

}  // namespace lattice
