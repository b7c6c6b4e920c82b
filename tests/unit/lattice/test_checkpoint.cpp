// Lattice state as data (issue 28): a fracture test written to disk mid-run and read by a fresh model,
// solver and test continues exactly as the original does, for both stiffness storages and with the
// incrementally updated coarse space; a checkpoint of another specimen is refused.
#include <omp.h>

#include <cstring>
#include <filesystem>

#include <gtest/gtest.h>

#include "common/errors.hpp"
#include "common/state_archive.hpp"
#include "lattice/fracture_test.hpp"
#include "lattice/model.hpp"
#include "lattice/solver.hpp"
#include "temp_dir.hpp"

using namespace lattice;

namespace {

std::array<PhaseProperties, kPhaseCount> phases() {
  return {{{{1.0, 0.6, 0.6}, 2e-4, 2e-3}, {{3.0, 2.1, 2.1}, 1.333e-4, 2e-3}, {{0.7, 0.28, 0.28}, 5e-5, 2e-3}}};
}

Specimen specimen(double side) {
  Specimen sp = randomSpecimen({Vec3::Zero(), Vec3::Constant(side)}, 0.003, 0.5, 3);
  sp.aggregates = {{Vec3::Constant(0.5 * side), 0.3 * side}};
  classifyRods(sp);
  return sp;
}

// A model, its solver and the test on it, as a standalone run builds them.
struct Run {
  Model model;
  std::unique_ptr<EquilibriumSolver> solver;
  FractureTest test;
  Run(const Specimen& sp, Operator op, const SolverSettings& s, const std::string& type, const std::string& keys)
      : model(sp, makeRodLaw("beam"), phases(), {3e10, 9e-6}, {2, true, {}}, op),
        solver(makeSolver(type, s, op == Operator::kMatrixFree, keys)),
        test(model, *solver, loading()) {}
  static LoadingSettings loading() {
    LoadingSettings ls;
    ls.strainIncrement = 1e-5;
    ls.maxStrain = 3e-4;
    return ls;
  }
  void write(const std::filesystem::path& file) {
    common::StateArchive::write(file, "lattice test", [&](common::StateArchive& a) {
      a.shape(model.shape());
      model.archive(a);
      a.io("test", test);
      auto s = a.scope("solver");
      solver->archive(a);
    });
  }
  void read(const std::filesystem::path& file) {
    auto a = common::StateArchive::open(file, "lattice test");
    a.shape(model.shape());
    model.archive(a);
    a.io("test", test);
    solver->update(model);
    auto s = a.scope("solver");
    solver->archive(a);
  }
};

bool sameBits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// `keys`: the solver's own, as a scene's `solver:` gives them.
void checkRestart(Operator op, const SolverSettings& s, const std::string& type, int before, const std::string& keys = {}) {
  const Specimen sp = specimen(0.018);
  const TempDir dir;
  const auto file = dir.path() / "state.h5";
  Run a(sp, op, s, type, keys);
  for (int i = 0; i < before; ++i) a.test.step();
  ASSERT_GT(a.model.removedCount(), 0u) << "the checkpoint should come after the first removals";
  a.write(file);
  while (a.test.step()) {
  }
  Run b(sp, op, s, type, keys);
  b.read(file);
  while (b.test.step()) {
  }
  ASSERT_EQ(a.test.curve().size(), b.test.curve().size());
  for (std::size_t i = 0; i < a.test.curve().size(); ++i) {
    const IncrementResult &p = a.test.curve()[i], &q = b.test.curve()[i];
    EXPECT_TRUE(sameBits(p.stress, q.stress)) << "increment " << p.increment << ": " << p.stress << " vs " << q.stress;
    EXPECT_EQ(p.removedTotal, q.removedTotal) << "increment " << p.increment;
    EXPECT_EQ(p.iterations, q.iterations) << "increment " << p.increment;
  }
  EXPECT_GT(a.model.removedCount(), 50u);  // the run went past its peak: the restart covered cracking
  EXPECT_EQ(a.model.removalLog(), b.model.removalLog());
  EXPECT_EQ(a.test.totalIterations(), b.test.totalIterations());
  const Eigen::VectorXd &xa = a.test.state(), &xb = b.test.state();
  ASSERT_EQ(xa.size(), xb.size());
  EXPECT_EQ(std::memcmp(xa.data(), xb.data(), sizeof(double) * static_cast<std::size_t>(xa.size())), 0);

  // Another specimen's checkpoint: refused before anything changes, naming both shapes.
  Run other(specimen(0.015), op, s, type, keys);
  auto c = common::StateArchive::open(file, "lattice test");
  try {
    c.shape(other.model.shape());
    other.model.archive(c);
    ADD_FAILURE() << "another specimen's checkpoint was read";
  } catch (const common::ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("nodes"), std::string::npos) << e.what();
  }
  // The model alone refuses a state of other dimensions too.
  auto d = common::StateArchive::open(file, "lattice test");
  EXPECT_THROW(other.model.archive(d), common::ConfigError);
  EXPECT_EQ(other.model.removedCount(), 0u);
  EXPECT_EQ(other.model.restores(), 0u);
}

}  // namespace

TEST(LatticeCheckpoint, MatrixFreeMixedCgWithCoarseSpaceContinuesFromDiskBitForBit) {
  checkRestart(Operator::kMatrixFree, {}, "cg", 12, "precision: mixed");
}

// Two threads share the rod pass by records: the restart must rebuild the records where they were,
// the removed rods' included (rebuilt from the rod states alone, the last digits differed).
TEST(LatticeCheckpoint, MatrixFreeOnTwoThreadsContinuesFromDiskBitForBit) {
  const int threads = omp_get_max_threads();
  omp_set_num_threads(2);
  checkRestart(Operator::kMatrixFree, {}, "cg", 12, "precision: mixed");
  omp_set_num_threads(threads);
}

TEST(LatticeCheckpoint, AssembledCgContinuesFromDiskBitForBit) { checkRestart(Operator::kAssembled, {}, "cg", 12); }

TEST(LatticeCheckpoint, AveragingContinuesFromDiskBitForBit) {
  SolverSettings s;
  s.tolerance = 1e-5;
  checkRestart(Operator::kAssembled, s, "averaging", 12);
}
