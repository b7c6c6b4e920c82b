// Checkpoints (issue 28): a restored state repeats its steps bit for bit — what the coupler's repeated
// windows rely on. A pour (contacts forming, friction history, neighbour rebuilds) and a sphere bed on
// a mesh wall: step, save, step, record, restore, step again, compare every body's state and the
// energy ledger's bits.
#include <cstring>

#include <gtest/gtest.h>

#include "common/config.hpp"
#include "common/errors.hpp"
#include "common/state_archive.hpp"
#include "dem/scene.hpp"
#include "scene_run.hpp"
#include "temp_dir.hpp"

namespace {

struct Record {
  std::vector<double> values;
  void add(const dem::Vec3& v) { values.insert(values.end(), {v.x(), v.y(), v.z()}); }
};

Record record(const dem::Simulation& sim) {
  Record r;
  const dem::Bodies& b = sim.bodies();
  for (std::size_t i = 0; i < b.position.size(); ++i) {
    r.add(b.position[i]);
    r.add(b.velocity[i]);
    r.add(b.angularVelocity[i]);
  }
  const dem::EnergyLedger& e = sim.energy();
  r.values.insert(r.values.end(), {e.kinetic, e.potential, e.elastic, e.damping, e.friction, e.cundall, e.wallWork,
                                   sim.time(), static_cast<double>(sim.steps())});
  return r;
}

void expectSameBits(const Record& a, const Record& b) {
  ASSERT_EQ(a.values.size(), b.values.size());
  for (std::size_t i = 0; i < a.values.size(); ++i)
    ASSERT_EQ(std::memcmp(&a.values[i], &b.values[i], sizeof(double)), 0)
        << "value " << i << ": " << a.values[i] << " vs " << b.values[i];
}

void checkRepeat(const std::string& scene, const std::vector<std::string>& sets, int before, int between) {
  dem::Scene s = dem::loadScene(common::Config::load(testsupport::sourcePath(scene), sets));
  dem::Simulation& sim = *s.sim;
  for (int i = 0; i < before; ++i) sim.step();
  const auto saved = sim.saveCheckpoint();
  for (int i = 0; i < between; ++i) sim.step();
  const Record first = record(sim);
  sim.restoreCheckpoint(*saved);
  for (int i = 0; i < between; ++i) sim.step();
  expectSameBits(first, record(sim));
  // And once more from the same checkpoint: restoring does not consume or alter it.
  sim.restoreCheckpoint(*saved);
  for (int i = 0; i < between; ++i) sim.step();
  expectSameBits(first, record(sim));
}

// Through a disk checkpoint: a second simulation, built from the same scene, reads the state and
// continues as the first one does.
void checkRestart(const std::string& scene, const std::vector<std::string>& sets, int before, int between) {
  const auto load = [&] { return dem::loadScene(common::Config::load(testsupport::sourcePath(scene), sets)); };
  dem::Scene s = load();
  for (int i = 0; i < before; ++i) s.sim->step();
  const TempDir dir;
  const auto file = dir.path() / "state.h5";
  {
    auto a = common::StateArchive::create(file, "dem_solver");
    s.sim->archive(a);
    a.commit();
  }
  for (int i = 0; i < between; ++i) s.sim->step();
  const Record first = record(*s.sim);
  dem::Scene t = load();
  auto a = common::StateArchive::open(file, "dem_solver");
  t.sim->archive(a);
  for (int i = 0; i < between; ++i) t.sim->step();
  expectSameBits(first, record(*t.sim));
  // Another scene's checkpoint is refused, with the reason.
  dem::Scene other = dem::loadScene(common::Config::load(testsupport::sourcePath("configs/dem/hertz_bounce.yaml")));
  auto b = common::StateArchive::open(file, "dem_solver");
  EXPECT_THROW(other.sim->archive(b), common::ConfigError);
}

}  // namespace

TEST(DemCheckpoint, PourRestartsFromDiskBitForBit) {
  checkRestart("configs/dem/pour.yaml", {"generate[0].count=200", "generate[0].box.max=[0.1, 0.1, 0.4]"}, 3000, 1500);
}

TEST(DemCheckpoint, MeshWallBedRestartsFromDiskBitForBit) { checkRestart("configs/dem/mesh_floor.yaml", {}, 500, 800); }

TEST(DemCheckpoint, PourRepeatsItsStepsBitForBit) {
  checkRepeat("configs/dem/pour.yaml", {"generate[0].count=200", "generate[0].box.max=[0.1, 0.1, 0.4]"}, 3000, 1500);
}

TEST(DemCheckpoint, MeshWallBedRepeatsItsStepsBitForBit) { checkRepeat("configs/dem/mesh_floor.yaml", {}, 500, 800); }
