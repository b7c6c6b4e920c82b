// Contract tests over every registered acceleration (CONTRIBUTING.md): each converges on a linear fixed-point
// problem x = A x + b with a known solution, including one where the plain iteration diverges.
#include <filesystem>
#include <map>
#include <random>

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include "common/config.hpp"
#include "common/errors.hpp"
#include "common/state_archive.hpp"
#include "cosim/acceleration.hpp"
#include "temp_dir.hpp"

namespace {

struct Problem {
  Eigen::MatrixXd A;
  Eigen::VectorXd b, solution;
};

// A = Q diag(λ) Qᵀ with λ from −1.5 (the plain iteration diverges) to 0.9 (it is slow).
Problem linearProblem(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  Eigen::MatrixXd M(n, n);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) M(i, j) = u(rng);
  const Eigen::MatrixXd Q = Eigen::HouseholderQR<Eigen::MatrixXd>(M).householderQ();
  Eigen::VectorXd lambda = Eigen::VectorXd::LinSpaced(n, -1.5, 0.9);
  Problem p;
  p.A = Q * lambda.asDiagonal() * Q.transpose();
  p.b = Eigen::VectorXd::NullaryExpr(n, [&] { return u(rng); });
  p.solution = (Eigen::MatrixXd::Identity(n, n) - p.A).lu().solve(p.b);
  return p;
}

// Iterates until ‖r‖ < 1e-10 ‖b‖; returns the iterations (or -1).
int solve(cosim::Acceleration& acc, const Problem& p, Eigen::VectorXd& x, int maxIterations) {
  Eigen::VectorXd next(x.size());
  for (int k = 1; k <= maxIterations; ++k) {
    const Eigen::VectorXd hx = p.A * x + p.b;
    if ((hx - x).norm() < 1e-10 * p.b.norm()) {
      acc.converged();
      return k;
    }
    acc.next(std::span<const double>(x.data(), static_cast<std::size_t>(x.size())),
             std::span<const double>(hx.data(), static_cast<std::size_t>(hx.size())),
             std::span<double>(next.data(), static_cast<std::size_t>(next.size())));
    x = next;
  }
  return -1;
}

class EveryAcceleration : public ::testing::TestWithParam<std::string> {};

}  // namespace

TEST_P(EveryAcceleration, ConvergesOnALinearProblemWherePlainIterationDiverges) {
  const Problem p = linearProblem(10, 3);
  // constant: |1 − ω(1 − λ)| < 1 for every λ ∈ [−1.5, 0.9] with ω = 0.4
  auto acc = cosim::makeAcceleration(GetParam(), 0.4);
  Eigen::VectorXd x = Eigen::VectorXd::Zero(10);
  const int iterations = solve(*acc, p, x, 2000);
  ASSERT_GT(iterations, 0) << GetParam() << " did not converge";
  EXPECT_NEAR((x - p.solution).norm(), 0.0, 1e-8 * p.solution.norm()) << GetParam();
  if (GetParam() == "iqn_ils") {
    EXPECT_LE(iterations, 10 + 2);  // a secant method: exact after n updates
  }
  RecordProperty("iterations", iterations);
}

// Two fields of other units stacked (the parallel scheme's forces in N and displacements in m): y = D x
// with D = diag(1e6 … 1e6, 1e-6 … 1e-6). Weighted by D⁻¹ (setWeights), every method iterates on y as it
// does on x: the same iterates, scaled, so the same count; the weights enter only its norms.
TEST_P(EveryAcceleration, WeightsMakeItBlindToTheUnitsOfEachField) {
  const Problem p = linearProblem(10, 3);
  Eigen::VectorXd d(10);
  d << 1e6, 1e6, 1e6, 1e6, 1e6, 1e-6, 1e-6, 1e-6, 1e-6, 1e-6;
  Problem scaled;
  scaled.A = d.asDiagonal() * p.A * d.cwiseInverse().asDiagonal();
  scaled.b = d.cwiseProduct(p.b);
  auto plain = cosim::makeAcceleration(GetParam(), 0.4);
  Eigen::VectorXd x = Eigen::VectorXd::Zero(10);
  const int reference = solve(*plain, p, x, 2000);
  ASSERT_GT(reference, 0);

  auto weighted = cosim::makeAcceleration(GetParam(), 0.4);
  const Eigen::VectorXd w = d.cwiseInverse();
  Eigen::VectorXd y = Eigen::VectorXd::Zero(10), next(10);
  int iterations = -1;
  for (int k = 1; k <= 2000; ++k) {
    const Eigen::VectorXd hy = scaled.A * y + scaled.b;
    if (w.cwiseProduct(hy - y).norm() < 1e-10 * p.b.norm()) {
      iterations = k;
      break;
    }
    weighted->setWeights(std::span<const double>(w.data(), 10));
    weighted->next(std::span<const double>(y.data(), 10), std::span<const double>(hy.data(), 10),
                   std::span<double>(next.data(), 10));
    y = next;
  }
  ASSERT_GT(iterations, 0) << GetParam();
  EXPECT_NEAR(iterations, reference, 1) << GetParam();
  EXPECT_NEAR((w.cwiseProduct(y) - p.solution).norm(), 0.0, 1e-8 * p.solution.norm()) << GetParam();
}

INSTANTIATE_TEST_SUITE_P(Accelerations, EveryAcceleration, ::testing::ValuesIn(cosim::accelerationNames()));

// Reuse: a second window of the same operator with a new right-hand side needs far fewer IQN-ILS
// iterations, because the columns of the first window are kept.
TEST(IqnIls, ReusedWindowsSpeedUpTheNextWindow) {
  Problem p = linearProblem(10, 3);
  auto acc = cosim::makeAcceleration("iqn_ils");
  Eigen::VectorXd x = Eigen::VectorXd::Zero(10);
  const int first = solve(*acc, p, x, 200);
  p.b *= 1.3;
  p.b(0) += 0.2;
  const int second = solve(*acc, p, x, 200);
  ASSERT_GT(first, 0);
  ASSERT_GT(second, 0);
  EXPECT_LT(second, first / 2) << "first " << first << ", second " << second;
}

// Adaptive windows: a reused window models the interface over its own length, so a window of another
// length does not use it (it starts like a first window: the same iterations as a fresh accelerator),
// and a later window of the first length still does; abandon() drops only the void window's columns.
TEST(IqnIls, ReusesOnlyWindowsOfTheSameLength) {
  Problem p = linearProblem(10, 3);
  auto acc = cosim::makeAcceleration("iqn_ils");
  acc->setWindowSize(1e-4);
  Eigen::VectorXd x = Eigen::VectorXd::Zero(10);
  ASSERT_GT(solve(*acc, p, x, 200), 0);
  p.b *= 1.3;
  p.b(0) += 0.2;
  const Eigen::VectorXd start = x;
  auto fresh = cosim::makeAcceleration("iqn_ils");
  Eigen::VectorXd y = start;
  const int alone = solve(*fresh, p, y, 200);
  acc->setWindowSize(5e-5);
  const int halved = solve(*acc, p, x, 200);
  EXPECT_EQ(halved, alone);
  // A void window (abandoned) leaves the reused windows in place for the next window of their length.
  acc->setWindowSize(1e-4);
  Eigen::VectorXd z = start, next(10);
  const Eigen::VectorXd hz = p.A * z + p.b;
  acc->next(std::span<const double>(z.data(), 10), std::span<const double>(hz.data(), 10), std::span<double>(next.data(), 10));
  acc->abandon();
  p.b(1) -= 0.1;
  const int reused = solve(*acc, p, z, 200);
  ASSERT_GT(reused, 0);
  EXPECT_LT(reused, alone / 2) << "reused " << reused << ", alone " << alone;
}

// A window that ran out of iterations leaves nothing behind: after unconverged() the next window starts
// like the very first one (one relaxation step, x + ω r), not from the columns that failed — the same
// step a fresh accelerator takes. After converged() the kept columns change that first step.
TEST(IqnIls, AnUnconvergedWindowIsNotReused) {
  Problem p = linearProblem(10, 3);
  const double relaxation = 0.3;
  auto firstStep = [&](cosim::Acceleration& acc, const Eigen::VectorXd& x) {
    const Eigen::VectorXd hx = p.A * x + p.b;
    Eigen::VectorXd next(x.size());
    acc.next(std::span<const double>(x.data(), 10), std::span<const double>(hx.data(), 10), std::span<double>(next.data(), 10));
    return next;
  };
  for (bool windowConverged : {false, true}) {
    auto acc = cosim::makeAcceleration("iqn_ils", relaxation);
    Eigen::VectorXd x = Eigen::VectorXd::Zero(10);
    for (int k = 0; k < 4; ++k) x = firstStep(*acc, x);  // a window stopped after 4 iterations
    if (windowConverged) acc->converged();
    else acc->unconverged();
    const Eigen::VectorXd next = firstStep(*acc, x);
    const Eigen::VectorXd relaxed = x + relaxation * (p.A * x + p.b - x);
    if (windowConverged) EXPECT_GT((next - relaxed).norm(), 1e-6 * relaxed.norm());
    else EXPECT_NEAR((next - relaxed).norm(), 0.0, 1e-14 * relaxed.norm());
  }
}

// A contact-like interface: window t's fixed point is x = P_t (A x + b_t), where P_t keeps the entries
// "in contact" (a band that moves across the interface, so entries join and leave it) and zeroes the
// others exactly, as a DEM gives no force to a node out of contact. The plain iteration diverges (A has
// eigenvalues down to −1.5). Under each active_set mode every window converges within a bound, and under
// `mask` an entry out of contact stays exactly zero (no column learnt in contact puts a force back on it).
TEST(IqnIls, ConvergesWhileTheActiveSetChanges) {
  const int n = 12;
  const Problem p = linearProblem(n, 5);
  std::map<std::string, int> total;
  for (const std::string name : {"keep", "mask", "drop"}) {
    // Built as a scene gives it, so that the keys are seen to reach the method.
    const auto spec = cosim::readAcceleration(common::Config::parse(
        "type: iqn_ils\nrelaxation: 0.3\nreused_windows: 4\nactive_set: " + name));
    EXPECT_EQ(spec.relaxation, 0.3);
    auto acc = spec.build();
    Eigen::VectorXd x = Eigen::VectorXd::Zero(n), next(n);
    for (int t = 0; t < 30; ++t) {
      Eigen::VectorXd mask = Eigen::VectorXd::Zero(n);
      for (int i = t / 3; i < std::min(n, t / 3 + 5); ++i) mask(i) = 1.0;
      const Eigen::VectorXd b = p.b * (1.0 + 0.02 * t);
      int k = 1;
      for (; k <= 60; ++k) {
        const Eigen::VectorXd hx = mask.cwiseProduct(p.A * x + b);
        ASSERT_TRUE(hx.allFinite()) << name << ", window " << t;
        if ((hx - x).norm() < 1e-10 * b.norm()) break;
        acc->next(std::span<const double>(x.data(), n), std::span<const double>(hx.data(), n),
                  std::span<double>(next.data(), n));
        x = next;
        if (name == "mask") {
          for (int i = 0; i < n; ++i) {
            if (mask(i) == 0.0) {
              ASSERT_EQ(x(i), 0.0) << name << ", window " << t << ", entry " << i;
            }
          }
        }
      }
      ASSERT_LE(k, 30) << name << ": window " << t << " took " << k << " iterations";
      acc->converged();
      total[name] += k;
    }
  }
  // Reusing what stays valid pays against forgetting at every change.
  EXPECT_LT(total["mask"], total["drop"]) << "mask " << total["mask"] << ", drop " << total["drop"];
  EXPECT_LT(total["keep"], total["drop"]) << "keep " << total["keep"] << ", drop " << total["drop"];
}

// Restart: an acceleration written to disk between windows and read into a new one continues exactly
// as the original (IQN-ILS: its reused columns; the others carry nothing from window to window).
TEST_P(EveryAcceleration, ContinuesFromDiskBitForBit) {
  const Problem p = linearProblem(30, 7);
  auto original = cosim::makeAcceleration(GetParam(), 0.4);  // constant converges too (see above)
  Eigen::VectorXd x = Eigen::VectorXd::Zero(30);
  for (int w = 0; w < 3; ++w) {  // three windows, each a shifted right-hand side
    Problem pw = p;
    pw.b = p.b * (1.0 + 0.1 * w);
    ASSERT_GT(solve(*original, pw, x, 2000), 0);
  }
  const TempDir dir;
  const auto file = dir.path() / (GetParam() + ".h5");
  {
    auto a = common::StateArchive::create(file, "test");
    original->archive(a);
    a.commit();
  }
  auto restarted = cosim::makeAcceleration(GetParam(), 0.4);
  auto a = common::StateArchive::open(file, "test");
  restarted->archive(a);
  Problem next = p;
  next.b = p.b * 1.3;
  Eigen::VectorXd x1 = x, x2 = x;
  const int k1 = solve(*original, next, x1, 2000), k2 = solve(*restarted, next, x2, 2000);
  EXPECT_EQ(k1, k2);
  ASSERT_GT(k1, 0);
  for (Eigen::Index i = 0; i < x1.size(); ++i) ASSERT_EQ(x1(i), x2(i)) << i;
}

// The QR filters of IQN-ILS (cosim/qr_filter.hpp): both drop a column made exactly dependent on the
// others and keep the rest, with V = Q R; they differ on a column that is short but new: qr2 compares
// its orthogonal part with its own length (kept), qr1 |R_ii| with ‖R‖_F (dropped).
TEST(QrFilter, DropsADependentColumnAndFactorisesTheRest) {
  Eigen::MatrixXd V(5, 5);
  V.col(0) << 1, 2, 0, 1, 3;
  V.col(1) << 0, 1, 1, 4, 1;
  V.col(2) = V.col(0) - 2.0 * V.col(1);  // exactly dependent
  V.col(3) << 2, 0, 1, 0, 1;
  V.col(4) << 1e-6, 0, 0, 0, 0;          // short, not dependent
  const auto column = [&](std::size_t i, Eigen::VectorXd& v) { v = V.col(static_cast<Eigen::Index>(i)); };
  for (const char* name : {"qr1", "qr2"}) {
    Eigen::MatrixXd Q, R;
    const auto kept = cosim::filteredQr(4, 5, column, cosim::qrFilterNamed(name), 1e-4, Q, R);
    ASSERT_EQ(kept, (std::vector<std::size_t>{0, 1, 3})) << name;
    Eigen::MatrixXd Vk(5, 3);
    for (int j = 0; j < 3; ++j) Vk.col(j) = V.col(static_cast<Eigen::Index>(kept[static_cast<std::size_t>(j)]));
    const Eigen::MatrixXd Qk = Q.leftCols(3);
    EXPECT_LT((Qk * R - Vk).norm(), 1e-13 * Vk.norm()) << name;
    EXPECT_LT((Qk.transpose() * Qk - Eigen::MatrixXd::Identity(3, 3)).norm(), 1e-13) << name;
  }
  Eigen::MatrixXd Q, R;
  EXPECT_EQ(cosim::filteredQr(5, 5, column, cosim::QrFilter::kQr2, 1e-4, Q, R), (std::vector<std::size_t>{0, 1, 3, 4}));
  EXPECT_EQ(cosim::filteredQr(5, 5, column, cosim::QrFilter::kQr1, 1e-4, Q, R), (std::vector<std::size_t>{0, 1, 3}));
}

// The scene keys of an acceleration: its type and relaxation (what active_set does is
// ConvergesWhileTheActiveSetChanges, read from the scene there); a name that is not one of the three is
// a located error that lists them.
TEST(AccelerationKeys, AreReadFromTheScene) {
  const auto spec = cosim::readAcceleration(common::Config::parse("type: aitken\nrelaxation: 0.7"));
  EXPECT_EQ(spec.type, "aitken");
  EXPECT_EQ(spec.relaxation, 0.7);
  EXPECT_EQ(spec.build()->name(), "aitken");
  EXPECT_EQ(cosim::defaultAcceleration().build()->name(), "iqn_ils");  // no section
  try {
    cosim::readAcceleration(common::Config::parse("type: iqn_ils\nactive_set: masks"));
    ADD_FAILURE() << "active_set: masks was accepted";
  } catch (const common::ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("mask"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("active_set"), std::string::npos) << e.what();
  }
}
