#pragma once
// Internal state of the sphere–mesh contacts of dem::Simulation (src/mesh_contacts.cpp).
#include <cstdint>
#include <tuple>
#include <utility>
#include <vector>

#include "dem/simulation.hpp"

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

struct Simulation::MeshContacts {
  std::vector<MeshCandidate> candidates;                     // sorted; rebuilt with the skin
  std::vector<std::pair<std::size_t, std::size_t>> groups;   // runs of one (sphere, mesh)
  std::vector<std::vector<std::uint32_t>> candidateTriangles;  // per mesh: the triangles of some candidate
  // Work space reused every step. Not part of the state: a checkpoint neither copies nor restores it
  // (thousands of small vectors, copied per coupling iteration otherwise).
  struct Scratch {
    Scratch() = default;
    Scratch(const Scratch&) {}
    Scratch& operator=(const Scratch&) { return *this; }
    std::vector<std::vector<MeshContact>> perGroup;
    std::vector<std::vector<ContactHistory>> perGroupHistory;  // their hand-over histories
    std::vector<std::vector<Vec3>> faceNormals;                // per mesh: unit normal of each triangle
  } scratch;
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
};

}  // namespace dem
