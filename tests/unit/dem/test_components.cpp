// The components dem::Simulation orchestrates (dem_solver/src), each on its own: what it computes,
// against an exact or independent result, and its state as a value — copied and written to disk and
// read back, it continues bit for bit.
#include <omp.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>

#include "common/config.hpp"
#include "common/state_archive.hpp"
#include "dem/contact_law.hpp"
#include "dem/simulation.hpp"
#include "body_stiffness.hpp"
#include "contact_set.hpp"
#include "integrator.hpp"
#include "mesh_walls.hpp"
#include "neighbour_list.hpp"
#include "plane_walls.hpp"
#include "sphere_pairs.hpp"
#include "step_context.hpp"
#include "temp_dir.hpp"

using dem::Vec3;

namespace {

namespace fs = std::filesystem;

bool sameBits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }
bool sameBits(const Vec3& a, const Vec3& b) { return std::memcmp(a.data(), b.data(), sizeof(double) * 3) == 0; }

// Writes `value` to a fresh archive under `name` and reads it into `into`: a component's state on disk
// and back.
template <class T>
void writeAndRead(T& value, T& into, const std::string& name) {
  const TempDir dir;
  const fs::path path = dir.path() / (name + ".h5");
  {
    auto a = common::StateArchive::create(path, "test");
    a.io(name, value);
    a.commit();
  }
  auto a = common::StateArchive::open(path, "test");
  a.io(name, into);
}

constexpr double kPi = 3.14159265358979323846;

// The OpenMP thread count put back however a test that sets it ends.
struct ThreadCountKept {
  int max = omp_get_max_threads();
  ~ThreadCountKept() { omp_set_num_threads(max); }
};

// What a component reads from the simulation, built by hand: lone spheres of rock (material 0), walls of
// steel (material 1), one Hertz–Mindlin law for every pair, and the per-sphere sums.
struct Model {
  dem::Simulation::Settings settings;
  std::vector<std::unique_ptr<dem::ContactLaw>> laws;
  std::vector<int> lawOf{0, 0, 0, 0};
  dem::Bodies bodies;
  dem::Spheres spheres;
  std::vector<Vec3> force, torque;

  Model() {
    settings.dt = 1e-6;
    settings.skin = 2e-3;
    settings.meshSkin = 2e-3;
    const dem::Material rock{"rock", 2500, 5e7, 0.25}, steel{"steel", 7800, 2e11, 0.3};
    const auto law = common::Config::parse("{law: hertz_mindlin, restitution: 0.5, friction: 0.3}", "test.yaml");
    laws.push_back(dem::makeContactLaw("hertz_mindlin", law, rock, steel));
  }
  /// A free lone sphere of radius r at x; returns its index (= its body's).
  std::uint32_t addSphere(const Vec3& x, double r, const Vec3& velocity = Vec3::Zero(),
                          const Vec3& external = Vec3::Zero()) {
    const auto i = static_cast<std::uint32_t>(spheres.size());
    const double m = 4.0 / 3.0 * kPi * r * r * r * 2500.0;
    bodies.position.push_back(x), bodies.velocity.push_back(velocity);
    bodies.angularVelocity.push_back(Vec3::Zero()), bodies.angularMomentum.push_back(Vec3::Zero());
    bodies.orientation.push_back(dem::Quat::Identity()), bodies.mass.push_back(m);
    bodies.inertia.push_back(Vec3::Constant(0.4 * m * r * r)), bodies.force.push_back(Vec3::Zero());
    bodies.torque.push_back(Vec3::Zero()), bodies.externalForce.push_back(external), bodies.fixed.push_back(0);
    bodies.firstSphere.push_back(i), bodies.sphereCount.push_back(1);
    spheres.local.push_back(Vec3::Zero()), spheres.position.push_back(x), spheres.radius.push_back(r);
    spheres.material.push_back(0), spheres.body.push_back(i);
    force.push_back(Vec3::Zero()), torque.push_back(Vec3::Zero());
    return i;
  }
  dem::StepContext context() {
    std::fill(force.begin(), force.end(), Vec3::Zero());
    std::fill(torque.begin(), torque.end(), Vec3::Zero());
    return {settings, laws, lawOf, 2, bodies, spheres, bodies.position.data(), force.data(), torque.data(),
            true, true, false};
  }
  /// The elastic normal force |F_n| and stiffness of a contact of R*, m* and overlap δ by the law.
  dem::ContactLaw::NormalTangent law(double effRadius, double effMass, double overlap) const {
    return laws[0]->normalTangent(effRadius, effMass, overlap);
  }
};

}  // namespace

// Leapfrog with the half kick first integrates a constant acceleration exactly: x(t) = x0 + v0 t + a t²/2
// and the half-step velocity v(t − dt/2) = v0 + a (t − dt/2), to round-off (1e-12 relative: 400 steps
// of additions to numbers of order 1). Its clock counts the steps, and its state written and read back
// continues with the same bits.
TEST(DemIntegrator, ConstantAccelerationIsExactAndItsStateContinuesBitForBit) {
  const Vec3 x0(0.1, -0.2, 1.0), v0(1.0, 0.5, 2.0), external(0.0, 3.0, 4.0);
  const double m = 2.0;
  Model model;
  model.addSphere(x0, 0.01, v0, external);
  model.bodies.mass[0] = m;
  dem::Simulation::Settings& settings = model.settings;
  settings.dt = 1e-3;
  settings.gravity = Vec3(0.0, 0.0, -9.81);
  const Vec3 a = settings.gravity + external / m;
  dem::Bodies& bodies = model.bodies;
  const dem::Spheres& spheres = model.spheres;
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

// A floor and three spheres: one touching it (overlap δ), one within the skin, one beyond. Only the first
// two are candidates; the touching one is pushed up by the law's elastic force (at rest: no dashpot, no
// friction), the floor takes the reaction, its stiffness is the law's and the pass sums the law's stored
// energy. Written and read back, the walls compute the same forces with the same bits.
TEST(DemPlaneWalls, ForceAndReactionAreTheLawsAndTheStateContinuesBitForBit) {
  Model model;
  const double r = 0.01, overlap = 1e-4;
  model.addSphere(Vec3(0.0, 0.0, r - overlap), r);
  model.addSphere(Vec3(0.1, 0.0, r + 0.5 * model.settings.skin), r);
  model.addSphere(Vec3(0.2, 0.0, r + 2.0 * model.settings.skin), r);
  dem::PlaneWalls walls;
  walls.add({"floor", Vec3::Zero(), Vec3(0.0, 0.0, 2.0), Vec3::Zero(), 1});
  EXPECT_DOUBLE_EQ(walls.walls()[0].normal.z(), 1.0) << "the normal is normalised";
  walls.rebuildCandidates(model.context());
  ASSERT_EQ(walls.contacts().size(), 2u);
  EXPECT_EQ(walls.contacts().a[0], 0u);
  EXPECT_EQ(walls.contacts().a[1], 1u);
  walls.computeContacts(model.context());
  const auto expected = model.law(r, model.bodies.mass[0], overlap);
  EXPECT_NEAR(model.force[0].z(), expected.force, 1e-12 * expected.force);
  EXPECT_EQ(model.force[0].x(), 0.0);
  EXPECT_EQ(model.force[1].norm(), 0.0) << "a candidate that does not touch";
  EXPECT_EQ(model.torque[0].norm(), 0.0) << "the force passes through the centre";
  EXPECT_EQ((walls.forces()[0] + model.force[0]).norm(), 0.0) << "action = −reaction";
  // Without rolling resistance the pass sums the energies: Hertz's ∫ F dδ = (2/5) F δ, nothing dissipated at rest.
  EXPECT_TRUE(walls.energySummed());
  EXPECT_NEAR(walls.energy()[0], 0.4 * expected.force * overlap, 1e-9 * expected.force * overlap) << "elastic energy";
  EXPECT_EQ(walls.energy()[1], 0.0) << "damping";
  EXPECT_EQ(walls.energy()[2], 0.0) << "friction";
  EXPECT_NEAR(walls.contactStiffness(model.laws)[0], expected.stiffness, 1e-12 * expected.stiffness);
  // The stable-step estimate: a wall does not move with the sphere, so its body sees k_n and c_n alone.
  dem::BodyStiffness stiffness(3);
  walls.addStiffness(model.laws, model.spheres, stiffness);
  EXPECT_NEAR(stiffness.k[0], expected.stiffness, 1e-12 * expected.stiffness);
  EXPECT_NEAR(stiffness.c[0], expected.damping, 1e-12 * expected.damping);
  EXPECT_EQ(stiffness.k[1], 0.0) << "a candidate that does not touch";

  dem::PlaneWalls read;
  writeAndRead(walls, read, "plane_walls");
  dem::PlaneWalls copied = walls;
  model.bodies.position[0].z() -= 1e-5;  // one more step's approach: the history now matters
  model.bodies.velocity[0].z() = -1.0;
  std::vector<std::vector<Vec3>> sums;
  for (dem::PlaneWalls* w : {&walls, &read, &copied}) {
    w->computeContacts(model.context());
    sums.push_back(model.force);
  }
  EXPECT_GT(sums[0][0].z(), expected.force) << "deeper and approaching: more force";
  for (int k = 1; k < 3; ++k) {
    EXPECT_TRUE(sameBits(sums[k][0], sums[0][0])) << "copy " << k;
  }
  EXPECT_TRUE(sameBits(read.forces()[0], walls.forces()[0]));
}

// The plane pass's energy sums (without rolling resistance) are the sums of the energies of the contact
// forces it stores with rolling resistance: the same bits on one thread, to round-off on 2 to 7 (the sums
// are split among the threads), for more candidates than one thread takes and two laws (each thread's sums
// carried from one law's batch to the next).
TEST(DemPlaneWalls, EnergiesSummedInThePassAreThoseOfTheContactsForces) {
  Model model;
  const dem::Material rock{"rock", 2500, 5e7, 0.25}, steel{"steel", 7800, 2e11, 0.3};
  const auto second = common::Config::parse("{law: hertz_mindlin, restitution: 0.7, friction: 0.5}", "test.yaml");
  model.laws.push_back(dem::makeContactLaw("hertz_mindlin", second, rock, steel));
  model.lawOf = {0, 0, 0, 1};  // [sphere material × 2 + wall material]: spheres of material 1 on steel, law 1
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const double r = 0.01;
  for (int y = 0; y < 40; ++y)
    for (int x = 0; x < 40; ++x) {  // pressed into the floor, approaching, sliding and spinning
      const auto i = model.addSphere(Vec3(0.03 * x, 0.03 * y, r - 1e-4 * (1.0 + 0.5 * u(rng))), r,
                                     Vec3(0.1 * u(rng), 0.1 * u(rng), -0.05 + 0.02 * u(rng)));
      model.bodies.angularVelocity[i] = Vec3(u(rng), u(rng), u(rng));
      if ((x + y) % 3 == 0) model.spheres.material[i] = 1;
    }
  dem::PlaneWalls walls;
  walls.add({"floor", Vec3::Zero(), Vec3::UnitZ(), Vec3::Zero(), 1});
  walls.rebuildCandidates(model.context());
  ASSERT_EQ(walls.contacts().size(), 1600u);
  for (const auto& [begin, end] : walls.contacts().ranges) ASSERT_GT(end - begin, std::size_t{256}) << "a law's batch";
  const ThreadCountKept restore;
  for (const int threads : {1, 2, 3, 7}) {
    omp_set_num_threads(threads);
    dem::PlaneWalls summing = walls, storing = walls;
    summing.computeContacts(model.context());
    dem::StepContext rolling = model.context();
    rolling.rolling = true;
    storing.computeContacts(rolling);
    ASSERT_TRUE(summing.energySummed());
    ASSERT_FALSE(storing.energySummed());
    std::array<double, 3> want{};
    for (const dem::ContactForce& f : storing.contacts().force)
      want[0] += f.elasticEnergy, want[1] += f.dampingEnergy, want[2] += f.frictionEnergy;
    EXPECT_GT(want[0], 0.0);
    EXPECT_GT(want[1], 0.0) << "approaching: the dashpots dissipate";
    for (std::size_t k = 0; k < 3; ++k) {
      if (threads == 1) EXPECT_TRUE(sameBits(summing.energy()[k], want[k])) << "energy " << k;
      else EXPECT_NEAR(summing.energy()[k], want[k], 1e-12 * std::abs(want[k])) << "energy " << k << ", " << threads << " threads";
    }
  }
}

// A sphere pressed into a square of two triangles, off their shared edge: one face contact with the
// law's elastic force, split to the three nodes of its triangle by the barycentric weights (they sum
// to the reaction, so the total is conserved), its moment about the origin that of the contact point.
// Written and read back, the walls compute the same contact with the same bits.
TEST(DemMeshWalls, ForceIsTheLawsAndItsNodeSplitConservesItAndTheStateContinuesBitForBit) {
  Model model;
  const double r = 0.01, overlap = 1e-4;
  const Vec3 centre(0.03, 0.07, r - overlap);
  model.addSphere(centre, r);
  dem::MeshWalls meshes;
  dem::MeshWall square;
  square.name = "square";
  square.nodes = {Vec3(0, 0, 0), Vec3(0.1, 0, 0), Vec3(0.1, 0.1, 0), Vec3(0, 0.1, 0)};
  square.triangles = {{0, 1, 2}, {0, 2, 3}};
  square.material = 1;
  meshes.add(square);
  EXPECT_EQ(meshes.walls()[0].nodeForce.size(), 4u);
  meshes.rebuildCandidates(model.context());
  ASSERT_FALSE(meshes.contacts().candidates.empty());
  meshes.computeContacts(model.context());
  ASSERT_EQ(meshes.contacts().contacts.size(), 1u);
  EXPECT_EQ(meshes.contacts().contacts[0].triangle, 1u) << "x < y: the triangle (0, 2, 3)";
  meshes.computeForces(model.context());
  const auto expected = model.law(r, model.bodies.mass[0], overlap);
  const Vec3 f = model.force[0];
  EXPECT_NEAR(f.z(), expected.force, 1e-12 * expected.force);
  EXPECT_NEAR(std::hypot(f.x(), f.y()), 0.0, 1e-15 * expected.force);
  const dem::MeshWall& w = meshes.walls()[0];
  Vec3 nodeSum = Vec3::Zero();
  for (const Vec3& n : w.nodeForce) nodeSum += n;
  EXPECT_NEAR((nodeSum + f).norm(), 0.0, 1e-14 * expected.force) << "the node forces sum to the reaction";
  EXPECT_EQ(w.nodeForce[1].norm(), 0.0) << "node 1 is not in the triangle";
  EXPECT_EQ((w.force + f).norm(), 0.0);
  const Vec3 point(centre.x(), centre.y(), 0.0);
  EXPECT_NEAR((w.moment + point.cross(f)).norm(), 0.0, 1e-14 * expected.force);
  dem::BodyStiffness stiffness(1);
  meshes.addStiffness(model.laws, model.spheres, stiffness);
  EXPECT_NEAR(stiffness.k[0], expected.stiffness, 1e-12 * expected.stiffness) << "a wall: k_n alone";

  dem::MeshWalls read, copied = meshes;
  writeAndRead(meshes, read, "mesh_walls");
  model.bodies.position[0] += Vec3(1e-4, 0.0, -1e-5);  // on along the face and deeper: histories matter
  model.bodies.velocity[0] = Vec3(0.5, 0.0, -1.0);
  std::vector<std::vector<Vec3>> sums;
  for (dem::MeshWalls* m : {&meshes, &read, &copied}) {
    auto ctx = model.context();
    m->computeContacts(ctx);
    m->computeForces(ctx);
    sums.push_back(model.force);
  }
  EXPECT_GT(sums[0][0].z(), expected.force) << "deeper and approaching: more force";
  EXPECT_LT(sums[0][0].x(), 0.0) << "friction against the sliding";
  for (int k = 1; k < 3; ++k) EXPECT_TRUE(sameBits(sums[k][0], sums[0][0])) << "copy " << k;
  EXPECT_TRUE(sameBits(read.walls()[0].nodeForce[2], meshes.walls()[0].nodeForce[2]));
}

// The neighbour list as a component, on a random polydisperse packing: its pairs are exactly those within
// r_a + r_b + skin (brute force over every pair); a shift shared by every body uses up no skin, one body
// moving more than the skin relative to the others calls for a rebuild, less does not — for lone spheres
// and through the general test for rigid bodies alike.
TEST(DemNeighbourList, ComponentFindsThePairsWithinTheSkinAndRebuildsOnRelativeMotionOnly) {
  Model model;
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> box(0.0, 0.02), radius(0.5e-3, 1.5e-3);
  for (int i = 0; i < 600; ++i) model.addSphere(Vec3(box(rng), box(rng), box(rng)), radius(rng));
  const double skin = model.settings.skin = 2e-4;
  dem::NeighbourList list;
  for (std::size_t b = 0; b < model.bodies.size(); ++b) list.addBody(0.0);
  list.prepare(true);
  const dem::BondSet noBonds;
  const std::vector<dem::Triple> found = list.findPairs(model.context(), noBonds);
  std::vector<dem::Triple> expected;
  const auto& x = model.spheres.position;
  const auto& r = model.spheres.radius;
  for (std::uint32_t i = 0; i < x.size(); ++i)
    for (std::uint32_t j = i + 1; j < x.size(); ++j)
      if ((x[i] - x[j]).norm() < r[i] + r[j] + skin) expected.emplace_back(0, i, j);
  ASSERT_GT(expected.size(), 300u) << "a packing dense enough to test";
  EXPECT_EQ(found, expected);

  const std::vector<dem::PlaneWall> planes;
  const std::vector<dem::MeshWall> meshes;
  for (const bool lone : {true, false}) {
    dem::Bodies& bodies = model.bodies;
    const std::vector<Vec3> start = bodies.position;
    list.pairsBuilt(bodies, lone);
    for (Vec3& p : bodies.position) p += Vec3(5.0 * skin, -3.0 * skin, 0.0);
    auto rebuild = [&] { return list.needsRebuild(bodies, lone, model.settings, planes, meshes).pairs; };
    EXPECT_FALSE(rebuild()) << "shared motion, lone " << lone;
    bodies.position[7].z() += 0.9 * skin;
    EXPECT_FALSE(rebuild()) << "0.9 skin, lone " << lone;
    bodies.position[7].z() += 0.2 * skin;
    EXPECT_TRUE(rebuild()) << "1.1 skin, lone " << lone;
    bodies.position = start;
  }

  // Its state (the poses at the last builds) as a value: a copy, and a list built for the same bodies that
  // read it from disk, decide as the original does, step by step across the skin.
  dem::Bodies& bodies = model.bodies;
  list.pairsBuilt(bodies, false);
  dem::NeighbourList copied = list, read;
  for (std::size_t b = 0; b < bodies.size(); ++b) read.addBody(0.0);
  read.prepare(true);
  writeAndRead(list, read, "neighbour_list");
  int rebuilds = 0;
  for (const double dz : {0.5, 0.45, 0.1, 0.3}) {
    bodies.position[7].z() += dz * skin;
    const bool original = list.needsRebuild(bodies, false, model.settings, planes, meshes).pairs;
    EXPECT_EQ(copied.needsRebuild(bodies, false, model.settings, planes, meshes).pairs, original) << dz;
    EXPECT_EQ(read.needsRebuild(bodies, false, model.settings, planes, meshes).pairs, original) << dz;
    rebuilds += original;
  }
  EXPECT_EQ(rebuilds, 2) << "past the skin after 1.05 and 1.35 skins";
}

// Two touching spheres and an open candidate: the pair's forces are equal and opposite with the law's
// elastic magnitude (at rest), the open candidate adds nothing and reports its gap as a negative
// overlap, and the pass sums the touching pair's energy. Written and read back, the pairs continue with
// the same bits.
TEST(DemSpherePairs, ActionIsMinusReactionWithTheLawsForceAndTheStateContinuesBitForBit) {
  Model model;
  const double r = 0.01, overlap = 1e-4, gap = 3e-4;
  model.addSphere(Vec3(0.0, 0.0, 0.0), r);
  model.addSphere(Vec3(2.0 * r - overlap, 0.0, 0.0), r);
  model.addSphere(Vec3(0.0, 2.0 * r + gap, 0.0), r);
  dem::SpherePairs pairs;
  std::vector<dem::Triple> candidates{{0, 0, 1}, {0, 0, 2}};
  pairs.assign(model.context(), candidates);
  ASSERT_EQ(pairs.contacts().size(), 2u);
  double wait = 0.0;
  pairs.computeForces(model.context(), wait);
  const double m = model.bodies.mass[0];
  const auto expected = model.law(0.5 * r, 0.5 * m, overlap);
  EXPECT_NEAR(model.force[1].x(), expected.force, 1e-9 * expected.force);
  EXPECT_EQ((model.force[0] + model.force[1]).norm(), 0.0) << "action = −reaction";
  EXPECT_EQ(model.force[2].norm(), 0.0) << "an open candidate";
  EXPECT_NEAR(pairs.overlap(0, model.spheres), overlap, 1e-9 * overlap);
  EXPECT_NEAR(pairs.overlap(1, model.spheres), -gap, 1e-9 * gap);
  EXPECT_TRUE(pairs.energySummed());
  // Hertz: ∫ F dδ = (2/5) F δ, the one touching pair's.
  EXPECT_NEAR(pairs.energy()[0], 0.4 * expected.force * overlap, 1e-9 * expected.force * overlap) << "elastic energy stored";
  // The stable-step estimate: two equal free masses on a spring k vibrate at ω² = 2k/m, so each body
  // sees k (1 + √(m/m)) = 2k; the open candidate adds nothing.
  dem::BodyStiffness stiffness(3);
  pairs.addStiffness(model.laws, model.spheres, model.bodies, stiffness);
  for (int b = 0; b < 2; ++b) {
    EXPECT_NEAR(stiffness.k[b], 2.0 * expected.stiffness, 1e-9 * expected.stiffness) << "body " << b;
    EXPECT_NEAR(stiffness.c[b], 2.0 * expected.damping, 1e-9 * expected.damping) << "body " << b;
  }
  EXPECT_EQ(stiffness.k[2], 0.0);

  dem::SpherePairs read, copied = pairs;
  writeAndRead(pairs, read, "sphere_pairs");
  model.bodies.velocity[0] = Vec3(1.0, 0.2, 0.0);  // approaching and sliding: the history matters
  model.bodies.position[0] += Vec3(1e-5, 2e-6, 0.0);
  std::vector<std::vector<Vec3>> sums;
  std::vector<double> elastic;
  for (dem::SpherePairs* p : {&pairs, &read, &copied}) {
    p->computeForces(model.context(), wait);
    sums.push_back(model.force);
    elastic.push_back(p->energy()[0]);
  }
  EXPECT_GT(sums[0][1].x(), expected.force) << "deeper and approaching: more force";
  for (int k = 1; k < 3; ++k) {
    EXPECT_TRUE(sameBits(sums[k][0], sums[0][0]) && sameBits(sums[k][1], sums[0][1])) << "copy " << k;
    EXPECT_TRUE(sameBits(elastic[k], elastic[0])) << "copy " << k;
  }
}

// The stable-step estimate's per-body sums (SpherePairs::addStiffness) have the order of one pass over the
// contacts on any number of threads: on 1 to 7 threads the same bits as a serial sum in contact order, for
// more touching pairs than a block of terms (2^14), spheres of several sizes (unequal couplings) and some
// fixed bodies (couplings of 1).
TEST(DemSpherePairs, StiffnessSumsHaveTheBitsOfOnePassOnAnyNumberOfThreads) {
  Model model;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const std::uint32_t n = 28;  // 28³ = 21,952 spheres, 3 · 27 · 28² = 63,504 neighbour pairs
  const double spacing = 0.02;
  for (std::uint32_t z = 0; z < n; ++z)
    for (std::uint32_t y = 0; y < n; ++y)
      for (std::uint32_t x = 0; x < n; ++x) model.addSphere(spacing * Vec3(x, y, z), 0.0101 + 0.0008 * u(rng));
  for (auto& f : model.bodies.fixed)
    if (u(rng) < 0.05) f = dem::kFixed;
  std::vector<dem::Triple> candidates;
  for (std::uint32_t i = 0; i < n * n * n; ++i) {
    const std::uint32_t x = i % n, y = i / n % n, z = i / (n * n);
    if (x + 1 < n) candidates.emplace_back(0, i, i + 1);
    if (y + 1 < n) candidates.emplace_back(0, i, i + n);
    if (z + 1 < n) candidates.emplace_back(0, i, i + n * n);
  }
  dem::SpherePairs pairs;
  pairs.assign(model.context(), candidates);
  double wait = 0.0;
  pairs.computeForces(model.context(), wait);  // the overlaps the sums read
  const dem::ContactSet& c = pairs.contacts();
  dem::BodyStiffness want(model.bodies.size());
  std::size_t touching = 0;
  for (std::size_t k = 0; k < c.size(); ++k) {
    if (!(c.overlap[k] > 0.0)) continue;
    ++touching;
    const auto t = model.law(c.effRadius[k], c.effMass[k], c.overlap[k]);
    want.addPair(model.bodies, c.a[k], c.b[k], t.stiffness, t.damping);
  }
  ASSERT_GT(touching, std::size_t{1} << 14);
  const ThreadCountKept restore;
  for (const int threads : {1, 2, 3, 4, 7}) {
    omp_set_num_threads(threads);
    dem::BodyStiffness got(model.bodies.size());
    pairs.addStiffness(model.laws, model.spheres, model.bodies, got);
    for (std::size_t b = 0; b < model.bodies.size(); ++b) {
      ASSERT_TRUE(sameBits(got.k[b], want.k[b])) << "body " << b << " on " << threads << " threads";
      ASSERT_TRUE(sameBits(got.c[b], want.c[b])) << "body " << b << " on " << threads << " threads";
    }
  }
}

// ContactSet::assign moves the surviving candidates' histories, R* and m* in place: against a map from
// each key to its old values, for lists that grow, shrink, gain or lose candidates at the front or the
// back, and are replaced outright, on 1 to 7 threads (each thread's run then takes some of its sources
// from other runs). A survivor keeps its history only if it touched (lastOverlap > 0).
TEST(DemContactSet, AssignCarriesTheSurvivorsHistoriesInPlace) {
  using Key = std::tuple<int, std::uint32_t, std::uint32_t>;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  auto keys = [&](std::size_t count, std::uint32_t lowest, std::uint32_t span) {
    std::vector<Key> k;
    for (std::size_t i = 0; i < count; ++i)
      k.emplace_back(static_cast<int>(u(rng) < 0.3), lowest + static_cast<std::uint32_t>(u(rng) * span),
                     static_cast<std::uint32_t>(u(rng) * 1000));
    std::sort(k.begin(), k.end());
    k.erase(std::unique(k.begin(), k.end()), k.end());
    return k;
  };
  struct Case {
    std::size_t oldCount, newCount;
    std::uint32_t oldLowest, newLowest, span;
    double survive;  // the fraction of the old keys carried into the new list
  };
  const std::vector<Case> cases = {
      {20000, 3000, 0, 0, 5000, 0.9},     // grows at every place
      {20000, 0, 0, 0, 5000, 0.5},        // loses half
      {20000, 15000, 0, 2500, 2500, 0.8}, // loses the front, grows the back
      {20000, 15000, 2500, 0, 2500, 0.8}, // grows the front
      {20000, 20000, 0, 0, 5000, 0.0},    // replaced
      {0, 20000, 0, 0, 5000, 0.0},        // the first build
      {20000, 0, 0, 0, 5000, 0.0},        // emptied
      {300, 100, 0, 0, 50, 0.95},
      {2000, 2, 0, 0, 500, 0.001},        // fewer candidates than threads: empty runs
  };
  const ThreadCountKept restore;
  for (const Case& c : cases) {
    for (const int threads : {1, 2, 3, 4, 7}) {
      omp_set_num_threads(threads);
      dem::ContactSet set;
      const std::vector<Key> oldKeys = keys(c.oldCount, c.oldLowest, c.span);
      std::map<Key, std::tuple<dem::ContactHistory, double, double>> before;
      for (const auto& [l, a, b] : oldKeys) {
        set.law.push_back(l), set.a.push_back(a), set.b.push_back(b);
        dem::ContactHistory h;
        h.shearForce = Vec3(u(rng), u(rng), u(rng));
        h.lastOverlap = u(rng) < 0.8 ? u(rng) : 0.0;
        set.history.push_back(h), set.effRadius.push_back(1.0 + u(rng)), set.effMass.push_back(1.0 + u(rng));
        before[{l, a, b}] = {h, set.effRadius.back(), set.effMass.back()};
      }
      std::vector<Key> pairs = keys(c.newCount, c.newLowest, c.span);
      for (const Key& k : oldKeys)
        if (u(rng) < c.survive) pairs.push_back(k);
      std::sort(pairs.begin(), pairs.end());
      pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
      const std::vector<Key> expected = pairs;
      const bool pointsAndForces = c.oldCount == 300;  // as the plane walls ask
      set.assign(pairs, 2, pointsAndForces);
      ASSERT_EQ(set.size(), expected.size());
      ASSERT_EQ(set.history.size(), expected.size());
      std::size_t carried = 0;
      for (std::size_t i = 0; i < expected.size(); ++i) {
        ASSERT_EQ(Key(set.law[i], set.a[i], set.b[i]), expected[i]);
        const auto it = before.find(expected[i]);
        const bool touched = it != before.end() && std::get<0>(it->second).lastOverlap > 0.0;
        const dem::ContactHistory want = touched ? std::get<0>(it->second) : dem::ContactHistory{};
        ASSERT_EQ(set.history[i].shearForce, want.shearForce) << "candidate " << i << " on " << threads << " threads";
        ASSERT_EQ(set.history[i].lastOverlap, want.lastOverlap);
        if (set.effRadius.empty()) continue;  // the first build carries no R*, m*
        ASSERT_EQ(set.effRadius[i], it != before.end() ? std::get<1>(it->second) : 0.0);
        ASSERT_EQ(set.effMass[i], it != before.end() ? std::get<2>(it->second) : 0.0);
        carried += it != before.end();
      }
      EXPECT_EQ(set.point.size(), pointsAndForces ? expected.size() : 0u);
      EXPECT_EQ(set.force.size(), pointsAndForces ? expected.size() : 0u);
      const auto law0 = static_cast<std::size_t>(
          std::count_if(expected.begin(), expected.end(), [](const Key& k) { return std::get<0>(k) == 0; }));
      ASSERT_EQ(set.ranges.size(), 2u);
      EXPECT_EQ(set.ranges[0], std::make_pair(std::size_t{0}, law0));
      EXPECT_EQ(set.ranges[1], std::make_pair(law0, expected.size()));
      if (c.survive >= 0.5 && c.oldCount > 0) {
        EXPECT_GT(carried, 0u);
      }
    }
  }
}
