#include "dem/walls.hpp"

#include <fmt/format.h>

#include "common/errors.hpp"

namespace dem {

std::uint32_t PlaneWallSet::add(const PlaneWall& wall) {
  walls_.push_back(wall);
  walls_.back().normal.normalize();
  forces_.push_back(Vec3::Zero());
  return static_cast<std::uint32_t>(walls_.size() - 1);
}

std::uint32_t MeshWallSet::add(MeshWall wall) {
  wall.nodeVelocity.assign(wall.nodes.size(), wall.motion == MeshWall::Motion::kPrescribed ? wall.velocity : Vec3::Zero());
  wall.nodeForce.assign(wall.nodes.size(), Vec3::Zero());
  walls_.push_back(std::move(wall));
  return static_cast<std::uint32_t>(walls_.size() - 1);
}

void MeshWallSet::setState(std::uint32_t mesh, const std::vector<Vec3>& positions, const std::vector<Vec3>& velocities) {
  MeshWall& w = walls_.at(mesh);
  if (positions.size() != w.nodes.size() || velocities.size() != w.nodes.size())
    throw common::SimulationError(fmt::format("mesh wall \"{}\" has {} nodes; the state given has {} positions and {} "
                                              "velocities.",
                                              w.name, w.nodes.size(), positions.size(), velocities.size()));
  w.nodes = positions;
  w.nodeVelocity = velocities;
}

}  // namespace dem
