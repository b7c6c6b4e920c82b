#pragma once
// Triangle-mesh walls: fixed, moving rigidly with a prescribed velocity, or driven from outside (node
// positions and velocities set every step — how a coupled FEM membrane appears to the DEM).
//
// Contact rule (no double counting where triangles share edges or vertices). For one sphere and one
// mesh, every triangle within reach gives its closest point and the feature it lies on (face, edge,
// vertex; common::closestPointOnTriangle). These hits are taken faces first, then edges, then vertices,
// nearer first within a kind; a hit is dropped when
//   - the same feature (the same face, the same two edge nodes, the same node) was already kept, or
//   - its closest point is not in front of the tangent plane of a contact already kept
//     ((p_hit − p_kept)·n_kept ≤ 1e-9 R): it is hidden behind that contact
// (the distance hierarchy of Santasusana et al. 2016, Kratos' Double Hierarchy Method, in its simplest
// form). So a sphere on a flat triangulated floor has exactly one contact with the plane's normal and
// overlap wherever it sits and however deep it presses; a convex ridge gives one contact whose normal
// turns continuously; a concave corner gives one face contact per face. A contact's tangential history
// follows the sphere from feature to feature of the same mesh (it is handed to the new contact whose
// normal is closest to the old one, within 45°).
// The force on the wall acts at the closest point and is split to the triangle's nodes with its
// barycentric weights, so the nodal forces sum to the total force and moment.

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/heap_bytes.hpp"
#include "common/state_archive.hpp"

namespace dem {

using Vec3 = Eigen::Vector3d;

struct MeshWall {
  enum class Motion { kFixed, kPrescribed, kExternal };

  std::string name;
  std::vector<Vec3> nodes;          ///< current node positions [m]
  std::vector<Vec3> nodeVelocity;   ///< [m/s]
  std::vector<std::array<std::uint32_t, 3>> triangles;
  std::uint32_t material = 0;
  Motion motion = Motion::kFixed;
  Vec3 velocity = Vec3::Zero();  ///< kPrescribed: translation velocity [m/s]
  std::vector<Vec3> nodeForce;   ///< force the spheres exert on each node in the last step [N]
  /// Lumped node masses of a deformable wall (a membrane), empty for a rigid wall of infinite mass [kg].
  /// A contact's effective mass is then m* = m_body m_w / (m_body + m_w), m_w interpolated at the contact
  /// point: a heavy block on a light net is not damped as if the net were rigid.
  std::vector<double> nodeMass;
  /// One-sided sheet: spheres live on the side its triangles' normals (right-hand rule) point to; a sphere
  /// whose centre crossed it is pushed back towards its closest point, its overlap counted through the
  /// sheet (r + depth). Two-sided (false): either side.
  bool oneSided = false;
  /// One-sided: how far behind the sheet a centre still is in contact, in its own radii. Soft contacts
  /// (the rockfall paper's E = 1e5 Pa) push small spheres more than a radius through; deeper centres
  /// are lost contacts, counted in lostThroughSheet (rockfall c5: 1.73 radii deep in the coupled run,
  /// 2.46 on a rigid floor).
  double depthRadii = 3.0;
  std::int64_t lostThroughSheet = 0;  ///< contacts lost so far because a centre went deeper than depthRadii
  double maxDepthRadii = 0.0;         ///< the deepest centre behind the sheet so far, in radii
  Vec3 force = Vec3::Zero();     ///< total force on the wall [N]
  Vec3 moment = Vec3::Zero();    ///< total moment about the origin [N m]
  void archive(common::StateArchive& a) {
    a.io("name", name), a.io("nodes", nodes), a.io("node_velocity", nodeVelocity), a.io("triangles", triangles);
    a.io("material", material), a.io("motion", motion), a.io("velocity", velocity), a.io("node_force", nodeForce);
    a.io("node_mass", nodeMass), a.io("one_sided", oneSided), a.io("depth_radii", depthRadii);
    a.io("lost_through_sheet", lostThroughSheet), a.io("max_depth_radii", maxDepthRadii), a.io("force", force);
    a.io("moment", moment);
  }
  std::size_t heapBytes() const { return common::heapBytes(nodes, nodeVelocity, triangles, nodeForce, nodeMass); }
};

}  // namespace dem
