#pragma once
// The triangle-mesh walls of dem::Simulation (dem/mesh_wall.hpp) and their contacts with the spheres:
// the walls with their nodes and the forces on them, the sphere–triangle candidates (rebuilt with their
// own Verlet skin), the contacts by the face/edge/vertex rule with their histories, and the walls' power.
//
// Call order per step: rebuildCandidates() when the neighbour list asks for it (the spheres' centres
// current), computeContacts() before the force pass, computeForces() in it after the plane walls,
// applyRollingResistance() after every contact's force (with rolling resistance), move() after the
// bodies moved. Not thread safe; the candidate build and computeContacts() use OpenMP inside. Units SI.
#include <array>
#include <cstdint>
#include <tuple>
#include <utility>
#include <vector>

#include "body_stiffness.hpp"
#include "common/heap_bytes.hpp"
#include "common/state_archive.hpp"
#include "dem/mesh_wall.hpp"
#include "dem/model.hpp"
#include "dem/walls.hpp"
#include "step_context.hpp"
#include "transient.hpp"

namespace dem {

struct MeshCandidate {
  std::uint32_t sphere, mesh, triangle;
  bool operator<(const MeshCandidate& o) const {
    return std::tie(sphere, mesh, triangle) < std::tie(o.sphere, o.mesh, o.triangle);
  }
};

struct MeshContact {
  std::uint32_t sphere = 0, mesh = 0, triangle = 0;
  std::uint64_t key = 0;  // the feature: face, edge (two nodes) or vertex, kind in the top bits
  int law = 0;
  std::array<double, 3> bary{};
  Vec3 wallPoint = Vec3::Zero();     // closest point on the mesh [m]
  Vec3 wallVelocity = Vec3::Zero();  // velocity of the mesh there [m/s]
  ContactPoint point;
};

/// The candidates and contacts of the sphere–mesh pairs.
struct MeshContacts {
  std::vector<MeshCandidate> candidates;                     // sorted; rebuilt with the skin
  std::vector<std::pair<std::size_t, std::size_t>> groups;   // runs of one (sphere, mesh)
  std::vector<std::vector<std::uint32_t>> candidateTriangles;  // per mesh: the triangles of some candidate
  // Work space reused every step, not state (thousands of small vectors, copied per coupling iteration
  // otherwise).
  struct Scratch {
    std::vector<std::vector<MeshContact>> perGroup;
    std::vector<std::vector<ContactHistory>> perGroupHistory;  // their hand-over histories
    std::vector<std::vector<Vec3>> faceNormals;                // per mesh: unit normal of each triangle
  };
  detail::Transient<Scratch> scratch;
  std::vector<MeshContact> contacts, previous;
  std::vector<ContactHistory> history, previousHistory;
  std::vector<ContactPoint> points;
  std::vector<ContactForce> forces;
  std::vector<std::pair<std::size_t, std::size_t>> ranges;  // per law
  void archive(common::StateArchive& a) {
    a.io("candidates", candidates), a.io("groups", groups), a.io("candidate_triangles", candidateTriangles);
    a.io("contacts", contacts), a.io("previous", previous), a.io("history", history);
    a.io("previous_history", previousHistory), a.io("points", points), a.io("forces", forces), a.io("ranges", ranges);
  }
  std::size_t heapBytes() const {
    return common::heapBytes(candidates, groups, candidateTriangles, scratch->perGroup, scratch->perGroupHistory,
                             scratch->faceNormals, contacts, previous, history, previousHistory, points, forces,
                             ranges);
  }
};

class MeshWalls : public MeshWallSet {
 public:
  const MeshContacts& contacts() const { return contacts_; }
  /// Adds each touching contact's normal stiffness and damping to its bodies (the stable-step estimate).
  void addStiffness(const std::vector<std::unique_ptr<ContactLaw>>& laws, const Spheres& spheres,
                    BodyStiffness& out) const;
  /// The skin Settings::meshSkin = 0 stands for [m] (dem_solver/README.md).
  double automaticSkin(const Spheres& spheres, double pairSkin) const;

  /// No candidates, contacts nor forces: the spheres were replaced.
  void clearContacts();
  /// The contacts of the last step, ordered by (law, sphere, mesh), whose histories the next step's
  /// contacts take over by feature key and normal: a run on several ranks moves them with their spheres.
  void setLastContacts(std::vector<MeshContact> contacts, std::vector<ContactHistory> history) {
    contacts_.contacts = std::move(contacts), contacts_.history = std::move(history);
  }

  /// Candidates: every (sphere, triangle) within the sphere's reach plus Settings::meshSkin (another
  /// rank's ghost spheres have none: their rank computes their contacts).
  void rebuildCandidates(const StepContext& ctx);
  /// The contacts of the candidates now, with the histories handed over from the last step's.
  void computeContacts(const StepContext& ctx);
  /// The laws' forces, each added to its sphere and split to its triangle's nodes; the walls' power.
  void computeForces(const StepContext& ctx);
  /// The rolling-resistance couple of each contact whose law has one, to its sphere and its wall.
  void applyRollingResistance(const StepContext& ctx);
  /// Moves the prescribed walls by their velocities over dt, adding the walls' work on the spheres in
  /// the last step to `wallWork` [J].
  void move(double dt, double& wallWork);

  void archive(common::StateArchive& a) {
    a.io("walls", walls_), a.io("contacts", contacts_), a.io("power", power_);
  }
  std::size_t heapBytes() const { return common::heapBytes(walls_, contacts_); }

 private:
  void applyForces(const StepContext& ctx);

  MeshContacts contacts_;
  double power_ = 0.0;  // of the walls on the spheres in the last step [W]
};

}  // namespace dem
