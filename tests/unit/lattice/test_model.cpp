// The lattice model and its solvers: K updated in place on rod removal equals K assembled without the
// rod; cg and averaging reach the same state; the warm start is exact in the linear range; detached
// fragments are held; the fracture test removes the same rods with either solver.
#include <omp.h>

#include <chrono>
#include <span>

#include <gtest/gtest.h>

#include "lattice/fracture_test.hpp"
#include "lattice/model.hpp"
#include "lattice/solver.hpp"
#include "solvers/block_cholesky.hpp"
#include "solvers/coarse_space.hpp"

using namespace lattice;

namespace {

std::array<PhaseProperties, kPhaseCount> phases() {
  return {{{{1.0, 0.6, 0.6}, 2e-4, 2e-3}, {{3.0, 2.1, 2.1}, 1.333e-4, 2e-3}, {{0.7, 0.28, 0.28}, 5e-5, 2e-3}}};
}

Specimen smallSpecimen(double side = 0.015, std::uint64_t seed = 3) {
  Specimen sp = randomSpecimen({Vec3::Zero(), Vec3::Constant(side)}, 0.003, 0.5, seed);
  // One aggregate in the middle so all three phases take part.
  sp.aggregates = {{Vec3::Constant(0.5 * side), 0.3 * side}};
  classifyRods(sp);
  return sp;
}

Model makeModel(const Specimen& sp, bool lateralFixed = true, const std::string& law = "beam",
                Operator op = Operator::kAssembled) {
  return Model(sp, makeRodLaw(law), phases(), {3e10, 9e-6}, {2, lateralFixed, {}}, op);
}

}  // namespace

TEST(LatticeModel, StiffnessIsSymmetric) {
  const Model m = makeModel(smallSpecimen());
  const Model::SparseMatrix& K = m.stiffness();
  const Model::SparseMatrix Kt = K.transpose();
  EXPECT_LT((K - Kt).norm(), 1e-14 * K.norm());
  // A truss lattice drops the rotations: half the unknowns.
  const Model t = makeModel(smallSpecimen(), true, "truss");
  EXPECT_LT(t.freeDofs(), m.freeDofs() / 2 + 1);
}

TEST(LatticeModel, RemovingRodsEqualsAssemblingWithoutThem) {
  const Specimen sp = smallSpecimen();
  Model a = makeModel(sp);
  // Rods of several kinds: inner ones and rods touching the moving face (their load in b changes too).
  std::vector<std::uint32_t> gone;
  for (std::uint32_t r = 0; r < sp.rods.size() && gone.size() < 6; r += 37) gone.push_back(r);
  for (std::uint32_t r = 0; r < sp.rods.size() && gone.size() < 9; ++r)
    if (sp.nodes[sp.rods[r][1]].z() == 0.015 && sp.nodes[sp.rods[r][0]].z() < 0.015) gone.push_back(r);
  ASSERT_EQ(gone.size(), 9u);
  std::sort(gone.begin(), gone.end());
  a.removeRods(gone, Eigen::VectorXd::Zero(static_cast<Eigen::Index>(a.freeDofs())));
  Specimen without = sp;
  without.rods.clear();
  without.phases.clear();
  for (std::uint32_t r = 0; r < sp.rods.size(); ++r)
    if (!std::binary_search(gone.begin(), gone.end(), r)) {
      without.rods.push_back(sp.rods[r]);
      without.phases.push_back(sp.phases[r]);
    }
  const Model b = makeModel(without);
  ASSERT_EQ(a.freeDofs(), b.freeDofs());  // no node lost all its rods
  EXPECT_EQ(a.heldNodes(), 0u);
  const Model::SparseMatrix diff = a.stiffness() - b.stiffness();
  EXPECT_LT(diff.norm(), 1e-13 * b.stiffness().norm());
  EXPECT_LT((a.rhs(1.0) - b.rhs(1.0)).norm(), 1e-13 * b.rhs(1.0).norm());
}

TEST(LatticeSolvers, CgAndAveragingReachTheSameState) {
  const Model m = makeModel(smallSpecimen(0.018));
  const Eigen::VectorXd b = m.rhs(1e-4);
  SolverSettings s;
  s.tolerance = 1e-11;
  Eigen::VectorXd xc = Eigen::VectorXd::Zero(b.size()), xa = xc;
  auto cg = makeSolver("cg", s), avg = makeSolver("averaging", s);
  cg->update(m);
  avg->update(m);
  auto t0 = std::chrono::steady_clock::now();
  const SolveReport rc = cg->solve(b, xc);
  auto t1 = std::chrono::steady_clock::now();
  const SolveReport ra = avg->solve(b, xa);
  auto t2 = std::chrono::steady_clock::now();
  // Both stop at ‖b − Kx‖ ≤ 1e-11 ‖b‖; the states then agree to about κ × 1e-11.
  EXPECT_LT((xc - xa).norm(), 1e-7 * xc.norm());
  std::vector<double> uc, ua;
  m.fullDisplacement(xc, 1e-4, uc);
  m.fullDisplacement(xa, 1e-4, ua);
  EXPECT_NEAR(m.reaction(ua), m.reaction(uc), 1e-8 * std::abs(m.reaction(uc)));
  const double tc = std::chrono::duration<double>(t1 - t0).count(), ta = std::chrono::duration<double>(t2 - t1).count();
  RecordProperty("cg_iterations", rc.iterations);
  RecordProperty("averaging_sweeps", ra.iterations);
  RecordProperty("time_ratio_averaging_over_cg", std::to_string(ta / tc));
  std::printf("%zu dofs: cg %d iterations %.4f s, averaging %d sweeps %.4f s, ratio %.1f\n", m.freeDofs(), rc.iterations, tc,
              ra.iterations, ta, ta / tc);
  EXPECT_GT(ra.iterations, rc.iterations);  // the point of the Krylov solver
}

TEST(LatticeSolvers, WarmStartIsExactInTheLinearRange) {
  Model m = makeModel(smallSpecimen());
  auto cg = makeSolver("cg", {});
  LoadingSettings ls;
  ls.strainIncrement = 1e-6;  // far below the first critical strain
  ls.maxStrain = 3e-6;
  FractureTest test(m, *cg, ls);
  while (test.step()) {
  }
  ASSERT_EQ(test.curve().size(), 3u);
  EXPECT_GT(test.curve()[0].iterations, 10);
  EXPECT_EQ(test.curve()[1].iterations, 0);
  EXPECT_EQ(test.curve()[2].iterations, 0);
  EXPECT_NEAR(test.curve()[2].stress, 3 * test.curve()[0].stress, 1e-7 * test.curve()[2].stress);
  EXPECT_EQ(test.removals().size(), 0u);
}

TEST(LatticeModel, ANodeThatLosesAllItsRodsIsHeld) {
  const Specimen sp = cubicLattice({Vec3::Zero(), Vec3::Constant(0.04)}, 0.01);
  Model m = makeModel(sp);
  auto cg = makeSolver("cg", {});
  cg->update(m);
  Eigen::VectorXd x = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(m.freeDofs()));
  cg->solve(m.rhs(1e-5), x);
  // The centre node (2, 2, 2) and its six rods.
  const std::uint32_t centre = (2 * 5 + 2) * 5 + 2;
  std::vector<std::uint32_t> rods;
  for (std::uint32_t r = 0; r < sp.rods.size(); ++r)
    if (sp.rods[r][0] == centre || sp.rods[r][1] == centre) rods.push_back(r);
  ASSERT_EQ(rods.size(), 6u);
  std::vector<double> before;
  m.fullDisplacement(x, 1e-5, before);
  EXPECT_EQ(m.removeRods(rods, x), 1u);
  cg->update(m);
  cg->solve(m.rhs(1e-5), x);  // singular without holding
  std::vector<double> after;
  m.fullDisplacement(x, 1e-5, after);
  for (int k = 0; k < 6; ++k) EXPECT_NEAR(after[6 * centre + k], before[6 * centre + k], 1e-14);
}

TEST(LatticeSolvers, FractureTestRemovesTheSameRodsWithEitherSolver) {
  const Specimen sp = smallSpecimen(0.012, 5);
  LoadingSettings ls;
  ls.strainIncrement = 2e-5;
  ls.maxStrain = 1.2e-4;
  SolverSettings s;
  s.tolerance = 1e-10;
  std::vector<std::vector<RemovalRecord>> removals;
  std::vector<std::vector<IncrementResult>> curves;
  for (const char* name : {"cg", "averaging"}) {
    Model m = makeModel(sp);
    auto solver = makeSolver(name, s);
    FractureTest test(m, *solver, ls);
    while (test.step()) {
    }
    removals.push_back(test.removals());
    curves.push_back(test.curve());
  }
  ASSERT_GT(removals[0].size(), 5u);
  ASSERT_EQ(removals[0].size(), removals[1].size());
  for (std::size_t i = 0; i < removals[0].size(); ++i) {
    EXPECT_EQ(removals[0][i].rod, removals[1][i].rod);
    EXPECT_EQ(removals[0][i].increment, removals[1][i].increment);
  }
  for (std::size_t i = 0; i < curves[0].size(); ++i)
    EXPECT_NEAR(curves[1][i].stress, curves[0][i].stress, 1e-7 * std::abs(curves[0][i].stress));
}

// The matrix-free operator is the assembled one computed rod by rod: the same K x, the same node blocks,
// the same b, before and after removals that detach a fragment; and the same fracture run.
// A block of 2 × 2 × 2 inner nodes cut out of a cubic lattice is held as one piece, all 8 nodes; with one
// of the cut rods left it stays attached and nothing is held.
TEST(LatticeModel, ACutOutBlockIsHeldWhole) {
  const Specimen sp = cubicLattice({Vec3::Zero(), Vec3::Constant(0.05)}, 0.01);  // 6 nodes a side
  auto inBlock = [&](std::uint32_t n) {
    const Vec3& p = sp.nodes[n];
    return (p.array() > 0.015).all() && (p.array() < 0.035).all();
  };
  std::vector<std::uint32_t> cut;
  for (std::uint32_t r = 0; r < sp.rods.size(); ++r)
    if (inBlock(sp.rods[r][0]) != inBlock(sp.rods[r][1])) cut.push_back(r);
  ASSERT_EQ(cut.size(), 24u);  // 6 faces × 4 nodes
  for (const Operator op : {Operator::kAssembled, Operator::kMatrixFree}) {
    Model m = makeModel(sp, true, "beam", op);
    const Eigen::VectorXd x = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(m.freeDofs()));
    EXPECT_EQ(m.removeRods(std::span(cut).first(23), x), 0u);
    EXPECT_EQ(m.removeRods(std::span(cut).last(1), x), 8u);
    for (std::uint32_t n = 0; n < sp.nodes.size(); ++n) EXPECT_EQ(m.held(n), inBlock(n)) << n;
  }
}

// addRodProducts gives what K x loses when the rods go.
TEST(LatticeModel, RodProductsAreWhatRemovalTakesFromKx) {
  const Specimen sp = smallSpecimen();
  for (const Operator op : {Operator::kAssembled, Operator::kMatrixFree}) {
    Model m = makeModel(sp, false, "beam", op);
    const Eigen::VectorXd x = Eigen::VectorXd::Random(static_cast<Eigen::Index>(m.freeDofs()));
    std::vector<std::uint32_t> gone;
    for (std::uint32_t r = 0; r < sp.rods.size(); r += 11) gone.push_back(r);
    Eigen::VectorXd before, after;
    m.apply(x, before);
    m.removeRods(gone, x);
    ASSERT_EQ(m.heldNodes(), 0u);
    m.apply(x, after);
    Eigen::VectorXd lost = Eigen::VectorXd::Zero(x.size());
    m.addRodProducts(gone, x, lost);
    EXPECT_GT(lost.norm(), 1e-3 * before.norm());
    EXPECT_LT((before - after - lost).norm(), 1e-12 * before.norm());
  }
}

TEST(LatticeModel, MatrixFreeEqualsAssembled) {
  for (const char* law : {"beam", "truss"}) {
    const Specimen sp = smallSpecimen();
    Model a = makeModel(sp, false, law), f = makeModel(sp, false, law, Operator::kMatrixFree);
    ASSERT_EQ(a.freeDofs(), f.freeDofs());
    EXPECT_EQ(f.nonZeros(), 0);
    const Eigen::VectorXd x = Eigen::VectorXd::Random(static_cast<Eigen::Index>(a.freeDofs()));
    auto compare = [&](const char* when) {
      Eigen::VectorXd ya, yf;
      a.apply(x, ya);
      f.apply(x, yf);
      EXPECT_LT((ya - yf).norm(), 1e-12 * ya.norm()) << law << " " << when;
      EXPECT_LT((a.rhs(1.0) - f.rhs(1.0)).norm(), 1e-12 * a.rhs(1.0).norm()) << law << " " << when;
      // The two storages hold the same K (the matrix-free one builds it from its rods).
      EXPECT_LT((a.stiffness() - f.stiffness()).norm(), 1e-12 * a.stiffness().norm()) << law << " " << when;
      const double scale = a.diagonalBlock(0).norm() + a.diagonalBlock(1).norm();
      for (std::size_t blk = 0; blk < a.blockStart().size() - 1; ++blk)
        EXPECT_LT((a.diagonalBlock(blk) - f.diagonalBlock(blk)).norm(), 1e-12 * scale) << law << " " << when << " " << blk;
    };
    compare("intact");
    const Model::Checkpoint ca = a.checkpoint(), cf = f.checkpoint();
    // All rods of a corner node and of an inner node: both become held one-node fragments (the corner
    // too, although it sits on a support: without rods its free dofs have no stiffness).
    std::uint32_t inner = 0;
    while ((sp.nodes[inner].array() <= 0.001).any() || (sp.nodes[inner].array() >= 0.014).any()) ++inner;
    std::vector<std::uint32_t> gone;
    for (std::uint32_t r = 0; r < sp.rods.size(); ++r)
      if (sp.rods[r][0] == 5 || sp.rods[r][1] == 5 || sp.rods[r][0] == inner || sp.rods[r][1] == inner || r % 41 == 0)
        gone.push_back(r);
    EXPECT_EQ(a.removeRods(gone, x), 2u);
    EXPECT_EQ(f.removeRods(gone, x), a.heldNodes());
    compare("after removals");
    a.restore(ca);
    f.restore(cf);
    EXPECT_EQ(f.heldNodes(), 0u);
    compare("restored");
  }
}

namespace {
// The fracture run of the 15 mm specimen to ε = 2e-4 in steps of 2e-5 with cg.
struct FractureRun {
  std::vector<RemovalRecord> removals;
  std::vector<IncrementResult> curve;
  double peak = 0.0;
};
FractureRun fractureRun(const Specimen& sp, Operator op, const SolverSettings& s, const std::string& precision = "double") {
  LoadingSettings ls;
  ls.strainIncrement = 2e-5;
  ls.maxStrain = 2e-4;
  Model m = makeModel(sp, true, "beam", op);
  auto solver = makeSolver("cg", s, op == Operator::kMatrixFree, "precision: " + precision);
  FractureTest test(m, *solver, ls);
  while (test.step()) {
  }
  return {test.removals(), test.curve(), test.curve()[static_cast<std::size_t>(test.peakIndex())].stress};
}
}  // namespace

TEST(LatticeSolvers, MatrixFreeFractureRunEqualsAssembled) {
  const Specimen sp = smallSpecimen(0.015, 7);
  SolverSettings s;
  s.tolerance = 1e-10;
  const FractureRun a = fractureRun(sp, Operator::kAssembled, s), f = fractureRun(sp, Operator::kMatrixFree, s);
  ASSERT_GT(a.removals.size(), 10u);
  ASSERT_EQ(a.removals.size(), f.removals.size());
  for (std::size_t i = 0; i < a.removals.size(); ++i) EXPECT_EQ(a.removals[i].rod, f.removals[i].rod);
  EXPECT_NEAR(f.peak, a.peak, 1e-8 * a.peak);
}

// The single-precision product is K x with the rods' data rounded to float, also after removals (its
// copy of the rods loses their springs with the double one) and with held fragments; in the padded
// space it is 0 at the dofs that are not free, and that space holds the free dofs one to one.
TEST(LatticeModel, SinglePrecisionProductIsTheRoundedOne) {
  const Specimen sp = smallSpecimen();
  Model m = makeModel(sp, false, "beam", Operator::kMatrixFree);
  const Eigen::VectorXd x = Eigen::VectorXd::Random(static_cast<Eigen::Index>(m.freeDofs()));
  Eigen::VectorXf x6;
  m.toPadded(x, 2.0, x6);
  ASSERT_EQ(x6.size(), m.paddedSize());
  EXPECT_NEAR(x6.cast<double>().norm(), 2.0 * x.norm(), 1e-6 * x.norm());
  auto compare = [&](const char* when) {
    Eigen::VectorXd y, ys = Eigen::VectorXd::Zero(x.size());
    Eigen::VectorXf y6;
    m.apply(x, y);
    m.applySingle(x6, y6);
    m.addFromPadded(y6, 0.5, ys);
    const double err = (ys - y).norm() / y.norm();
    EXPECT_LT(err, 1e-5) << when;
    EXPECT_GT(err, 1e-9) << when;  // really float
    EXPECT_NEAR(y6.cast<double>().norm(), 2.0 * ys.norm(), 1e-5 * ys.norm()) << when << ": only the free dofs are not 0";
  };
  compare("intact");
  std::vector<std::uint32_t> gone;
  for (std::uint32_t r = 0; r < sp.rods.size(); r += 7) gone.push_back(r);
  m.removeRods(gone, x);
  compare("after removals");
  // Every rod of one node: it is held, its rows the original diagonal.
  const std::uint32_t n = m.blockNodes()[m.blockNodes().size() / 2];
  std::vector<std::uint32_t> around;
  for (std::uint32_t r = 0; r < sp.rods.size(); ++r)
    if (m.active(r) && (sp.rods[r][0] == n || sp.rods[r][1] == n)) around.push_back(r);
  ASSERT_EQ(m.removeRods(around, x), 1u);
  compare("with a held node");
}

// Mixed precision (float inner solves, refined in double) stops on the same double residual test:
// the same rods go in the same order and the curve agrees to the tolerance.
TEST(LatticeSolvers, MixedPrecisionFractureRunEqualsDouble) {
  const Specimen sp = smallSpecimen(0.015, 7);
  SolverSettings s;
  s.tolerance = 1e-9;
  const FractureRun d = fractureRun(sp, Operator::kMatrixFree, s);
  const FractureRun m = fractureRun(sp, Operator::kMatrixFree, s, "mixed");
  ASSERT_GT(d.removals.size(), 10u);
  ASSERT_EQ(d.removals.size(), m.removals.size());
  for (std::size_t i = 0; i < d.removals.size(); ++i) EXPECT_EQ(d.removals[i].rod, m.removals[i].rod);
  ASSERT_EQ(d.curve.size(), m.curve.size());
  for (std::size_t i = 0; i < d.curve.size(); ++i)
    EXPECT_NEAR(m.curve[i].stress, d.curve[i].stress, 1e-7 * std::abs(d.curve[i].stress)) << i;
}

// cg's coarse stiffness, kept up to date rod by rod, equals the one built from scratch after the
// removals, for either operator.
TEST(LatticeSolvers, CoarseStiffnessUpdatedPerRodEqualsRebuilt) {
  for (Operator op : {Operator::kAssembled, Operator::kMatrixFree}) {
    const Specimen sp = smallSpecimen(0.018, 2);
    Model m = makeModel(sp, true, "beam", op);
    CoarseSpace incremental;
    incremental.build(m, 0.006);
    std::vector<std::uint32_t> gone;
    for (std::uint32_t r = 3; r < sp.rods.size(); r += 29) gone.push_back(r);
    m.removeRods(gone, Eigen::VectorXd::Zero(static_cast<Eigen::Index>(m.freeDofs())));
    ASSERT_EQ(m.heldNodes(), 0u);
    incremental.update(m);
    CoarseSpace fresh;
    fresh.build(m, 0.006);
    const Eigen::SparseMatrix<double> diff = incremental.matrix() - fresh.matrix();
    EXPECT_LT(diff.norm(), 1e-10 * fresh.matrix().norm());  // round-off of ~600 subtractions
    EXPECT_EQ(fresh.size(), 6 * 27);  // 3 × 3 × 3 cells of 6 mm
    // The inner solves' coarse solve (the factor rounded to float) is A_c⁻¹ to float precision.
    const Eigen::VectorXd rc = Eigen::VectorXd::Random(fresh.size());
    Eigen::VectorXd yc = rc;
    fresh.solve(yc);
    const double err = (fresh.matrix() * yc - rc).norm() / rc.norm();
    EXPECT_LT(err, 1e-4);
    EXPECT_GT(err, 1e-12);  // really rounded
  }
}

namespace {
// K x of m on `threads` OpenMP threads.
Eigen::VectorXd productOn(int threads, const Model& m, const Eigen::VectorXd& x) {
  const int before = omp_get_max_threads();
  omp_set_num_threads(threads);
  Eigen::VectorXd y;
  m.apply(x, y);
  omp_set_num_threads(before);
  return y;
}
}  // namespace

// The matrix-free rod pass on 1, 2, 3 and 5 threads equals the assembled K (the rods of each thread's
// share summed into its own vector).
TEST(LatticeModel, RodProductOnAnyThreadCountEqualsAssembled) {
  const Specimen sp = smallSpecimen();
  const Model a = makeModel(sp, false), f = makeModel(sp, false, "beam", Operator::kMatrixFree);
  const Eigen::VectorXd x = Eigen::VectorXd::Random(static_cast<Eigen::Index>(a.freeDofs()));
  const Eigen::VectorXd ref = a.stiffness() * x;
  for (int threads : {1, 2, 3, 5}) EXPECT_LT((productOn(threads, f, x) - ref).norm(), 1e-13 * ref.norm()) << threads << " threads";
}

// K x of the assembled blocks: the one-thread pass (each upper block used twice) and the threaded
// gather of the lower blocks give the same product, and both equal the Eigen matrix built from them.
TEST(LatticeModel, BlockProductOnOneAndTwoThreadsAgree) {
  const Model m = makeModel(smallSpecimen(), false);
  const Eigen::VectorXd x = Eigen::VectorXd::Random(static_cast<Eigen::Index>(m.freeDofs()));
  const Eigen::VectorXd y1 = productOn(1, m, x), y2 = productOn(2, m, x);
  const Eigen::VectorXd ref = m.stiffness() * x;
  EXPECT_LT((y1 - ref).norm(), 1e-13 * ref.norm());
  EXPECT_LT((y2 - ref).norm(), 1e-13 * ref.norm());
  for (std::size_t blk = 0; blk + 1 < m.blockStart().size(); blk += 5) {
    const int first = static_cast<int>(m.blockStart()[blk]);
    const int n = static_cast<int>(m.blockStart()[blk + 1]) - first;
    const Model::Vec6 yb = m.blockProduct(blk, x);
    double diff = 0.0;
    for (int i = 0; i < n; ++i) diff = std::max(diff, std::abs(yb[i] - ref[first + i]));
    EXPECT_LT(diff, 1e-12 * ref.norm());
  }
}

// The block factorisation solves a sparse SPD matrix of 6 × 6 blocks (a 3D grid of cells coupled to
// their 26 neighbours, as the coarse level's) to round-off, and to float precision from its float copy;
// an indefinite matrix is refused.
TEST(LatticeSolvers, BlockCholeskySolvesABlockSparseMatrix) {
  constexpr int n = 5, nb = n * n * n;
  std::vector<std::vector<int>> neighbours(nb);
  std::vector<Eigen::Triplet<double>> t;
  std::srand(4);
  auto cell = [&](int i, int j, int k) { return (k * n + j) * n + i; };
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i)
        for (int dk = -1; dk <= 1; ++dk)
          for (int dj = -1; dj <= 1; ++dj)
            for (int di = -1; di <= 1; ++di) {
              const int a = cell(i, j, k);
              if (i + di < 0 || i + di >= n || j + dj < 0 || j + dj >= n || k + dk < 0 || k + dk >= n) continue;
              const int b = cell(i + di, j + dj, k + dk);
              if (b <= a) continue;
              neighbours[static_cast<std::size_t>(a)].push_back(b);
              neighbours[static_cast<std::size_t>(b)].push_back(a);
              const Eigen::Matrix<double, 6, 6> m = Eigen::Matrix<double, 6, 6>::Random();
              for (int r = 0; r < 6; ++r)
                for (int c = 0; c < 6; ++c) {
                  t.emplace_back(6 * a + r, 6 * b + c, m(r, c));
                  t.emplace_back(6 * b + c, 6 * a + r, m(r, c));
                }
            }
  for (int a = 0; a < nb; ++a)
    for (int r = 0; r < 6; ++r) t.emplace_back(6 * a + r, 6 * a + r, 200.0);  // diagonally dominant
  Eigen::SparseMatrix<double> A(6 * nb, 6 * nb);
  A.setFromTriplets(t.begin(), t.end());
  BlockCholesky f;
  f.analyze(neighbours);
  ASSERT_TRUE(f.factorize(A));
  EXPECT_GT(f.offDiagonalBlocks(), 13u * nb / 2);  // at least A's blocks, plus fill
  const Eigen::VectorXd b = Eigen::VectorXd::Random(6 * nb);
  Eigen::VectorXd x = b, xs = b;
  f.solve(x);
  f.solveSingle(xs);
  EXPECT_LT((A * x - b).norm(), 1e-13 * b.norm() * 200);
  const double err = (A * xs - b).norm() / b.norm();
  EXPECT_LT(err, 1e-5);
  EXPECT_GT(err, 1e-12);
  Eigen::SparseMatrix<double> indefinite = A;
  indefinite.coeffRef(6 * 7 + 2, 6 * 7 + 2) = -500.0;
  EXPECT_FALSE(f.factorize(indefinite));
}

// Mixed-precision cg updates its residual from the removed rods only for the model and x of its last
// solve: given another model of the same size and that same x, it still reaches that model's equilibrium.
TEST(LatticeSolvers, MixedCgResidualUpdateOnlyForItsLastModel) {
  const Specimen sp = smallSpecimen();
  Specimen plain = sp;  // the same lattice without the aggregate: another equilibrium
  for (auto& p : plain.phases) p = Phase::kMatrix;
  Model a = makeModel(sp, true, "beam", Operator::kMatrixFree), b = makeModel(plain, true, "beam", Operator::kMatrixFree);
  ASSERT_EQ(a.freeDofs(), b.freeDofs());
  SolverSettings s;
  s.tolerance = 1e-9;
  auto cg = makeSolver("cg", s, true, "precision: mixed");
  cg->update(a);
  Eigen::VectorXd x = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(a.freeDofs()));
  cg->solve(a.rhs(1e-5), x);
  cg->update(b);
  const SolveReport r = cg->solve(b.rhs(1e-5), x);
  EXPECT_GT(r.iterations, 0);
  Eigen::VectorXd Kx;
  b.apply(x, Kx);
  EXPECT_LT((b.rhs(1e-5) - Kx).norm(), 1e-8 * b.rhs(1e-5).norm());
}
