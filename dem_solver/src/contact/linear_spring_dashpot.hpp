#pragma once
#include "batch_law.hpp"

namespace dem {

/// Linear spring-dashpot with Coulomb friction (Cundall & Strack 1979): F_n = k_n δ − c_n v_n ≥ 0,
/// c_n = c √(m* k_n) with c from the requested restitution (dem/restitution.hpp); tangential spring k_t,
/// dashpot c √(m* k_t), cap μ F_n. Scene keys: stiffness_normal [N/m], stiffness_tangential [N/m]
/// (default 2/7 k_n), restitution, friction.
class LinearSpringDashpot final : public detail::BatchLaw<LinearSpringDashpot> {
 public:
  LinearSpringDashpot(double kn, double kt, const InteractionParams& params);
  std::string name() const override { return "linear_spring_dashpot"; }
  /// A block of touching contacts (friction > 0 or not); called by the batch loop.
  template <bool kFriction>
  void blockLoop(detail::ContactBlock& b, double dt) const;
  ImpactPrediction elasticImpact(double effRadius, double effMass, double speed) const override;
  double criticalTimeStep(const Material& material, double radius, double mass) const override;
  NormalTangent normalTangent(double effRadius, double effMass, double overlap) const override;
  double restitution() const override { return params_.restitution; }
  double friction() const override { return params_.friction; }
  double rollingFriction() const override { return params_.rollingFriction; }

 private:
  double kn_;  ///< k_n [N/m]
  double kt_;  ///< k_t [N/m]
  double c_;   ///< scaled damping c [-], dem/restitution.hpp
  InteractionParams params_;
};

}  // namespace dem
