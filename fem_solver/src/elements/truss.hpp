#pragma once
#include "fem/element.hpp"

namespace fem {

/// Truss / cable, 2 nodes, total Lagrangian (fem_solver/README.md §Truss): E_GL = (l² − L₀²)/(2L₀²),
/// S = E E_GL + σ₀ (zero when `tensionOnly` and negative: a slack cable), f₂ = −f₁ = (S A / L₀)(x₂ − x₁),
/// K = (A/L₀)[(E/L₀²)(x₂₁ ⊗ x₂₁) + S I] in the pattern [[K, −K], [−K, K]].
class Truss final : public Element {
 public:
  struct Params {
    double young;      ///< E [Pa]
    double density;    ///< ρ [kg/m³]
    double area;       ///< A [m²]
    double prestress;  ///< σ₀, PK2 [Pa]
    bool tensionOnly;  ///< cable: no compression
  };
  Truss(std::vector<std::uint32_t> connectivity, const std::vector<Vec3>& reference, const Params& p);

  std::string name() const override { return "truss"; }
  int nodesPerElement() const override { return 2; }
  common::CellType cellType() const override { return common::CellType::kLine; }
  const std::vector<std::uint32_t>& connectivity() const override { return conn_; }
  double internalForces(std::span<const double> u, std::span<double> slots) const override;
  void tangent(std::span<const double> u, std::vector<Triplet>& triplets) const override;
  void addLumpedMass(std::span<double> nodeMass) const override;
  double criticalTimeStep() const override;
  Current current(std::span<const double> u) const override;
  int stressComponents() const override { return 1; }
  void stress(std::span<const double> u, std::span<double> out) const override;

 private:
  double pk2(double strain) const;
  std::vector<std::uint32_t> conn_;
  /// d = x₂ − x₁ and the strain (|d|² − L₀²)/(2L₀²) = (2 D·Δu + |Δu|²)/(2L₀²), D = X₂ − X₁ (no cancellation).
  std::pair<Vec3, double> kinematics(std::span<const double> u, std::size_t e) const;
  std::vector<double> length_;  ///< L₀ [m]
  std::vector<Vec3> axis_;      ///< X₂ − X₁ [m]
  Params p_;
};

}  // namespace fem
