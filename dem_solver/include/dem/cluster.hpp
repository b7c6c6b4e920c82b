#pragma once
// Rigid clusters of spheres: their files, mass properties and generation.
//
// Cluster file (YAML):
//   spheres: [[x, y, z, r], …]             member spheres in the cluster's own frame [m]
//   shape:                                  optional: mass properties of the true shape (e.g. the cube
//     volume: V                             the spheres approximate), used instead of the sphere union
//     center: [x, y, z]                     when the scene asks for `mass_properties: shape`
//     inertia_per_mass: [[..], [..], [..]]  inertia tensor about the center divided by the mass [m²]
//   comment: text                           free text (what generated it)

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/mesh_io.hpp"

namespace dem {

using Vec3 = Eigen::Vector3d;

/// Volume, centroid and inertia of a solid of unit density.
struct MassProperties {
  double volume = 0.0;                                ///< V [m³]
  Vec3 center = Vec3::Zero();                         ///< centroid [m]
  Eigen::Matrix3d inertiaPerMass = Eigen::Matrix3d::Zero();  ///< I/m about the centroid [m²]
};

struct ClusterShape {
  std::vector<Vec3> centers;
  std::vector<double> radii;
  std::optional<MassProperties> shape;  ///< of the true shape, when the file declares it
  std::string comment;
};

/// Reads a cluster file; errors are common::ConfigError with file, key path and line.
ClusterShape readClusterFile(const std::filesystem::path& file);
void writeClusterFile(const std::filesystem::path& file, const ClusterShape& cluster);

/// Mass properties of the union of the spheres (overlaps counted once). Spheres that overlap no other
/// are integrated exactly; otherwise the union is integrated by the midpoint rule on a grid of
/// `resolution` cells along the longest side of its bounding box (relative volume error ~ 1/resolution²
/// for smooth parts of the surface; tested against the lens of two spheres).
MassProperties unionMassProperties(const std::vector<Vec3>& centers, const std::vector<double>& radii,
                                   int resolution = 160);

/// Mass properties of a box of edges `size`, centred at the origin.
MassProperties boxMassProperties(const Vec3& size);

/// A cube of edge `edge` filled by n³ spheres on a cubic lattice (n = 1: one sphere of the cube's volume),
/// radius chosen so that the union has the cube's volume. Declares the cube's own mass properties.
ClusterShape makeCubeCluster(double edge, int n);
/// n³ touching spheres on a cubic lattice in a cube of `edge` (r = edge / 2n): a block to bond, whose
/// spheres do not overlap (its volume is π/6 of the cube's).
ClusterShape makeCubeLattice(double edge, int n);
/// nx × ny × nz touching spheres of diameter `spacing` on a cubic lattice, centred at the origin: a slab or
/// a bar to bond.
ClusterShape makeBoxLattice(double spacing, const Eigen::Vector3i& n);
/// The largest overlap of two spheres, relative to their radii sum, (r_a + r_b − d)/(r_a + r_b), and the
/// pair (≤ 0: none overlap).
std::pair<double, std::pair<std::size_t, std::size_t>> largestOverlap(const std::vector<Vec3>& centers,
                                                                     const std::vector<double>& radii);

/// Mass properties of the solid bounded by a closed triangle mesh (divergence theorem over the signed
/// tetrahedra from the origin; exact for the polyhedron; either orientation).
MassProperties meshMassProperties(const common::TriangleMesh& mesh);

/// True when p is inside the closed mesh (generalised winding number > 1/2; robust to small gaps).
bool insideMesh(const common::TriangleMesh& mesh, const Vec3& p);

/// Fills a closed surface mesh with spheres on a cubic lattice of spacing (V/count)^{1/3} (points inside
/// the mesh), radius chosen so the union's volume equals the mesh volume. Declares the mesh's own mass
/// properties. Throws common::SimulationError if the mesh is not closed (zero volume) or nothing fits.
ClusterShape fillMesh(const common::TriangleMesh& mesh, std::size_t count);

}  // namespace dem
