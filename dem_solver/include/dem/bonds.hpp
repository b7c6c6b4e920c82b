#pragma once
// Cohesive bonds between spheres (dem_solver/README.md §Cohesive bonds). A contact law that bonds
// (ContactLaw::bonding()) says which sphere pairs bond at the start, with what constants, and what force a
// bond exerts and when it breaks; BondSet owns the bonds and their state, computes them each step and
// keeps a bonded pair out of the sphere-pair contacts (as LAMMPS keeps bonded atoms out of its pair
// lists) until the bond breaks: from then on the pair is an ordinary contact of the same law.
//
// Sign conventions as in dem/contact_law.hpp: normal from b to a, forces on a, overlap δ = r_a + r_b − d
// (negative when apart; a bond carries tension there).

#include <cstdint>
#include <functional>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "common/heap_bytes.hpp"
#include "common/state_archive.hpp"

namespace dem {

using Vec3 = Eigen::Vector3d;

/// One bond: its constants, set when it forms, and its state.
struct Bond {
  std::uint32_t a = 0, b = 0;  ///< spheres, a < b
  double kn = 0.0, ks = 0.0;   ///< normal and shear stiffness [N/m]
  double tensile = 0.0;        ///< largest tensile normal force [N]
  double cohesion = 0.0;       ///< shear strength at zero normal force [N]
  double friction = 0.0;       ///< μ in the shear strength C + μ F_n [-]
  double restOverlap = 0.0;    ///< δ₀, where the normal force is zero [m]
  double gammaN = 0.0, gammaT = 0.0;  ///< normal and shear dashpots [N s/m]
  Vec3 shearForce = Vec3::Zero();     ///< elastic shear force on a [N], incremental
};

/// What one bond does in one step.
struct BondForce {
  Vec3 force = Vec3::Zero();  ///< on a [N]; zero if it broke
  double normalForce = 0.0;   ///< elastic normal force k_n (δ − δ₀), > 0 in compression [N]
  double elastic = 0.0;       ///< stored now [J]
  double damping = 0.0;       ///< dissipated by the dashpots in this step [J]
  bool broke = false;
  /// If it broke: the energy it held less what the contact that replaces it holds at once [J].
  double released = 0.0;
};

/// What a contact law that bonds provides.
class BondingLaw {
 public:
  virtual ~BondingLaw() = default;
  /// Spheres of radii r_a, r_b bond at the start if their centres are closer than this [m].
  virtual double bondReach(double ra, double rb) const = 0;
  /// The bond of two spheres at overlap δ (negative: a gap) with effective mass m*.
  virtual Bond makeBond(double ra, double rb, double effMass, double overlap) const = 0;
  /// The bond's force at overlap δ, unit normal n (b → a) and relative velocity v_a − v_b at the contact
  /// point; updates its shear force. A bond that exceeds its strength breaks (`broke`, no force).
  virtual BondForce bondForce(Bond& bond, const Vec3& normal, double overlap, const Vec3& relVelocity,
                              double dt) const = 0;
};

/// The bonds of a simulation: a value (copied into checkpoints), bonds in (a, b) order.
class BondSet {
 public:
  /// Sphere data the set reads. `body[s]`, `bodyPosition`, `velocity`, `angularVelocity` per body.
  struct View {
    const Vec3* centre = nullptr;
    const double* radius = nullptr;
    const std::uint32_t* body = nullptr;
    const Vec3* bodyPosition = nullptr;
    const Vec3* velocity = nullptr;
    const Vec3* angularVelocity = nullptr;
    std::size_t spheres = 0;
  };
  /// The bonding law of spheres s and t (null: they do not bond), and their effective mass.
  using LawOf = std::function<const BondingLaw*(std::uint32_t, std::uint32_t)>;
  using MassOf = std::function<double(std::uint32_t, std::uint32_t)>;
  /// The shear force a new bond between spheres s < t starts with (a contact's, carried over).
  using ShearOf = std::function<Vec3(std::uint32_t, std::uint32_t)>;

  /// Bonds every pair of spheres of different bodies whose law bonds and whose centres are within its
  /// reach (at most `maxReach`). Replaces any bonds there were.
  void create(const View& v, const LawOf& lawOf, const MassOf& massOf, double maxReach, const ShearOf& shearOf = {});
  /// This step's bond forces from the current centres and velocities; bonds that exceed their strength
  /// are removed. Returns how many broke (their pairs must become contact candidates now).
  std::size_t compute(const View& v, double dt);
  /// Adds each bond's force and torque (about the sphere centre) to the per-sphere sums, in bond order.
  void scatter(const View& v, Vec3* force, Vec3* torque) const;

  /// Scales each bond's stiffnesses, dashpots and strengths by `weight(bond)` (a bridging domain's share).
  void weigh(const std::function<double(const Bond&)>& weight);
  bool empty() const { return bonds_.empty(); }
  std::size_t size() const { return bonds_.size(); }
  const std::vector<Bond>& bonds() const { return bonds_; }
  /// Whether spheres i < j are bonded (partners of i are sorted).
  bool bonded(std::uint32_t i, std::uint32_t j) const;
  /// Every sphere that has a bond, to mark (calls mark(s), perhaps twice for one s).
  template <class Mark>
  void forEachBondedSphere(Mark&& mark) const {
    for (const Bond& b : bonds_) mark(b.a), mark(b.b);
  }
  std::int64_t created() const { return created_; }
  /// Whether bonds formed in this run (here, or on another rank that sent some: replace()): compute()
  /// then renews its sums every step, also once every bond here has broken.
  bool formed() const { return created_ > 0 || received_; }
  /// Replaces the bonds by `bonds` between spheres numbered anew, `spheres` of them (a run on several
  /// ranks moves each bond to the rank that computes it), their laws found again by `lawOf`, and
  /// `everBonded` per sphere; `formed`: bonds formed somewhere in the run. created() and broken() stay
  /// this set's counts.
  void replace(std::vector<Bond> bonds, std::vector<std::uint8_t> everBonded, const LawOf& lawOf, bool formed);
  /// Per sphere: 1 if it had a bond when the bonds formed.
  const std::vector<std::uint8_t>& everBonded() const { return everBonded_; }
  std::int64_t broken() const { return broken_; }
  /// Counts carried over by a run on several ranks that takes up another number of ranks' shares: the
  /// sums of those it took up (the run's counts are the ranks' sums).
  void setCounts(std::int64_t created, std::int64_t broken) { created_ = created, broken_ = broken; }
  /// This step's sums over the bonds.
  double elasticEnergy() const { return elastic_; }
  double dampingEnergy() const { return damping_; }
  double releasedEnergy() const { return released_; }
  /// The bonds now: (sphere a, sphere b, normal force, > 0 in compression).
  struct Line {
    std::uint32_t a, b;
    double normalForce;
  };
  std::vector<Line> lines() const;

  /// The bonds' state (their laws are not state: relink() finds them again after a read).
  void archive(common::StateArchive& a);
  void relink(const LawOf& lawOf);
  std::size_t heapBytes() const {
    return common::heapBytes(law_, bonds_, force_, point_, partnerStart_, partner_, everBonded_);
  }

 private:
  void index(std::size_t spheres);  // partnerStart_ / partner_ from bonds_

  std::vector<const BondingLaw*> law_;  // per bond
  std::vector<Bond> bonds_;
  std::vector<BondForce> force_;            // per bond, this step's
  std::vector<Vec3> point_;                 // per bond, this step's contact point
  std::vector<std::uint32_t> partnerStart_, partner_;  // per sphere i: its partners j > i, sorted
  std::vector<std::uint8_t> everBonded_;
  std::int64_t created_ = 0, broken_ = 0;
  bool received_ = false;  // replace() with `formed`
  double elastic_ = 0.0, damping_ = 0.0, released_ = 0.0;
};

/// The pieces bonds hold together, as masses, largest first: `links` join bodies (by number, below
/// `bodies`), `masses` give each bonded body's mass once, in a fixed order (the sums follow it). A body
/// with no mass listed belongs to no piece.
std::vector<double> pieceMasses(std::size_t bodies, const std::vector<std::pair<std::uint64_t, std::uint64_t>>& links,
                                const std::vector<std::pair<std::uint64_t, double>>& masses);

}  // namespace dem
