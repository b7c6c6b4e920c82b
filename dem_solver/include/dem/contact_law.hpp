#pragma once
// The contact law interface (CONTRIBUTING.md, "Adding one unit of physics"). A law turns the geometry of a
// batch of contacts into forces. The solver calls compute() once per batch of contacts that share one
// interaction (material pair), so there is no virtual call per contact; the loop is inside the law.
//
// Sign conventions: a contact is between side a (always a sphere) and side b (a sphere or a wall
// element). normal points from b to a; relVelocity is the velocity of a's material point minus b's at
// the contact point; force is the force on a (b receives −force). All SI units.
//
// Thread safety: compute() is called from one thread and may use OpenMP inside; a law object holds only
// constant parameters after construction.

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "dem/bonds.hpp"
#include "dem/material.hpp"

namespace common {
class Config;
}

namespace dem {

using Vec3 = Eigen::Vector3d;

/// Loops shorter than this run on one thread: a parallel region costs more than it saves, and idle
/// OpenMP threads spinning would slow down other processes on a small machine.
inline constexpr std::ptrdiff_t kParallelMin = 256;

/// Geometry and kinematics of one contact candidate, filled by the solver's geometry pass.
struct ContactPoint {
  Vec3 normal = Vec3::UnitZ();      ///< unit normal from b to a [-]
  Vec3 point = Vec3::Zero();        ///< contact point, middle of the overlap [m]
  Vec3 relVelocity = Vec3::Zero();  ///< v_a − v_b at the contact point [m/s]
  double overlap = 0.0;             ///< δ, > 0 when in contact [m]
  double effRadius = 0.0;           ///< R* = R_a R_b / (R_a + R_b); R for a wall [m]
  double effMass = 0.0;             ///< m* = m_a m_b / (m_a + m_b); m_a for a wall [kg]
};

/// State carried by a contact from step to step. Reset when the contact opens.
struct ContactHistory {
  Vec3 shearForce = Vec3::Zero();  ///< elastic tangential force on a [N] (incremental, force-based)
  double lastOverlap = 0.0;        ///< δ at the previous step [m]; 0: contact was open (the law derives
                                   ///< its last tangential stiffness from it)
};

/// What a law returns for one contact.
struct ContactForce {
  Vec3 force = Vec3::Zero();    ///< total force on a [N]
  double normalForce = 0.0;     ///< F_n ≥ 0 [N]
  double elasticEnergy = 0.0;   ///< normal + tangential spring energy stored now [J]
  double dampingEnergy = 0.0;   ///< energy dissipated by the dashpots during this step [J]
  double frictionEnergy = 0.0;  ///< energy dissipated by Coulomb sliding during this step [J]
};

/// Sphere–sphere candidates and the state their geometry is computed from, for the fused pass
/// ContactLaw::computeSpherePairs. Arrays are indexed by candidate (a, b, effRadius, effMass, overlap,
/// point, history, force), sphere (position, radius, body, sphereForce, sphereTorque) or body
/// (bodyPosition, velocity, angularVelocity).
struct SpherePairView {
  const std::uint32_t* a = nullptr;
  const std::uint32_t* b = nullptr;
  const double* effRadius = nullptr;  ///< R* per candidate
  const double* effMass = nullptr;    ///< m* per candidate
  /// Per candidate (output): δ > 0 if touching; −d² ≤ 0 if open, d the centres' distance (the signed
  /// overlap r_a + r_b − d of an open candidate is rarely read and costs a square root). Input: the
  /// last pass's, > 0 exactly when the history holds a contact (its lastOverlap ≠ 0).
  double* overlap = nullptr;
  /// Contact points (output): written only if `keepGeometry` — they are four times the size of the
  /// rest, and a sample of 50,000 spheres has 175,000 candidates.
  ContactPoint* point = nullptr;
  bool keepGeometry = true;
  ContactHistory* history = nullptr;
  /// Null (only with `energy`): forces are not stored, only added to the spheres.
  ContactForce* force = nullptr;
  const Vec3* position = nullptr;
  const double* radius = nullptr;
  const std::uint32_t* body = nullptr;
  const Vec3* bodyPosition = nullptr;
  const Vec3* velocity = nullptr;
  const Vec3* angularVelocity = nullptr;
  /// Every sphere is its own body, at its centre (a granular sample): body and bodyPosition are not read;
  /// velocity and angularVelocity are indexed by sphere.
  bool loneSpheres = false;
  /// Per-sphere sums to add each touching contact's force (and, if not null, torque) to, in candidate
  /// order on one thread (several threads: see BatchLaw::spherePairs).
  Vec3* sphereForce = nullptr;
  Vec3* sphereTorque = nullptr;
  /// Running sums (elastic, damping, friction) to add the touching contacts' energies to, in candidate
  /// order on one thread; `force`, if not null, then gets only force and normalForce. Null: the energies
  /// are stored in `force` (and summed by the caller).
  double* energy = nullptr;
  /// Lone spheres too many for the per-core cache: the pass prefetches side b's velocities and sums,
  /// and its centres ahead (at N = 10⁴ the prefetches only cost, at 5·10⁴ they gain; docs/performance.md).
  bool prefetch = false;
  /// If not null, thread t of the pass stores its wall-clock seconds in it at [t] (omp_get_max_threads()
  /// entries; a pass on one thread stores only [0]).
  double* threadSeconds = nullptr;
};

/// Closed-form prediction of a head-on impact (no gravity) for validation and time-step checks.
struct ImpactPrediction {
  double contactDuration;  ///< [s]
  double maxOverlap;       ///< [m]
};

namespace detail {
struct ContactBlock;
}

class ContactLaw {
 public:
  virtual ~ContactLaw() = default;
  /// The registered name, equal to the file name (`hertz_mindlin`).
  virtual std::string name() const = 0;
  /// Forces for every contact of the batch. Entries with overlap ≤ 0 get zero force and a reset history.
  virtual void compute(std::span<const ContactPoint> points, std::span<ContactHistory> history,
                       std::span<ContactForce> out, double dt) const = 0;
  /// Geometry, force and (optionally) the scatter to the spheres of the sphere–sphere candidates
  /// [begin, end) of `v` in one pass: the same numbers as filling `point` and calling compute(), without
  /// writing the contact points out and reading them back.
  virtual void computeSpherePairs(const SpherePairView& v, std::size_t begin, std::size_t end, double dt) const = 0;
  /// Forces of a block of touching contacts gathered by the caller (src/contact/batch_law.hpp): what
  /// compute() does to each block it gathers.
  virtual void computeBlock(detail::ContactBlock& block, double dt) const = 0;
  /// The elastic, undamped head-on impact of effective radius R*, mass m* at `speed`.
  virtual ImpactPrediction elasticImpact(double effRadius, double effMass, double speed) const = 0;
  /// The largest stable explicit time step for a sphere of `material`, `radius`, effective mass `mass`
  /// in this interaction [s].
  virtual double criticalTimeStep(const Material& material, double radius, double mass) const = 0;
  /// The normal tangent stiffness dF_n/dδ [N/m], dashpot coefficient γ_n [N s/m] and elastic normal
  /// force [N] of one contact at overlap δ > 0 (the stable step of a contact network follows the first
  /// two; the contact network output shows the force).
  struct NormalTangent {
    double stiffness = 0.0, damping = 0.0, force = 0.0;
  };
  virtual NormalTangent normalTangent(double effRadius, double effMass, double overlap) const = 0;
  /// The coefficient of restitution the damping was built for (1: no damping).
  virtual double restitution() const = 0;
  /// Coulomb friction coefficient μ (0: no tangential force, no history).
  virtual double friction() const = 0;
  /// Rolling friction coefficient μ_r (0: no rolling resistance).
  virtual double rollingFriction() const = 0;
  /// The law's bonds (dem/bonds.hpp), if it bonds spheres at the start; null for a purely contact law.
  virtual const BondingLaw* bonding() const { return nullptr; }
};

/// Parameters shared by every law, read from one `interactions` entry.
struct InteractionParams {
  double restitution = 1.0;  ///< e in (0, 1]
  double friction = 0.0;     ///< μ ≥ 0, Coulomb
  double rollingFriction = 0.0;  ///< μ_r ≥ 0, constant directional torque μ_r R* F_n (dimensionless)
};

/// Changes to a scene's interaction for a preparation phase: a specimen grown with less friction
/// (denser) and before its bonds form.
struct LawOverride {
  std::optional<double> friction;  ///< μ instead of the entry's
  bool bonds = true;               ///< false: the law bonds nothing
};

/// Creates the law registered under `type` for materials a and b; `params` is the scene entry (its
/// law-specific keys are read here, overridden or not). Unknown names: ConfigError with a suggestion.
std::unique_ptr<ContactLaw> makeContactLaw(const std::string& type, const common::Config& params,
                                           const Material& a, const Material& b, const LawOverride& change = {});
/// The registered law names.
std::vector<std::string> contactLawNames();

}  // namespace dem
