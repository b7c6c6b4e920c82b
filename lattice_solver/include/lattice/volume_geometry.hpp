#pragma once
// A closed volume of a gmsh model (.geo, .step/.brep through OpenCASCADE, or a .msh with its surface
// mesh), read for specimen generation: the triangles of its boundary surfaces and the segments of their
// curves (lattice_solver/README.md, "Specimen from a gmsh volume"). The only gmsh use of this part;
// generation itself works on the plain arrays.

#include <array>
#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <vector>

#include "lattice/closed_surface.hpp"

namespace lattice {

struct VolumeGeometry {
  int volume = 0;                   ///< gmsh tag of the volume
  std::vector<Vec3> vertices;       ///< boundary mesh nodes [m] (scaled)
  struct Surface {
    int tag = 0;
    std::vector<Triangle> triangles;  ///< into vertices
  };
  std::vector<Surface> surfaces;    ///< the volume's boundary surfaces
  std::vector<std::vector<std::array<std::uint32_t, 2>>> curves;  ///< segments of each boundary curve
  std::vector<std::uint32_t> corners;  ///< vertices at the geometry points of the boundary
  /// All boundary triangles as one closed surface (throws std::invalid_argument when it is not closed).
  ClosedSurface closedSurface() const;
};

/// The volume tag asked for is not in the file.
struct VolumeTagError : std::invalid_argument {
  using std::invalid_argument::invalid_argument;
};

/// Opens `file` with gmsh and returns volume `volumeTag` (0: the file's only volume). Files other than
/// .msh are meshed on their surfaces with gmsh (Mesh.MeshSizeMax = meshSize / scale); a .msh must hold
/// its boundary triangles. Coordinates are multiplied by `scale` (the file's length unit in metres).
/// Throws std::invalid_argument with a message for the user (missing file, no volume, unknown tag, no
/// surface triangles; VolumeTagError for an unknown tag) — the scene reader adds the key and line.
VolumeGeometry readVolumeGeometry(const std::filesystem::path& file, int volumeTag, double meshSize, double scale);

}  // namespace lattice
