// Checkpoints (issue 28): Model::saveState / restoreState repeat explicit steps bit for bit, including
// a change of step inside the repeated stretch (the variable-step leapfrog's last step is state too):
// the pre-stressed membrane under pressure and the bar wave.
#include <cstring>

#include <gtest/gtest.h>

#include "common/config.hpp"
#include "common/state_archive.hpp"
#include "fem/scene.hpp"
#include "scene_run.hpp"
#include "temp_dir.hpp"

namespace {

std::vector<double> record(const fem::Model& m) {
  std::vector<double> r = m.displacement();
  const fem::EnergyState& e = m.energy();
  r.insert(r.end(), {e.kinetic, e.strain, m.time(), m.dt(), static_cast<double>(m.steps())});
  return r;
}

void checkRepeat(const std::string& scene) {
  fem::Scene s = fem::loadScene(common::Config::load(testsupport::sourcePath(scene)));
  fem::Model& m = s.model;
  m.initializeExplicit(s.dt);
  for (int i = 0; i < 200; ++i) m.stepExplicit();
  const fem::Model::State saved = m.saveState();
  auto stretch = [&] {
    for (int i = 0; i < 150; ++i) {
      if (i == 70) m.setTimeStep(0.7 * s.dt);
      m.stepExplicit();
    }
    return record(m);
  };
  const std::vector<double> first = stretch();
  m.restoreState(saved);
  const std::vector<double> again = stretch();
  ASSERT_EQ(first.size(), again.size());
  for (std::size_t i = 0; i < first.size(); ++i)
    ASSERT_EQ(std::memcmp(&first[i], &again[i], sizeof(double)), 0) << scene << " value " << i;
}

// Through a disk checkpoint: a second model of the same scene reads the state and continues as the first.
void checkRestart(const std::string& scene) {
  auto load = [&] { return fem::loadScene(common::Config::load(testsupport::sourcePath(scene))); };
  fem::Scene s = load();
  s.model.initializeExplicit(s.dt);
  for (int i = 0; i < 200; ++i) s.model.stepExplicit();
  const TempDir dir;
  const auto file = dir.path() / "state.h5";
  common::StateArchive::write(file, "fem_solver", [&](common::StateArchive& a) {
    fem::Model::State state = s.model.saveState();
    a.io("model", state);
  });
  auto stretch = [&](fem::Model& m) {
    for (int i = 0; i < 150; ++i) m.stepExplicit();
    return record(m);
  };
  const std::vector<double> first = stretch(s.model);
  fem::Scene t = load();
  t.model.initializeExplicit(t.dt);
  auto a = common::StateArchive::open(file, "fem_solver");
  fem::Model::State state;
  a.io("model", state);
  t.model.restoreState(state);
  const std::vector<double> again = stretch(t.model);
  ASSERT_EQ(first.size(), again.size());
  for (std::size_t i = 0; i < first.size(); ++i)
    ASSERT_EQ(std::memcmp(&first[i], &again[i], sizeof(double)), 0) << scene << " value " << i;
}

}  // namespace

TEST(FemCheckpoint, ExplicitStepsContinueFromDiskBitForBit) {
  checkRestart("configs/fem/bar_wave.yaml");
  checkRestart("configs/fem/membrane_vibration.yaml");
}

TEST(FemCheckpoint, ExplicitStepsRepeatBitForBit) {
  checkRepeat("configs/fem/bar_wave.yaml");
  checkRepeat("configs/fem/membrane_vibration.yaml");
}
