#pragma once
// The project's calls into the gmsh API (libgmsh), kept out of cosim::common: gmsh loads a few hundred
// shared libraries (OpenCASCADE, FLTK, X11 …), about 45 MB of resident memory before a scene is read. A
// program that meshes (fem_solver, lattice_solver, make_cluster) links cosim::gmsh; dem_solver reads its
// wall meshes through the cosim_mesh_reader module (common/mesh_io.hpp), loaded only when a scene has one.

#include <filesystem>
#include <mutex>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/mesh_io.hpp"

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

/// gmsh::open of `file` after checkGmshHeader: the one way the project opens a gmsh file, inside a
/// GmshSession. Throws what either throws.
void openGmshFile(const std::filesystem::path& file);

/// Coordinates of the given node tags of the current gmsh model, in that order (gmsh must be initialised
/// and the model meshed or loaded).
std::vector<Eigen::Vector3d> gmshNodeCoordinates(const std::vector<std::size_t>& tags);

/// readTriangleMesh's work, through gmsh in this process (the mesh reader module calls it).
TriangleMesh gmshReadTriangleMesh(const std::filesystem::path& file, const std::string& physical);

}  // namespace common
