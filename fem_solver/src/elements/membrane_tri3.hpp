#pragma once
#include <array>

#include "fem/element.hpp"

namespace fem {

/// Membrane triangle, 3 nodes, total Lagrangian, St. Venant–Kirchhoff, isotropic in-plane prestress
/// (fem_solver/README.md §Membrane). Per element: F = Σ x_i ⊗ ∇N_i (3×2, ∇N in a reference in-plane
/// frame), E = ½(FᵀF − I), S = D E + σ₀ I (plane stress), f_i = t A₀ F S ∇N_i,
/// K_ij = t A₀ [B_iᵀ D B_j + (∇N_iᵀ S ∇N_j) I₃].
class MembraneTri3 final : public Element, public Prestressed {
 public:
  struct Params {
    double young;      ///< E [Pa]
    double poisson;    ///< ν [-]
    double density;    ///< ρ [kg/m³]
    double thickness;  ///< t [m]
    double prestress;  ///< σ₀, isotropic PK2 prestress [Pa]
  };
  MembraneTri3(std::vector<std::uint32_t> connectivity, const std::vector<Vec3>& reference, const Params& p);

  std::string name() const override { return "membrane_tri3"; }
  int nodesPerElement() const override { return 3; }
  common::CellType cellType() const override { return common::CellType::kTriangle; }
  const std::vector<std::uint32_t>& connectivity() const override { return conn_; }
  double internalForces(std::span<const double> u, std::span<double> slots) const override;
  void tangent(std::span<const double> u, std::vector<Triplet>& triplets) const override;
  void addLumpedMass(std::span<double> nodeMass) const override;
  double criticalTimeStep() const override;
  Current current(std::span<const double> u) const override;
  int stressComponents() const override { return 3; }
  void stress(std::span<const double> u, std::span<double> out) const override;
  void addPressure(double q, const Vec3& direction, std::span<double> force) const override;

  /// Changes σ₀ (static solver continuation from a larger artificial prestress).
  Prestressed* prestressed() override { return this; }
  void setPrestress(double s) override { p_.prestress = s; }
  double prestress() const override { return p_.prestress; }

 private:
  struct Ref {
    std::array<Eigen::Vector2d, 3> grad;  ///< ∇N_i in the reference in-plane frame [1/m]
    Eigen::Matrix<double, 3, 2> frame;    ///< F₀ = [e₁ e₂], the reference in-plane basis
    double area;                          ///< A₀ [m²]
    double minAltitude;                   ///< 2A₀ / longest edge [m]
  };
  /// Displacement gradient H = Σ u_i ⊗ ∇N_i; F = F₀ + H.
  Eigen::Matrix<double, 3, 2> displacementGradient(std::span<const double> u, std::size_t e) const;
  /// Green–Lagrange strain (Voigt, engineering shear) from F₀ᵀH + HᵀF₀ + HᵀH, without cancellation.
  Eigen::Vector3d strain(const Eigen::Matrix<double, 3, 2>& H, const Eigen::Matrix<double, 3, 2>& F0) const;

  std::vector<std::uint32_t> conn_;
  std::vector<Ref> ref_;
  Params p_;
  Eigen::Matrix3d D_;  ///< plane-stress elasticity, Voigt (E11, E22, 2E12) [Pa]
};

}  // namespace fem
