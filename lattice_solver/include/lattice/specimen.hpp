#pragma once
// A lattice specimen: nodes in a box, rods between them, and the concrete phase of every rod
// (lattice_solver/README.md, "Specimen"). Generation is deterministic for a seed.
//
// Call order: randomNodes() or cubicLattice() → delaunayRods() (random nodes only) → placeAggregates()
// → classifyRods(). The functions throw std::invalid_argument for arguments that cannot work (the scene
// reader turns them into located ConfigErrors) and PackingError when the aggregates do not fit.
// Units SI; node and rod indices are 0-based.

#include <array>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "lattice/sieve_curve.hpp"

namespace lattice {

using Vec3 = Eigen::Vector3d;
using Rod = std::array<std::uint32_t, 2>;

/// The three phases of concrete in the LGM (Kozicki & Tejchman 2007): a rod with both ends in the same
/// aggregate is aggregate, one end (or ends in two different aggregates) interfacial zone, else matrix.
enum class Phase : std::uint8_t { kMatrix = 0, kAggregate = 1, kInterface = 2 };
constexpr std::size_t kPhaseCount = 3;
const char* phaseName(Phase p);

struct Aggregate {
  Vec3 center;
  double radius;  ///< [m]
};

struct Box {
  Vec3 origin = Vec3::Zero();
  Vec3 size = Vec3::Ones();  ///< edge lengths [m]
  double volume() const { return size.prod(); }
};

struct Specimen {
  Box box;
  std::vector<Vec3> nodes;  ///< reference coordinates [m]
  std::vector<Rod> rods;    ///< node pairs, first < second
  std::vector<Phase> phases;  ///< per rod (all matrix until classifyRods)
  std::vector<Aggregate> aggregates;
  double meanRodLength() const;
};

/// Nodes for a random lattice of mean rod length `rodLength` in `box`: corners, then random points on
/// the edges, the faces and in the volume (so the convex hull is the box and the loaded faces carry
/// nodes), each at least `minDistance` × spacing from every other, where spacing = (V/N)^(1/3) is the
/// mean node distance. The count is calibrated so that the Delaunay rods have the requested mean length
/// (one correction pass; deterministic for `seed`). Throws std::invalid_argument when the rod length
/// does not fit the box or the hard-core distance cannot be met.
Specimen randomSpecimen(const Box& box, double rodLength, double minDistance, std::uint64_t seed);

/// The random points alone: mean node distance `spacing` [m], every two at least `minGap` [m] apart.
std::vector<Vec3> randomNodes(const Box& box, double spacing, double minGap, std::uint64_t seed);

/// The unique edges of the Delaunay tetrahedralisation of `nodes`, computed by gmsh
/// (gmsh::model::mesh::tetrahedralize); sorted, each rod {a, b} with a < b.
std::vector<Rod> delaunayRods(const std::vector<Vec3>& nodes);

/// The 2-D Delaunay triangulation of points given as (u, v) pairs, computed by gmsh
/// (gmsh::model::mesh::triangulate): triangles as 0-based indices into `points`. Participant mode uses it
/// for the interface mesh of a specimen face.
std::vector<std::array<std::uint32_t, 3>> delaunayTriangles(const std::vector<Eigen::Vector2d>& points);

/// A regular simple-cubic lattice: nodes on a grid of spacing ≈ `rodLength` (adjusted per axis so the
/// box holds a whole number of cells) and rods between grid neighbours along x, y and z.
Specimen cubicLattice(const Box& box, double rodLength);

struct PackingError : std::runtime_error {
  PackingError(const std::string& what, double packedFraction)
      : std::runtime_error(what), packedFraction(packedFraction) {}
  double packedFraction;  ///< the volume fraction reached before giving up
};

struct AggregateSettings {
  double volumeFraction = 0.0;  ///< target aggregate volume / specimen volume
  double gap = 0.0;             ///< least distance between two aggregate surfaces [m]
  int attempts = 20000;         ///< random positions tried per aggregate before giving up
  std::uint64_t seed = 1;
};

/// Spheres whose diameters follow `sieve` (by volume), totalling volumeFraction × V, placed largest
/// first at random positions fully inside the box without overlap (random sequential addition).
/// Throws PackingError naming the aggregate that found no place.
std::vector<Aggregate> placeAggregates(const Box& box, const SieveCurve& sieve, const AggregateSettings& s);

/// Sets specimen.phases from the aggregates: which aggregate (if any) holds each end of a rod.
void classifyRods(Specimen& specimen);

}  // namespace lattice
