#pragma once
#include "batch_law.hpp"

namespace dem {

/// The cohesive-frictional law of Kozicki & Donzé 2008 (§2.1, eqs. (1)–(3);
/// dem_solver/README.md §Cohesive-frictional): linear springs whose stiffnesses follow from both
/// bodies' moduli and radii, k_n = 2 R* E_h with E_h = 2 E_a E_b / (E_a + E_b) (for two spheres of one
/// modulus E: k_n = 2 E r_a r_b / (r_a + r_b), as YADE's Ip2_FrictMat_FrictMat_FrictPhys), k_s = α k_n;
/// Coulomb friction μ. Pairs closer than `interaction_radius` × (r_a + r_b) at the start are bonded: a
/// bond carries tension up to σ_t A and shear up to c A + μ F_n (A = π min(r_a, r_b)²), then breaks and
/// the pair is an ordinary frictional contact from then on.
///
/// Scene keys (an `interactions` entry): shear_stiffness_ratio α (default 0.25), tensile_strength σ_t
/// [Pa], cohesion c [Pa] (both default 0: no bonds), interaction_radius (≥ 1, default 1), restitution,
/// friction.
class CohesiveFrictional final : public detail::BatchLaw<CohesiveFrictional>, public BondingLaw {
 public:
  struct Strength {
    double tensile = 0.0;   ///< σ_t [Pa]
    double cohesion = 0.0;  ///< c [Pa]
    double interactionRadius = 1.0;  ///< bonds form at the start between centres closer than this × (r_a + r_b)
  };
  CohesiveFrictional(const Material& a, const Material& b, double shearRatio, const Strength& strength,
                     const InteractionParams& params);
  std::string name() const override { return "cohesive_frictional"; }
  template <bool kFriction>
  void blockLoop(detail::ContactBlock& b, double dt) const;
  ImpactPrediction elasticImpact(double effRadius, double effMass, double speed) const override;
  double criticalTimeStep(const Material& material, double radius, double mass) const override;
  NormalTangent normalTangent(double effRadius, double effMass, double overlap) const override;
  double restitution() const override { return params_.restitution; }
  double friction() const override { return params_.friction; }
  double rollingFriction() const override { return params_.rollingFriction; }
  const BondingLaw* bonding() const override {
    return strength_.tensile > 0.0 || strength_.cohesion > 0.0 ? this : nullptr;
  }

  double bondReach(double ra, double rb) const override { return strength_.interactionRadius * (ra + rb); }
  Bond makeBond(double ra, double rb, double effMass, double overlap) const override;
  BondForce bondForce(Bond& bond, const Vec3& normal, double overlap, const Vec3& relVelocity,
                      double dt) const override;

 private:
  double twoModulus_;  ///< 2 E_h [Pa]: k_n = 2 E_h R*
  double shearRatio_;  ///< α = k_s / k_n [-]
  double c_;           ///< scaled damping c [-], dem/restitution.hpp
  Strength strength_;
  InteractionParams params_;
};

}  // namespace dem
