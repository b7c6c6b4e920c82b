// The components dem::Simulation orchestrates (dem_solver/src), each on its own: what it computes,
// against an exact or independent result, and its state as a value — copied and written to disk and
// read back, it continues bit for bit.
#include <cmath>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/state_archive.hpp"
#include "dem/simulation.hpp"
#include "integrator.hpp"

using dem::Vec3;

namespace {

namespace fs = std::filesystem;

bool sameBits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }
bool sameBits(const Vec3& a, const Vec3& b) { return std::memcmp(a.data(), b.data(), sizeof(double) * 3) == 0; }

// Writes `value` to a fresh archive under `name` and reads it into `into`: a component's state on disk
// and back.
template <class T>
void writeAndRead(T& value, T& into, const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / "cosim_dem_components_test";
  fs::create_directories(dir);
  const fs::path path = dir / (name + ".h5");
  fs::remove(path);
  {
    auto a = common::StateArchive::create(path, "test");
    a.io(name, value);
    a.commit();
  }
  auto a = common::StateArchive::open(path, "test");
  a.io(name, into);
}

// One free body (a lone sphere of mass m at its centre) under gravity and a constant external force.
dem::Bodies oneBody(const Vec3& position, const Vec3& velocity, double mass, const Vec3& external) {
  dem::Bodies b;
  b.position = {position}, b.velocity = {velocity}, b.angularVelocity = {Vec3::Zero()};
  b.angularMomentum = {Vec3::Zero()}, b.orientation = {dem::Quat::Identity()}, b.mass = {mass};
  b.inertia = {Vec3::Constant(0.4 * mass * 1e-4)}, b.force = {Vec3::Zero()}, b.torque = {Vec3::Zero()};
  b.externalForce = {external}, b.fixed = {0}, b.firstSphere = {0}, b.sphereCount = {1};
  return b;
}

dem::Spheres oneSphere() {
  dem::Spheres s;
  s.local = {Vec3::Zero()}, s.position = {Vec3::Zero()}, s.radius = {0.01}, s.material = {0}, s.body = {0};
  return s;
}

}  // namespace

// Leapfrog with the half kick first integrates a constant acceleration exactly: x(t) = x0 + v0 t + a t²/2
// and the half-step velocity v(t − dt/2) = v0 + a (t − dt/2), to round-off (1e-12 relative: 400 steps
// of additions to numbers of order 1). Its clock counts the steps, and its state written and read back
// continues with the same bits.
TEST(DemIntegrator, ConstantAccelerationIsExactAndItsStateContinuesBitForBit) {
  const Vec3 x0(0.1, -0.2, 1.0), v0(1.0, 0.5, 2.0), external(0.0, 3.0, 4.0);
  const double m = 2.0;
  dem::Simulation::Settings settings;
  settings.dt = 1e-3;
  settings.gravity = Vec3(0.0, 0.0, -9.81);
  const Vec3 a = settings.gravity + external / m;
  dem::Bodies bodies = oneBody(x0, v0, m, external);
  const dem::Spheres spheres = oneSphere();
  dem::Integrator integrator;
  integrator.prepare(bodies, true);
  const int n = 400;
  for (int i = 0; i < n; ++i) integrator.advance(bodies, spheres, settings, false, true);
  const double t = n * settings.dt;
  EXPECT_EQ(integrator.steps(), n);
  EXPECT_DOUBLE_EQ(integrator.time(), t);
  const Vec3 x = x0 + v0 * t + 0.5 * a * t * t, v = v0 + a * (t - 0.5 * settings.dt);
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(bodies.position[0][c], x[c], 1e-12 * x.norm()) << "component " << c;
    EXPECT_NEAR(bodies.velocity[0][c], v[c], 1e-12 * v.norm()) << "component " << c;
  }

  // The same continuation from a copy and from a copy written to disk.
  dem::Integrator copied = integrator, read;
  writeAndRead(integrator, read, "integrator");
  read.prepare(bodies, true);
  EXPECT_EQ(read.steps(), n);
  EXPECT_TRUE(sameBits(read.time(), integrator.time()));
  dem::Bodies b1 = bodies, b2 = bodies, b3 = bodies;
  const auto e1 = integrator.advance(b1, spheres, settings, false, true);
  const auto e2 = copied.advance(b2, spheres, settings, false, true);
  const auto e3 = read.advance(b3, spheres, settings, false, true);
  EXPECT_TRUE(sameBits(b1.position[0], b2.position[0]) && sameBits(b1.position[0], b3.position[0]));
  EXPECT_TRUE(sameBits(b1.velocity[0], b2.velocity[0]) && sameBits(b1.velocity[0], b3.velocity[0]));
  EXPECT_TRUE(sameBits(e1.kinetic, e2.kinetic) && sameBits(e1.kinetic, e3.kinetic));
  // After the first step the kinetic energy is the shadow form ½ m v(t − dt/2)·v(t + dt/2).
  const Vec3 vm = v, vp = v + a * settings.dt;
  EXPECT_NEAR(e1.kinetic, 0.5 * m * vm.dot(vp), 1e-12 * 0.5 * m * vp.squaredNorm());
  EXPECT_EQ(e1.shift, 0.0);
}
