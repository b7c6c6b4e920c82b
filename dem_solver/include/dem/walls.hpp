#pragma once
// The walls of a dem::Simulation as its users see them (Simulation::planeWalls(), meshWalls()): the scene
// adds them, a servo or a coupled run moves them between steps, and a run reads the forces the spheres
// exerted on them in the last step. Their contacts with the spheres are the simulation's (the components
// dem_solver/src/plane_walls and mesh_walls, which extend these with the candidates and histories).

#include <cstdint>
#include <vector>

#include "dem/mesh_wall.hpp"
#include "dem/model.hpp"

namespace dem {

class PlaneWallSet {
 public:
  /// Adds a wall (its normal normalised). Returns its index.
  std::uint32_t add(const PlaneWall& wall);
  const std::vector<PlaneWall>& walls() const { return walls_; }
  bool empty() const { return walls_.empty(); }
  /// A wall's translation velocity from the next step on [m/s].
  void setVelocity(std::uint32_t wall, const Vec3& velocity) { walls_.at(wall).velocity = velocity; }
  /// Total force the spheres exerted on each wall in the last force pass [N].
  const std::vector<Vec3>& forces() const { return forces_; }

 protected:
  // Copied only as part of its component (a checkpoint): a copy of sim.planeWalls() would move nothing.
  PlaneWallSet() = default;
  PlaneWallSet(const PlaneWallSet&) = default;
  PlaneWallSet& operator=(const PlaneWallSet&) = default;
  std::vector<PlaneWall> walls_;
  std::vector<Vec3> forces_;
};

class MeshWallSet {
 public:
  /// Adds a wall; its nodeVelocity and nodeForce are sized here. Returns its index.
  std::uint32_t add(MeshWall wall);
  /// The node positions and velocities of an externally driven wall for the next step.
  void setState(std::uint32_t mesh, const std::vector<Vec3>& positions, const std::vector<Vec3>& velocities);
  /// The walls, with the forces on their nodes and their moments from the last step.
  const std::vector<MeshWall>& walls() const { return walls_; }
  bool empty() const { return walls_.empty(); }

 protected:
  MeshWallSet() = default;
  MeshWallSet(const MeshWallSet&) = default;
  MeshWallSet& operator=(const MeshWallSet&) = default;
  std::vector<MeshWall> walls_;
};

}  // namespace dem
