#include "common/geometry.hpp"

#include <filesystem>
#include <fstream>
#include <unistd.h>

#include "common/errors.hpp"
#include "common/memory.hpp"
#include "common/mesh_io.hpp"

#include <random>

#include <gtest/gtest.h>

using common::Aabb;
using common::closestPointOnTriangle;
using common::TriangleFeature;
using common::Vec3;

namespace {

const Vec3 kA(0, 0, 0), kB(1, 0, 0), kC(0, 1, 0);

struct Case {
  Vec3 p;
  TriangleFeature feature;
  Vec3 point;
  std::array<double, 3> bary;
};

void expectCase(const Case& k, const Vec3& a, const Vec3& b, const Vec3& c) {
  const auto r = closestPointOnTriangle(k.p, a, b, c);
  SCOPED_TRACE(::testing::Message() << "p = " << k.p.transpose() << ", got " << common::toString(r.feature));
  EXPECT_EQ(r.feature, k.feature);
  EXPECT_NEAR((r.point - k.point).norm(), 0.0, 1e-15);
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(r.bary[i], k.bary[i], 1e-15);
  EXPECT_NEAR(r.distanceSquared, (k.p - k.point).squaredNorm(), 1e-15);
}

}  // namespace

// Hand-computed: each Voronoi region of the unit right triangle in the z = 0 plane.
TEST(Geometry, ClosestPointInEveryRegion) {
  const Case cases[] = {
      {{0.25, 0.25, 1.0}, TriangleFeature::kFace, {0.25, 0.25, 0}, {0.5, 0.25, 0.25}},
      {{0.25, 0.25, -2.0}, TriangleFeature::kFace, {0.25, 0.25, 0}, {0.5, 0.25, 0.25}},
      {{0.5, -1.0, 0.3}, TriangleFeature::kEdgeAB, {0.5, 0, 0}, {0.5, 0.5, 0}},
      {{1.0, 1.0, 0.0}, TriangleFeature::kEdgeBC, {0.5, 0.5, 0}, {0, 0.5, 0.5}},
      {{-1.0, 0.75, 0.0}, TriangleFeature::kEdgeCA, {0, 0.75, 0}, {0.25, 0, 0.75}},
      {{-1.0, -1.0, 0.5}, TriangleFeature::kVertexA, {0, 0, 0}, {1, 0, 0}},
      {{2.0, -0.5, 0.0}, TriangleFeature::kVertexB, {1, 0, 0}, {0, 1, 0}},
      {{-0.5, 2.0, 0.0}, TriangleFeature::kVertexC, {0, 1, 0}, {0, 0, 1}},
  };
  for (const auto& k : cases) expectCase(k, kA, kB, kC);
}

TEST(Geometry, DegenerateCollinearTriangleActsAsSegments) {
  const Vec3 a(0, 0, 0), b(1, 0, 0), c(2, 0, 0);
  expectCase({{1.5, 1.0, 0}, TriangleFeature::kEdgeBC, {1.5, 0, 0}, {0, 0.5, 0.5}}, a, b, c);
  expectCase({{3.0, 0.0, 0}, TriangleFeature::kVertexC, {2, 0, 0}, {0, 0, 1}}, a, b, c);
  expectCase({{-1.0, 0.0, 0}, TriangleFeature::kVertexA, {0, 0, 0}, {1, 0, 0}}, a, b, c);
  expectCase({{0.5, 0.0, 2.0}, TriangleFeature::kEdgeAB, {0.5, 0, 0}, {0.5, 0.5, 0}}, a, b, c);
}

TEST(Geometry, DegenerateCoincidentVertices) {
  const Vec3 q(1, 1, 1);
  expectCase({{1, 1, 2}, TriangleFeature::kVertexA, q, {1, 0, 0}}, q, q, q);
  // a == b: the triangle is the segment a-c.
  const Vec3 o(0, 0, 0), x(1, 0, 0);
  const auto r = closestPointOnTriangle({0.5, 1, 0}, o, o, x);
  EXPECT_NE(r.feature, TriangleFeature::kFace);
  EXPECT_NEAR((r.point - Vec3(0.5, 0, 0)).norm(), 0, 1e-15);
  EXPECT_NEAR(r.distanceSquared, 1.0, 1e-15);
  EXPECT_NEAR(r.bary[0] + r.bary[1] + r.bary[2], 1.0, 1e-15);
}

// Invariant: the reported point is on the triangle, matches its barycentric weights, and no sampled
// point of the triangle is closer.
TEST(Geometry, ClosestPointIsNeverBeatenBySamples) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-2, 2), s(0, 1);
  for (int trial = 0; trial < 200; ++trial) {
    const Vec3 a(u(rng), u(rng), u(rng)), b(u(rng), u(rng), u(rng)), c(u(rng), u(rng), u(rng)), p(u(rng), u(rng), u(rng));
    const auto r = closestPointOnTriangle(p, a, b, c);
    EXPECT_NEAR(r.bary[0] + r.bary[1] + r.bary[2], 1.0, 1e-12);
    for (double w : r.bary) EXPECT_GE(w, -1e-12);
    EXPECT_NEAR((r.bary[0] * a + r.bary[1] * b + r.bary[2] * c - r.point).norm(), 0.0, 1e-12);
    for (int k = 0; k < 200; ++k) {
      double x = s(rng), y = s(rng);
      if (x + y > 1) x = 1 - x, y = 1 - y;
      const Vec3 q = a + x * (b - a) + y * (c - a);
      EXPECT_LE(r.distanceSquared, (p - q).squaredNorm() + 1e-12);
    }
  }
}

TEST(Geometry, Aabb) {
  Aabb box;
  EXPECT_TRUE(box.empty());
  box.expand(Vec3(0, 0, 0));
  box.expand(Vec3(1, 2, 3));
  EXPECT_FALSE(box.empty());
  EXPECT_EQ(box.center(), Vec3(0.5, 1, 1.5));
  EXPECT_EQ(box.extent(), Vec3(1, 2, 3));
  EXPECT_TRUE(box.contains({1, 2, 3}));
  EXPECT_FALSE(box.contains({1, 2, 3.001}));
  EXPECT_DOUBLE_EQ(box.distance({0.5, 1, 1}), 0.0);
  EXPECT_DOUBLE_EQ(box.distance({4, 6, 3}), 5.0);  // 3-4-5 off the (1, 2) corner
  Aabb other{{1, 2, 3}, {5, 5, 5}};
  EXPECT_TRUE(box.overlaps(other));  // touching counts
  Aabb apart{{1.1, 0, 0}, {2, 1, 1}};
  EXPECT_FALSE(box.overlaps(apart));
  EXPECT_TRUE(box.inflated(0.1).overlaps(apart));
  Aabb merged = box;
  merged.expand(apart);
  EXPECT_EQ(merged.max, Vec3(2, 2, 3));
}

// STL written here, read back through gmsh: same triangles (gmsh merges duplicate STL vertices).
TEST(MeshIo, StlRoundTripThroughGmsh) {
  common::TriangleMesh m;
  m.nodes = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0.5, 0.5, 0.5}};
  m.triangles = {{0, 1, 4}, {1, 2, 4}, {2, 3, 4}, {3, 0, 4}};
  const auto file = std::filesystem::temp_directory_path() / "cosim_mesh_io.stl";
  common::writeStl(file, m);
  const auto back = common::readTriangleMesh(file);
  ASSERT_EQ(back.triangles.size(), 4u);
  EXPECT_EQ(back.nodes.size(), 5u);
  double area = 0;
  for (const auto& t : back.triangles)
    area += 0.5 * (back.nodes[t[1]] - back.nodes[t[0]]).cross(back.nodes[t[2]] - back.nodes[t[0]]).norm();
  EXPECT_NEAR(area, 4 * 0.5 * std::sqrt(0.5), 1e-12);  // four triangles of base 1, slant height √0.5
  std::filesystem::remove(file);
  try {
    common::readTriangleMesh("/no/such/mesh.msh");
    FAIL();
  } catch (const common::SimulationError& e) {
    EXPECT_STREQ(e.what(), "mesh file \"/no/such/mesh.msh\" does not exist.");
  }
}

// A gmsh header that claims what the file cannot hold is refused before gmsh allocates for it: 10⁸ nodes
// in 23 KB took 2.4 GB before its error; a largest node tag of 4·10⁹ (a pointer per tag: 32 GB) went
// unchecked. A real file passes.
TEST(MeshIo, HeadersClaimingMoreThanTheFileOrTheMachineAreRefused) {
  const auto dir = std::filesystem::temp_directory_path() / ("cosim_msh_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  auto write = [&](const char* name, const std::string& nodesHeader, const std::string& tags) {
    std::ofstream(dir / name) << "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n" << nodesHeader << "\n2 1 0 3\n"
                              << tags << "\n0 0 0\n1 0 0\n0 1 0\n$EndNodes\n$Elements\n1 1 1 1\n2 1 2 1\n1 " << tags
                              << "\n$EndElements\n" << std::string(23000, '%') << "\n";
    return dir / name;
  };
  auto message = [](const std::filesystem::path& file) {
    try {
      common::checkGmshHeader(file);
    } catch (const common::SimulationError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  const std::string many = message(write("many.msh", "1 100000000 1 100000000", "1 2 3"));
  EXPECT_NE(many.find("its header claims 1e+08 nodes, more than its"), std::string::npos) << many;
  if (common::physicalMemoryBytes() < 3.2e10) {
    const std::string sparse = message(write("sparse.msh", "1 3 1 4000000000", "1 2 4000000000"));
    EXPECT_NE(sparse.find("for the nodes tags up to 4e+09 of its header"), std::string::npos) << sparse;
  }
  EXPECT_EQ(message(write("fine.msh", "1 3 1 3", "1 2 3")), "");
  std::filesystem::remove_all(dir);
}
