#pragma once
// The lattice rod law (CONTRIBUTING.md, "Adding one unit of physics"): how one rod resists the relative motion
// of its two end nodes. A law is chosen by the scene key `rod.law` with the law's file name; adding
// one = a file pair in src/rod_laws/, its contract test (tests/unit/lattice), one line in rod_law.cpp.
//
// Every node carries 6 dofs: translation u [m] and a small rotation θ [rad]; a rod's dofs are ordered
// [u_a, θ_a, u_b, θ_b] in global axes. Linear (small displacement) kinematics: the stiffness is computed
// once per rod and assembled; laws are called per rod at assembly and on removal, never in a solver
// loop. Dofs a law gives no stiffness (a truss has none for rotations) are dropped by the model.

#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace lattice {

using Mat12 = Eigen::Matrix<double, 12, 12>;

/// The relative stiffnesses of a phase (the LGM's k_l, k_b, k_t; dimensionless, matrix k_l = 1).
struct RelativeStiffness {
  double kl = 1.0;  ///< longitudinal
  double kb = 0.6;  ///< bending
  double kt = 0.6;  ///< torsional
};

/// The section every rod shares: E₀ [Pa] scales the relative stiffnesses, A [m²] is the rod area.
struct RodSection {
  double youngModulus = 0.0;
  double area = 0.0;
};

/// The springs joining a rod's two rigid halves at its midpoint c, in the rod frame (e₁ along the rod):
/// with Δ = u_b − u_a − (L/2)(θ_a + θ_b) × e₁ and Φ = θ_b − θ_a,
///   W = ½ [normal (Δ·e₁)² + shear |Δ − (Δ·e₁)e₁|² + torsion (Φ·e₁)² + bending |Φ − (Φ·e₁)e₁|²].
/// Every law is one such set (README "Rod law"); the two shear springs are equal and so are the two
/// bending springs, so the stiffness does not depend on how e₂, e₃ are chosen.
struct RodSprings {
  double normal = 0.0;   ///< [N/m]
  double shear = 0.0;    ///< [N/m]
  double torsion = 0.0;  ///< [N·m/rad]
  double bending = 0.0;  ///< [N·m/rad]
};

class RodLaw {
 public:
  virtual ~RodLaw() = default;
  /// The registered name, equal to the file name (`beam`).
  virtual std::string name() const = 0;
  /// The springs of a rod of reference length `length` [m].
  virtual RodSprings springs(double length, const RelativeStiffness& k, const RodSection& section) const = 0;
  /// The symmetric positive semi-definite 12×12 stiffness [N/m, N, N·m] of a rod of reference length
  /// `length` along the unit vector `axis` (from node a to node b): K = Bᵀ diag(springs) B. Rigid-body
  /// motions of the rod give zero force.
  Mat12 stiffness(const Eigen::Vector3d& axis, double length, const RelativeStiffness& k, const RodSection& section) const;
};

/// K = Bᵀ D B of one rod from its springs (the kinematics shared by every law).
Mat12 rodStiffness(const Eigen::Vector3d& axis, double length, const RodSprings& springs);

/// A new law by registered name; std::invalid_argument for unknown names.
std::unique_ptr<RodLaw> makeRodLaw(const std::string& name);
/// The registered names, for scene validation and contract tests.
const std::vector<std::string>& rodLawNames();

}  // namespace lattice
