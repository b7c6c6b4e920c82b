#pragma once
// Mappings between two interface meshes. A mapping is built once for a pair of meshes
// "from" → "to" and is a sparse matrix M (n_to × n_from) with rows that sum to one:
//   consistent   (displacements, velocities):  v_to   = M v_from     — interpolation, exact for fields
//                                                                       the method reproduces
//   conservative (forces, reverse direction):  f_from = Mᵀ f_to       — the transpose, so Σ f is kept,
//                                                                       and Σ x × f too when the "to"
//                                                                       nodes lie on the "from" surface
// Each method is one source file behind this interface, chosen by name: identity, nearest_neighbor,
// nearest_projection, barycentric. Fields are flat arrays of `components` values per node.

#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <Eigen/SparseCore>

namespace cosim {

using Vec3 = Eigen::Vector3d;

struct InterfaceMesh {
  std::vector<Vec3> nodes;
  std::vector<std::array<std::uint32_t, 3>> triangles;  ///< may be empty (a point cloud)
  /// Cells of a volume or a line (a bridging domain's overlap): 0-based node indices, may be empty.
  std::vector<std::array<std::uint32_t, 4>> tetrahedra;
  std::vector<std::array<std::uint32_t, 2>> segments;
};

class Mapping {
 public:
  virtual ~Mapping() = default;
  virtual std::string name() const = 0;
  /// v_to = M v_from.
  void consistent(std::span<const double> from, std::span<double> to, int components) const;
  /// f_from = Mᵀ f_to.
  void conservative(std::span<const double> to, std::span<double> from, int components) const;
  std::size_t fromSize() const { return static_cast<std::size_t>(matrix_.cols()); }
  std::size_t toSize() const { return static_cast<std::size_t>(matrix_.rows()); }
  const Eigen::SparseMatrix<double, Eigen::RowMajor>& matrix() const { return matrix_; }
  /// The mapping copies values (identity or a selection of nodes), no weights.
  bool copies() const { return identity_ || !select_.empty(); }

 protected:
  /// Called by a method once matrix_ is built: when every row holds a single 1 (the "to" nodes are
  /// "from" nodes, e.g. a DEM wall and the FEM interface meshed alike, in any order), the mapping
  /// copies values instead of multiplying.
  void copyIfSelection();
  /// matrix_ (n_to × n_from) from the method's weights, then copyIfSelection().
  void setMatrix(const std::vector<Eigen::Triplet<double>>& weights, std::size_t to, std::size_t from);
  Eigen::SparseMatrix<double, Eigen::RowMajor> matrix_;
  bool identity_ = false;              ///< identical meshes: copies, no multiply
  std::vector<std::uint32_t> select_;  ///< row i of M is the unit row of "from" node select_[i]
};

/// Builds the mapping called `name` from `from` to `to`. Throws std::invalid_argument for unknown names
/// or incompatible meshes (identity with different node counts or positions).
std::unique_ptr<Mapping> makeMapping(const std::string& name, const InterfaceMesh& from, const InterfaceMesh& to);
std::vector<std::string> mappingNames();

/// The spin ½ ∇ × v of the linear field on `from`'s tetrahedra at each `to` node: the 3 n_to × 3 n_from
/// matrix that takes the nodes' velocities (node-major x, y, z) to the rotation rate of the continuum
/// where each `to` node lies (in the tetrahedron the barycentric mapping uses). A rigid rotation
/// v = ω × x gives ω. Throws std::invalid_argument if `from` has cells other than tetrahedra or a `to`
/// node lies in none.
Eigen::SparseMatrix<double> spinMatrix(const InterfaceMesh& from, const InterfaceMesh& to);

}  // namespace cosim
