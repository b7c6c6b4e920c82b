#pragma once
// The sphere–sphere contacts of dem::Simulation: the candidates with their histories, R*, m* and
// overlaps, the force pass over them (each law's batch loop, dem/contact_law.hpp SpherePairView), and
// the energies that pass summed.
//
// Call order: assign() with the neighbour list's pairs at each pair rebuild, computeForces() once per
// step, applyRollingResistance() after every contact's force (with rolling resistance). Not thread
// safe; both use OpenMP inside. Units SI.
#include <array>
#include <cstdint>
#include <vector>

#include "body_stiffness.hpp"
#include "common/heap_bytes.hpp"
#include "common/state_archive.hpp"
#include "contact_set.hpp"
#include "dem/model.hpp"
#include "step_context.hpp"
#include "transient.hpp"

namespace dem {

class SpherePairs {
 public:
  /// The candidates (a < b spheres), sorted by (law, a, b). Without rolling resistance `point` and
  /// `force` are empty (nothing reads them after the pass).
  const ContactSet& contacts() const { return contacts_; }
  /// The same, to set their histories (a run on several ranks moves them between ranks).
  ContactSet& contacts() { return contacts_; }

  /// Replaces the candidates by `pairs` (law, a, b) (the neighbour list's; sorted by law here if not
  /// yet), keeping the histories, R* and m* of those that stay.
  void assign(const StepContext& ctx, std::vector<Triple>& pairs);
  /// The force pass: overlaps, the laws, each touching pair's force (and torque) added to its spheres,
  /// and without rolling resistance the pairs' energies summed (energy()). `wait` gets, per law, the
  /// slowest thread's time minus the threads' mean [s].
  void computeForces(const StepContext& ctx, double& wait);
  /// The rolling-resistance couple of each touching pair whose law has one, to both spheres.
  void applyRollingResistance(const StepContext& ctx);
  /// Adds each touching contact's normal stiffness and damping to its bodies (the stable-step estimate).
  void addStiffness(const std::vector<std::unique_ptr<ContactLaw>>& laws, const Spheres& spheres, const Bodies& bodies,
                    BodyStiffness& out) const;
  /// The signed overlap of candidate k at the last force pass [m].
  double overlap(std::size_t k, const Spheres& spheres) const;
  /// The touching pairs' elastic, damping and friction energies of the last pass [J], if it summed them
  /// (energySummed()); else they are in contacts().force.
  const std::array<double, 3>& energy() const { return energy_; }
  bool energySummed() const { return energySummed_; }

  void archive(common::StateArchive& a) {
    a.io("contacts", contacts_), a.io("energy", energy_), a.io("energy_summed", energySummed_);
  }
  /// The candidates and their histories [bytes].
  std::size_t heapBytes() const { return common::heapBytes(contacts_, work_->threadSeconds); }

 private:
  struct Work {
    std::vector<double> threadSeconds;  // per thread, its time in the last pass of a law
  };
  ContactSet contacts_;
  std::array<double, 3> energy_{};
  bool energySummed_ = false;
  detail::Transient<Work> work_;
};

}  // namespace dem
