#pragma once
// FEM meshes from gmsh: a .msh file with physical groups, or a rectangle / line generated through the
// gmsh API from scene keys. No hand-written mesh parser.

#include <array>
#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace fem {

struct Mesh {
  std::vector<Eigen::Vector3d> nodes;
  /// Elements of each physical group, by gmsh dimension: lines (2 nodes), triangles (3), tetrahedra (4).
  struct Group {
    int dim = 0;
    std::vector<std::uint32_t> connectivity;  // dim+1 nodes per element (0-based)
    std::vector<std::uint32_t> nodes;         // sorted unique nodes of the group
  };
  std::map<std::string, Group> groups;

  const Group* group(const std::string& name) const {
    auto it = groups.find(name);
    return it == groups.end() ? nullptr : &it->second;
  }
  std::vector<std::string> groupNames() const;
};

/// Reads every physical group of a gmsh-readable file. Throws common::SimulationError naming the file.
Mesh readMesh(const std::filesystem::path& file);

/// A rectangle [0, lx] × [0, ly] in the plane z = 0 (translated by `origin`), triangles of about
/// `size`, meshed by gmsh (`structured`: a transfinite grid with alternating diagonals). Groups:
/// "surface" (triangles), "boundary" (all edges), "left", "right", "bottom", "top" (edges x=0, x=lx,
/// y=0, y=ly), and "center" (the node nearest the centre) as a 0-D group.
Mesh rectangleMesh(double lx, double ly, double size, bool structured, const Eigen::Vector3d& origin);

/// A box [0, size] (translated by `origin`) of tetrahedra of about `elementSize`. Groups: "volume",
/// faces "xmin", "xmax", "ymin", "ymax", "zmin", "zmax".
Mesh boxMesh(const Eigen::Vector3d& size, double elementSize, const Eigen::Vector3d& origin);

/// A straight line from a to b in n elements. Groups: "line", "start", "end" (end nodes).
Mesh lineMesh(const Eigen::Vector3d& a, const Eigen::Vector3d& b, int n);

}  // namespace fem
