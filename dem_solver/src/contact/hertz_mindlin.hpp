#pragma once
#include "batch_law.hpp"

namespace dem {

/// Hertz–Mindlin with damping and Coulomb friction (Johnson 1985; Mindlin & Deresiewicz 1953; damping
/// form of Tsuji et al. 1992 with the coefficient solved for the requested restitution):
///   F_n = (4/3) E* √R* δ^{3/2} − γ_n v_n ≥ 0,  γ_n = c √(S_n m*),  S_n = 2E* a,  a = √(R* δ)
///   tangential stiffness S_t = 8 G* a, dashpot c √(S_t m*), cap μ F_n, stored force scaled by a/a_old
///   when unloading.
/// E*, G* combine the two materials. Scene keys: restitution, friction.
class HertzMindlin final : public detail::BatchLaw<HertzMindlin> {
 public:
  HertzMindlin(const Material& a, const Material& b, const InteractionParams& params);
  std::string name() const override { return "hertz_mindlin"; }
  /// A block of touching contacts (friction > 0 or not); called by the batch loop.
  template <bool kFriction>
  void blockLoop(detail::ContactBlock& b, double dt) const;
  ImpactPrediction elasticImpact(double effRadius, double effMass, double speed) const override;
  double criticalTimeStep(const Material& material, double radius, double mass) const override;
  NormalTangent normalTangent(double effRadius, double effMass, double overlap) const override;
  double restitution() const override { return params_.restitution; }
  double friction() const override { return params_.friction; }
  double rollingFriction() const override { return params_.rollingFriction; }

  double effectiveYoung() const { return eStar_; }
  double effectiveShear() const { return gStar_; }

 private:
  double eStar_;  ///< E* = [(1−ν_a²)/E_a + (1−ν_b²)/E_b]⁻¹ [Pa]
  double gStar_;  ///< G* = [(2−ν_a)/G_a + (2−ν_b)/G_b]⁻¹ [Pa]
  double c_;      ///< scaled damping c [-], dem/restitution.hpp
  double shearToNormal_;  ///< √(S_t / S_n) = √(4G*/E*): the tangential dashpot from the normal one
  InteractionParams params_;
};

}  // namespace dem
