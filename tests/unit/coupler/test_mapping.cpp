// Contract tests over every registered mapping (CONTRIBUTING.md): a consistent map reproduces a linear field
// exactly, a conservative map preserves the total force and moment to round-off.
#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>

#include <gtest/gtest.h>

#include "cosim/mapping.hpp"

using cosim::InterfaceMesh;
using cosim::Vec3;

namespace {

// The unit square in the plane z = 0.3 x − 0.2 y (tilted), nx × ny cells, interior nodes jittered.
InterfaceMesh square(int nx, int ny, double jitter, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-jitter, jitter);
  InterfaceMesh m;
  for (int j = 0; j <= ny; ++j)
    for (int i = 0; i <= nx; ++i) {
      double x = static_cast<double>(i) / nx, y = static_cast<double>(j) / ny;
      if (i > 0 && i < nx && j > 0 && j < ny) x += u(rng) / nx, y += u(rng) / ny;
      m.nodes.emplace_back(x, y, 0.3 * x - 0.2 * y);
    }
  auto id = [&](int i, int j) { return static_cast<std::uint32_t>(j * (nx + 1) + i); };
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      m.triangles.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
      m.triangles.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
    }
  return m;
}

// The box [0, 1] × [0, 2] × [0, 0.5] in n × 2n × n cubes of six tetrahedra each (Kuhn's split: conforming),
// interior nodes jittered.
InterfaceMesh box(int n, double jitter, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-jitter, jitter);
  const int nx = n, ny = 2 * n, nz = n;
  const double h = 1.0 / n;
  InterfaceMesh m;
  for (int k = 0; k <= nz; ++k)
    for (int j = 0; j <= ny; ++j)
      for (int i = 0; i <= nx; ++i) {
        Vec3 x(i * h, j * h, 0.5 * k * h);
        if (i > 0 && i < nx && j > 0 && j < ny && k > 0 && k < nz) x += h * Vec3(u(rng), u(rng), 0.5 * u(rng));
        m.nodes.push_back(x);
      }
  auto id = [&](int i, int j, int k) { return static_cast<std::uint32_t>((k * (ny + 1) + j) * (nx + 1) + i); };
  const int perm[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i)
        for (const auto& p : perm) {  // the path from corner (0,0,0) to (1,1,1) one axis at a time
          int c[3] = {i, j, k};
          std::array<std::uint32_t, 4> t{};
          t[0] = id(c[0], c[1], c[2]);
          for (int s = 0; s < 3; ++s) ++c[p[s]], t[static_cast<std::size_t>(s) + 1] = id(c[0], c[1], c[2]);
          m.tetrahedra.push_back(t);
        }
  return m;
}

// Points spread through the same box, some on its faces.
InterfaceMesh pointsInBox(int count, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  InterfaceMesh m;
  for (int i = 0; i < count; ++i) m.nodes.emplace_back(u(rng), 2 * u(rng), i % 7 == 0 ? 0.5 : 0.5 * u(rng));
  return m;
}

// The pair of meshes each method is exact for: identity — the same mesh; nearest_neighbor — the same
// nodes in another order; nearest_projection — two different triangulations of the same surface;
// barycentric — points inside a tetrahedral volume (a bridging domain's particles in its elements).
std::pair<InterfaceMesh, InterfaceMesh> meshesFor(const std::string& name) {
  InterfaceMesh a = square(6, 5, 0.3, 1);
  if (name == "identity") return {a, a};
  if (name == "barycentric") return {box(4, 0.2, 3), pointsInBox(300, 5)};
  if (name == "nearest_neighbor") {
    InterfaceMesh b;
    b.nodes = a.nodes;
    std::shuffle(b.nodes.begin(), b.nodes.end(), std::mt19937(4));
    return {a, b};
  }
  return {a, square(9, 7, 0.35, 2)};
}

class EveryMapping : public ::testing::TestWithParam<std::string> {};

}  // namespace

TEST_P(EveryMapping, ConsistentReproducesLinearFields) {
  const auto [from, to] = meshesFor(GetParam());
  const auto map = cosim::makeMapping(GetParam(), from, to);
  auto field = [](const Vec3& x) { return Vec3(1 + 2 * x.x() - x.y(), -0.5 + 3 * x.z(), 0.25 * x.x() + x.y()); };
  std::vector<double> in, out(3 * to.nodes.size());
  for (const auto& x : from.nodes) {
    const Vec3 f = field(x);
    in.insert(in.end(), {f.x(), f.y(), f.z()});
  }
  map->consistent(in, out, 3);
  for (std::size_t i = 0; i < to.nodes.size(); ++i) {
    const Vec3 f = field(to.nodes[i]);
    EXPECT_NEAR((Vec3(out[3 * i], out[3 * i + 1], out[3 * i + 2]) - f).norm(), 0.0, 1e-13) << GetParam() << " node " << i;
  }
}

TEST_P(EveryMapping, ConservativePreservesForceAndMoment) {
  const auto [from, to] = meshesFor(GetParam());
  const auto map = cosim::makeMapping(GetParam(), from, to);
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<double> forcesTo(3 * to.nodes.size()), forcesFrom(3 * from.nodes.size());
  for (auto& f : forcesTo) f = u(rng);
  map->conservative(forcesTo, forcesFrom, 3);
  Vec3 F1 = Vec3::Zero(), M1 = Vec3::Zero(), F2 = Vec3::Zero(), M2 = Vec3::Zero();
  for (std::size_t i = 0; i < to.nodes.size(); ++i) {
    const Vec3 f(forcesTo[3 * i], forcesTo[3 * i + 1], forcesTo[3 * i + 2]);
    F1 += f;
    M1 += to.nodes[i].cross(f);
  }
  for (std::size_t i = 0; i < from.nodes.size(); ++i) {
    const Vec3 f(forcesFrom[3 * i], forcesFrom[3 * i + 1], forcesFrom[3 * i + 2]);
    F2 += f;
    M2 += from.nodes[i].cross(f);
  }
  EXPECT_NEAR((F1 - F2).norm(), 0.0, 1e-12 * (1 + F1.norm())) << GetParam();
  EXPECT_NEAR((M1 - M2).norm(), 0.0, 1e-12 * (1 + M1.norm())) << GetParam();
}

INSTANTIATE_TEST_SUITE_P(Mappings, EveryMapping, ::testing::ValuesIn(cosim::mappingNames()));

TEST(Mapping, ErrorsNameTheProblem) {
  const InterfaceMesh a = square(2, 2, 0, 1), b = square(3, 3, 0, 1);
  EXPECT_THROW(cosim::makeMapping("identity", a, b), std::invalid_argument);
  EXPECT_THROW(cosim::makeMapping("nearest_neigbor", a, b), std::invalid_argument);
  InterfaceMesh cloud;
  cloud.nodes = a.nodes;
  EXPECT_THROW(cosim::makeMapping("nearest_projection", cloud, b), std::invalid_argument);
  const auto map = cosim::makeMapping("nearest_neighbor", a, b);
  std::vector<double> wrong(5), out(3 * b.nodes.size());
  EXPECT_THROW(map->consistent(wrong, out, 3), std::invalid_argument);
}

// Triangles and segments are cells too: points on a tilted surface, and particles along a bar.
TEST(Mapping, BarycentricInterpolatesInTrianglesAndSegments) {
  auto field = [](const Vec3& x) { return 1 + 2 * x.x() - x.y() + 3 * x.z(); };
  const InterfaceMesh surface = square(6, 5, 0.3, 1), points = square(9, 7, 0.35, 2);
  InterfaceMesh bar, chain;
  for (int i = 0; i <= 10; ++i) bar.nodes.emplace_back(0.1 * i, 0.05 * i, 0);
  for (std::uint32_t i = 0; i < 10; ++i) bar.segments.push_back({i, i + 1});
  for (int i = 0; i <= 33; ++i) chain.nodes.emplace_back(i / 33.0, 0.5 * i / 33.0, 0);
  for (const auto& [from, to] : {std::pair{surface, points}, std::pair{bar, chain}}) {
    const auto map = cosim::makeMapping("barycentric", from, to);
    std::vector<double> in, out(to.nodes.size());
    for (const auto& x : from.nodes) in.push_back(field(x));
    map->consistent(in, out, 1);
    for (std::size_t i = 0; i < to.nodes.size(); ++i) EXPECT_NEAR(out[i], field(to.nodes[i]), 1e-13) << i;
  }
}

// Points on the cells' faces, edges and corners, the box's outer corners among them (the edge of the
// search grid), are found: the source's own nodes map to themselves.
TEST(Mapping, BarycentricFindsPointsOnFacesAndCorners) {
  const InterfaceMesh from = box(4, 0.2, 3);
  InterfaceMesh to;
  to.nodes = from.nodes;
  const auto map = cosim::makeMapping("barycentric", from, to);
  std::vector<double> in, out(to.nodes.size());
  for (const auto& x : from.nodes) in.push_back(std::sin(3 * x.x()) + x.y() * x.z());
  map->consistent(in, out, 1);
  for (std::size_t i = 0; i < in.size(); ++i) EXPECT_NEAR(out[i], in[i], 1e-12) << i;
}

// A particle outside every element of the overlap is an error that names it.
TEST(Mapping, BarycentricNamesAPointOutsideEveryCell) {
  InterfaceMesh points = pointsInBox(20, 5);
  points.nodes[13] = Vec3(0.5, 2.25, 0.1);
  try {
    cosim::makeMapping("barycentric", box(2, 0.0, 1), points);
    ADD_FAILURE() << "a point outside the box was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("node 13 at (0.5, 2.25, 0.1)"), std::string::npos) << e.what();
  }
  EXPECT_THROW(cosim::makeMapping("barycentric", pointsInBox(5, 1), points), std::invalid_argument);  // no cells
}

// A DEM wall meshed like the FEM interface (same nodes, any order, coordinates equal to round-off) maps
// by copying: the exact values, no weights; a mesh that differs does not.
TEST(Mapping, MeshesThatShareNodesMapByCopying) {
  const InterfaceMesh a = square(6, 5, 0.3, 1);
  std::vector<std::size_t> order(a.nodes.size());
  std::iota(order.begin(), order.end(), 0);
  std::shuffle(order.begin(), order.end(), std::mt19937(4));
  InterfaceMesh b;
  for (auto j : order) b.nodes.push_back(a.nodes[j] + Vec3(1e-15, 0, 0));
  std::vector<double> in(3 * a.nodes.size()), out(3 * b.nodes.size()), back(in.size());
  for (std::size_t i = 0; i < in.size(); ++i) in[i] = std::sin(0.7 * static_cast<double>(i));
  for (const std::string name : {"nearest_projection", "nearest_neighbor"}) {
    const auto map = cosim::makeMapping(name, a, b);
    EXPECT_TRUE(map->copies()) << name;
    map->consistent(in, out, 3);
    map->conservative(out, back, 3);
    for (std::size_t i = 0; i < b.nodes.size(); ++i)
      for (std::size_t k = 0; k < 3; ++k) EXPECT_EQ(out[3 * i + k], in[3 * order[i] + k]) << name << " node " << i;
    EXPECT_EQ(back, in) << name;  // a permutation: the transpose puts every value back
  }
  EXPECT_FALSE(cosim::makeMapping("nearest_projection", a, square(9, 7, 0.35, 2))->copies());
}

// The spin of a linear field, ½ ∇ × v, is exact in every tetrahedron: v = A x + b gives the axial
// vector of A's skew part at every point (a rigid rotation ω × x gives ω), and a field of pure strain
// (symmetric A) none. Triangles or segments have no spin: an error.
TEST(Mapping, SpinOfALinearFieldIsItsSkewPart) {
  const InterfaceMesh from = box(4, 0.2, 3), to = pointsInBox(300, 5);
  const Eigen::SparseMatrix<double> C = cosim::spinMatrix(from, to);
  ASSERT_EQ(C.rows(), 3 * static_cast<Eigen::Index>(to.nodes.size()));
  ASSERT_EQ(C.cols(), 3 * static_cast<Eigen::Index>(from.nodes.size()));
  Eigen::Matrix3d A;
  A << 0.3, -1.7, 0.4, 2.1, -0.2, 0.9, -0.6, 1.3, 0.5;
  const Vec3 b(0.2, -0.1, 0.7);
  const Eigen::Matrix3d skew = 0.5 * (A - A.transpose()), strain = 0.5 * (A + A.transpose());
  const Vec3 spin(skew(2, 1), skew(0, 2), skew(1, 0));
  for (const auto& [field, expected] : {std::pair{A, spin}, std::pair{strain, Vec3(Vec3::Zero())}}) {
    Eigen::VectorXd v(3 * static_cast<Eigen::Index>(from.nodes.size()));
    for (std::size_t i = 0; i < from.nodes.size(); ++i) v.segment<3>(3 * static_cast<Eigen::Index>(i)) = field * from.nodes[i] + b;
    const Eigen::VectorXd w = C * v;
    for (std::size_t j = 0; j < to.nodes.size(); ++j)
      for (int k = 0; k < 3; ++k) EXPECT_NEAR(w[3 * static_cast<Eigen::Index>(j) + k], expected[k], 1e-12) << j << " " << k;
  }
  EXPECT_THROW(cosim::spinMatrix(square(6, 5, 0.3, 1), square(9, 7, 0.35, 2)), std::invalid_argument);
}
