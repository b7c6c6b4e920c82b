#pragma once
// Triangle surface meshes read through the gmsh API (any format gmsh opens: .msh, .stl, …). No
// hand-written mesh parser. gmsh itself is loaded on the first read, from the cosim_mesh_reader module
// beside the executable (common/gmsh_session.hpp says why): a program that never reads a mesh never
// maps it.

#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace common {

struct TriangleMesh {
  std::vector<Eigen::Vector3d> nodes;
  std::vector<std::array<std::uint32_t, 3>> triangles;  ///< 0-based node indices
};

/// Refuses (SimulationError) a gmsh file whose $Nodes or $Elements header claims more entries than the
/// file's size can hold, a largest tag far beyond the count, or more than the machine's memory, before
/// gmsh allocates for it. openGmshFile calls it.
void checkGmshHeader(const std::filesystem::path& file);

/// Reads the 3-node triangles of `file` (all of them, or those of the 2-D physical group `physical`)
/// and their nodes, renumbered densely. Throws common::SimulationError naming the file when gmsh fails,
/// or when the mesh reader module cannot be loaded; callers add the scene location (the file name is in
/// the message).
TriangleMesh readTriangleMesh(const std::filesystem::path& file, const std::string& physical = "");

/// Writes `mesh` as an ASCII STL (tests and tools).
void writeStl(const std::filesystem::path& file, const TriangleMesh& mesh);

}  // namespace common
