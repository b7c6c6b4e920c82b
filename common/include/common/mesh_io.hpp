#pragma once
// Triangle surface meshes read through the gmsh API (any format gmsh opens: .msh, .stl, …). No
// hand-written mesh parser. gmsh is initialised once per process, quietly, on first use.

#include <array>
#include <cstdint>
#include <filesystem>
#include <mutex>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace common {

/// Holds the process-wide gmsh lock (gmsh keeps one global model) for its lifetime, and initialises
/// gmsh quietly (no terminal output, errors thrown) on first use. Every gmsh API call goes under one.
/// gmsh sets OpenMP's thread count to its own option (1) when it initialises: the session restores the
/// caller's count when it ends.
class GmshSession {
 public:
  GmshSession();
  ~GmshSession();
  GmshSession(const GmshSession&) = delete;
  GmshSession& operator=(const GmshSession&) = delete;

 private:
  std::unique_lock<std::mutex> lock_;
  int threads_;
};

struct TriangleMesh {
  std::vector<Eigen::Vector3d> nodes;
  std::vector<std::array<std::uint32_t, 3>> triangles;  ///< 0-based node indices
};

/// Refuses (SimulationError) a gmsh file whose $Nodes or $Elements header claims more entries than the
/// file's size can hold, a largest tag far beyond the count, or more than the machine's memory, before
/// gmsh allocates for it. openGmshFile calls it.
void checkGmshHeader(const std::filesystem::path& file);

/// gmsh::open of `file` after checkGmshHeader: the one way the project opens a gmsh file, inside a
/// GmshSession. Throws what either throws.
void openGmshFile(const std::filesystem::path& file);

/// Reads the 3-node triangles of `file` (all of them, or those of the 2-D physical group `physical`)
/// and their nodes, renumbered densely. Throws common::SimulationError naming the file when gmsh fails
/// and ConfigError-free: callers add the scene location (the file name is in the message).
TriangleMesh readTriangleMesh(const std::filesystem::path& file, const std::string& physical = "");

/// Coordinates of the given node tags of the current gmsh model, in that order (gmsh must be initialised
/// and the model meshed or loaded).
std::vector<Eigen::Vector3d> gmshNodeCoordinates(const std::vector<std::size_t>& tags);

/// Writes `mesh` as an ASCII STL (tests and tools).
void writeStl(const std::filesystem::path& file, const TriangleMesh& mesh);

}  // namespace common
