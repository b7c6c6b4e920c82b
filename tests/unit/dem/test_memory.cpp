// Simulation::memoryUse (the summary's `cost: memory_*` table) against what the allocator says the
// simulation holds: a structure left out of the table, or one counted twice, moves the sum away from it.
#include <malloc.h>

#include <cstddef>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/config.hpp"
#include "dem/contact_queries.hpp"
#include "dem/scene.hpp"
#include "dem/simulation.hpp"

namespace {

std::size_t heapInUse() {
  const struct mallinfo2 m = mallinfo2();
  return m.uordblks + m.hblkhd;  // small chunks in use + mmapped blocks
}

// A settling pour of 3,000 spheres from a 15 × 10 × 20 lattice, 300 steps.
double accountedFraction(const std::vector<std::string>& extra) {
  std::vector<std::string> overrides = {
      "generate[0]={material: glass, count: 3000, radius: [0.01, 0.01], box: {min: [0, 0, 0], max: [0.3255, 0.2205, "
      "0.4305]}, seed: 1}",
      "walls[2].point=[0.315, 0, 0]", "walls[4].point=[0, 0.21, 0]", "dt=2.42e-4", "dt_fraction=null",
      "steps_per_contact=9", "probe=null", "end_time=0.0726"};
  overrides.insert(overrides.end(), extra.begin(), extra.end());
  const auto cfg = common::Config::load(COSIM_SOURCE_DIR "/configs/dem/pour.yaml", overrides);
  const std::size_t before = heapInUse();
  dem::Scene scene = dem::loadScene(cfg);
  scene.sim->initialize();
  for (int i = 0; i < 300; ++i) scene.sim->step();
  const double held = static_cast<double>(heapInUse() - before);
  double accounted = 0.0;
  for (const auto& [name, bytes] : scene.sim->memoryUse()) accounted += static_cast<double>(bytes);
  EXPECT_GT(contactCounts(*scene.sim).pairCandidates, 4000);
  return accounted / held;
}

}  // namespace

TEST(DemMemory, UseByStructureIsWhatTheSimulationHolds) {
#if defined(__SANITIZE_ADDRESS__)
  GTEST_SKIP() << "AddressSanitizer's allocator does not fill mallinfo2";
#endif
  // The rest is the scene's own small allocations (laws, settings, names) and the allocator's headers.
  const double lone = accountedFraction({});
  EXPECT_GT(lone, 0.93);
  EXPECT_LE(lone, 1.0);
  // Rolling resistance keeps each candidate's point and force, and the spheres their own force sums.
  const double rolling = accountedFraction({"interactions[0].rolling_friction=0.1"});
  EXPECT_GT(rolling, 0.93);
  EXPECT_LE(rolling, 1.0);
}
