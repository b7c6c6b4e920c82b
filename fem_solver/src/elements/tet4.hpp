#pragma once
#include <array>

#include "fem/element.hpp"

namespace fem {

/// Linear tetrahedron, total Lagrangian, St. Venant–Kirchhoff (fem_solver/README.md §Solid):
/// H = Σ u_i ⊗ ∇N_i, F = I + H, E = ½(H + Hᵀ + HᵀH), S = λ tr(E) I + 2μ E, f_i = V₀ F S ∇N_i,
/// K_ij = V₀ [B_iᵀ D B_j + (∇N_iᵀ S ∇N_j) I₃].
class Tet4 final : public Element {
 public:
  struct Params {
    double young, poisson, density;
  };
  Tet4(std::vector<std::uint32_t> connectivity, const std::vector<Vec3>& reference, const Params& p);

  std::string name() const override { return "tet4"; }
  int nodesPerElement() const override { return 4; }
  common::CellType cellType() const override { return common::CellType::kTetrahedron; }
  const std::vector<std::uint32_t>& connectivity() const override { return conn_; }
  double internalForces(std::span<const double> u, std::span<double> slots) const override;
  void tangent(std::span<const double> u, std::vector<Triplet>& triplets) const override;
  void addLumpedMass(std::span<double> nodeMass) const override;
  double criticalTimeStep() const override { return criticalDt_; }
  Current current(std::span<const double> u) const override;
  int stressComponents() const override { return 6; }
  void stress(std::span<const double> u, std::span<double> out) const override;

 private:
  using Voigt = Eigen::Matrix<double, 6, 1>;
  Eigen::Matrix3d displacementGradient(std::span<const double> u, std::size_t e) const;
  Voigt pk2(const Eigen::Matrix3d& H) const;  ///< (S11, S22, S33, S12, S23, S13)
  Eigen::Matrix<double, 12, 12> stiffness(const Eigen::Matrix3d& H, std::size_t e) const;

  std::vector<std::uint32_t> conn_;
  std::vector<std::array<Vec3, 4>> grad_;  ///< ∇N_i [1/m]
  std::vector<double> volume_;             ///< V₀ [m³]
  Params p_;
  double lambda_, mu_;  ///< Lamé constants [Pa]
  Eigen::Matrix<double, 6, 6> D_;
  double criticalDt_ = 0.0;
  std::vector<double> elementDt_;  // per element: the exact reference bound [s]
};

}  // namespace fem
