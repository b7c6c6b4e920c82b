#pragma once
// The plane walls of dem::Simulation (dem/model.hpp PlaneWall) and their contacts with the spheres:
// the walls, their candidates with the contact histories, and the force each wall took in the last step.
//
// Call order per step: rebuildCandidates() when the neighbour list asks for it (the spheres' centres
// current), computeContacts() in the force pass after the sphere pairs, applyRollingResistance() after
// every contact's force (with rolling resistance), move() after the bodies moved. Not thread safe; the
// candidate build and the force pass use OpenMP inside. Units SI.
#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include "body_stiffness.hpp"
#include "common/heap_bytes.hpp"
#include "common/state_archive.hpp"
#include "contact_set.hpp"
#include "dem/model.hpp"
#include "dem/walls.hpp"
#include "step_context.hpp"
#include "transient.hpp"

namespace dem {

class PlaneWalls : public PlaneWallSet {
 public:
  /// No candidates and no forces: the spheres were replaced.
  void clearContacts() {
    contacts_ = ContactSet{};
    forces_.assign(walls_.size(), Vec3::Zero());
  }
  /// The sphere–plane candidates (a: sphere, b: wall), sorted by (law, sphere, wall); `point` holds each
  /// one's R* = r, m* = the body's mass and its overlap at the last force pass.
  const ContactSet& contacts() const { return contacts_; }
  /// The same, to set their histories (a run on several ranks moves them between ranks).
  ContactSet& contacts() { return contacts_; }

  /// Candidates: every sphere whose centre is within r + skin in front of a wall it has a law with; the
  /// histories of candidates that stay are kept.
  void rebuildCandidates(const StepContext& ctx);
  /// Overlaps, the laws and the sums: each touching candidate's force and torque added to its sphere,
  /// the reaction to its wall (forces()).
  void computeContacts(const StepContext& ctx);
  /// The rolling-resistance couple of each touching candidate whose law has one, added to its sphere.
  void applyRollingResistance(const StepContext& ctx);
  /// Adds each touching contact's normal stiffness and damping to its bodies (the stable-step estimate).
  void addStiffness(const std::vector<std::unique_ptr<ContactLaw>>& laws, const Spheres& spheres,
                    BodyStiffness& out) const;
  /// Per wall, the summed normal stiffness dF_n/dδ of its touching candidates at the last pass [N/m].
  std::vector<double> contactStiffness(const std::vector<std::unique_ptr<ContactLaw>>& laws) const;
  /// The touching candidates' elastic, damping and friction energies of the last pass [J], if it summed
  /// them (energySummed(): without rolling resistance); else they are in contacts().force.
  const std::array<double, 3>& energy() const { return energy_; }
  bool energySummed() const { return energySummed_; }
  /// Moves the walls by their velocities over dt, adding their work on the spheres in the last step to
  /// `wallWork` [J].
  void move(double dt, double& wallWork);

  void archive(common::StateArchive& a) { a.io("walls", walls_), a.io("forces", forces_), a.io("contacts", contacts_); }
  std::size_t heapBytes() const {
    return common::heapBytes(walls_, forces_, contacts_, work_->lists, work_->blocks);
  }

 private:
  struct Work {
    CandidateLists lists;
    std::vector<std::unique_ptr<detail::ContactBlock>> blocks;  // computeContacts' lanes per thread (10 kB)
  };
  ContactSet contacts_;
  // Not archived: every reader (the ledger's sums in initialize() and prepareStep()) follows a pass.
  std::array<double, 3> energy_{};
  bool energySummed_ = false;
  detail::Transient<Work> work_;
};

}  // namespace dem
