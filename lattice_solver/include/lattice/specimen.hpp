#pragma once
// A lattice specimen: nodes in a box, rods between them, and the concrete phase of every rod
// (lattice_solver/README.md, "Specimen"). Generation is deterministic for a seed.
//
// Call order: randomSpecimen() (a box or a closed gmsh volume) or cubicLattice() → placeAggregates() →
// classifyRods(). The functions throw std::invalid_argument for arguments that cannot work (the scene
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
using Tetrahedron = std::array<std::uint32_t, 4>;
class ClosedSurface;
struct VolumeGeometry;

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
  Box box;  ///< the box, or the bounding box of a volume specimen
  std::vector<Vec3> nodes;  ///< reference coordinates [m]
  std::vector<Rod> rods;    ///< node pairs, first < second
  std::vector<Phase> phases;  ///< per rod (all matrix until classifyRods)
  std::vector<Aggregate> aggregates;
  double solidVolume = 0.0;  ///< volume specimens: the sum of the kept tetrahedra [m³] (0 for a box)
  double volume() const { return solidVolume > 0 ? solidVolume : box.volume(); }
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

/// A random specimen in a closed volume (README "Specimen from a gmsh volume"): nodes at the geometry's
/// corner points, on its boundary curves and surfaces (sampled on their mesh) and inside (darts in the
/// bounding box kept when inside), the Delaunay tetrahedra of all of them, and of those only the ones
/// whose centroid and six edge midpoints lie inside, or within 0.05 rod lengths of the surface (keepInside). Spacing calibrated as for the box;
/// box = the bounding box, solidVolume = the kept tetrahedra's volume.
Specimen randomSpecimen(const VolumeGeometry& geometry, double rodLength, double minDistance, std::uint64_t seed);

/// The random points of a volume: as for the box, on the geometry's corners, curves, surfaces and inside.
std::vector<Vec3> randomNodes(const VolumeGeometry& geometry, const ClosedSurface& surface, double spacing, double minGap,
                              std::uint64_t seed);

/// Sets sp.rods to the edges of the tetrahedra (of sp.nodes) whose centroid and six edge midpoints lie in
/// `surface` or within `margin` [m] of it (a non-convex volume gets no rod across a notch or a re-entrant
/// corner), drops the nodes of no kept tetrahedron (renumbering the others in order), and sets
/// sp.solidVolume. randomSpecimen uses margin = 0.05 × rod length (README).
void keepInside(Specimen& sp, const std::vector<Tetrahedron>& tets, const ClosedSurface& surface, double margin);

/// The Delaunay tetrahedralisation of `nodes`, computed by gmsh (gmsh::model::mesh::tetrahedralize):
/// 0-based node indices.
std::vector<Tetrahedron> delaunayTetrahedra(const std::vector<Vec3>& nodes);
/// The unique edges of tetrahedra; sorted, each rod {a, b} with a < b.
std::vector<Rod> tetrahedronEdges(const std::vector<Tetrahedron>& tets);
/// The unique edges of the Delaunay tetrahedralisation of `nodes` (the two above).
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
/// first at random positions fully inside the box without overlap (random sequential addition). With
/// `solid`, V is its volume and a sphere must also lie fully inside it (centre inside, no surface
/// triangle within its radius). Throws PackingError naming the aggregate that found no place.
std::vector<Aggregate> placeAggregates(const Box& box, const SieveCurve& sieve, const AggregateSettings& s,
                                       const ClosedSurface* solid = nullptr);

/// Sets specimen.phases from the aggregates: which aggregate (if any) holds each end of a rod.
void classifyRods(Specimen& specimen);

}  // namespace lattice
