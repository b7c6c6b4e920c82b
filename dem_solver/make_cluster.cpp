// make_cluster: writes a cluster file (dem/cluster.hpp format) and reports how well the sphere union
// matches the target shape's volume and inertia. Run with:
//   make_cluster --edge 0.41 --count 8 --out configs/dem/clusters/cube_c2.yaml      (a cube)
//   make_cluster --mesh rock.msh --count 300 --out rock.yaml                         (any closed surface)
//   make_cluster --make-rock rock.msh --seed 3 --size 0.5 0.35 0.3                   (an irregular rock surface)
#include <cmath>
#include <cstdio>
#include <random>

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <gmsh.h>

#include "common/errors.hpp"
#include "common/mesh_io.hpp"
#include "dem/cluster.hpp"

namespace {

// An ellipsoid meshed by gmsh whose nodes are pushed radially by a few random low-order spherical
// modes: a closed, irregular, rock-like surface written as a gmsh .msh file.
void makeRock(const std::string& file, unsigned seed, const std::vector<double>& size) {
  gmsh::initialize(0, nullptr, false);
  gmsh::option::setNumber("General.Terminal", 0);
  gmsh::option::setNumber("General.AbortOnError", 3);
  gmsh::model::add("rock");
  const int v = gmsh::model::occ::addSphere(0, 0, 0, 1.0);
  gmsh::model::occ::dilate({{3, v}}, 0, 0, 0, size[0] / 2, size[1] / 2, size[2] / 2);
  gmsh::model::occ::synchronize();
  gmsh::option::setNumber("Mesh.MeshSizeMax", std::min({size[0], size[1], size[2]}) / 8);
  gmsh::model::mesh::generate(2);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  struct Mode {
    Eigen::Vector3d k;
    double phase, amplitude;
  };
  std::vector<Mode> modes;
  for (int i = 0; i < 6; ++i)
    modes.push_back({Eigen::Vector3d(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5).normalized() * (2 + 3 * u(rng)),
                     2 * 3.14159265358979 * u(rng), 0.06 * u(rng)});
  std::vector<std::size_t> tags;
  std::vector<double> coords, param;
  gmsh::model::mesh::getNodes(tags, coords, param, -1, -1, true, false);
  for (std::size_t i = 0; i < tags.size(); ++i) {
    Eigen::Vector3d x(coords[3 * i], coords[3 * i + 1], coords[3 * i + 2]);
    const Eigen::Vector3d dir = x.cwiseQuotient(Eigen::Vector3d(size[0], size[1], size[2]) / 2).normalized();
    double factor = 1.0;
    for (const auto& m : modes) factor += m.amplitude * std::sin(m.k.dot(dir) + m.phase);
    x *= factor;
    gmsh::model::mesh::setNode(tags[i], {x.x(), x.y(), x.z()}, {});
  }
  gmsh::model::addPhysicalGroup(2, {1}, 1);
  gmsh::model::setPhysicalName(2, 1, "surface");
  gmsh::option::setNumber("Mesh.SaveAll", 0);
  gmsh::write(file);
  gmsh::finalize();
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app("Generate a rigid cluster of spheres filling a cube or a closed surface mesh", "make_cluster");
  double edge = 0.41;
  long count = 8;
  std::string out, meshFile, physical, rockFile;
  unsigned seed = 1;
  std::vector<double> rockSize{0.5, 0.35, 0.3};
  app.add_option("--edge", edge, "cube edge [m]")->check(CLI::PositiveNumber);
  app.add_option("--count", count, "requested sphere count (the lattice gives about this many)")->check(CLI::PositiveNumber);
  app.add_option("--mesh", meshFile, "fill this closed surface mesh (.msh, .stl, … read by gmsh) instead of a cube");
  app.add_option("--physical", physical, "with --mesh: only this 2-D physical group");
  app.add_option("--out,-o", out, "cluster file to write");
  app.add_option("--make-rock", rockFile, "write an irregular rock surface (.msh) and exit");
  app.add_option("--seed", seed, "--make-rock: random seed");
  app.add_option("--size", rockSize, "--make-rock: bounding ellipsoid axes [m]")->expected(3);
  CLI11_PARSE(app, argc, argv);
  try {
    if (!rockFile.empty()) {
      makeRock(rockFile, seed, rockSize);
      std::printf("%s: irregular rock surface (seed %u)\n", rockFile.c_str(), seed);
      return 0;
    }
    if (out.empty()) throw std::runtime_error("--out is required");
    dem::ClusterShape c;
    if (!meshFile.empty()) {
      c = dem::fillMesh(common::readTriangleMesh(meshFile, physical), static_cast<std::size_t>(count));
      c.comment = fmt::format("{} filled with {} spheres on a cubic lattice, r = {:.6g} m", meshFile,
                              c.centers.size(), c.radii[0]);
    } else {
      const int n = std::max(1, static_cast<int>(std::lround(std::cbrt(static_cast<double>(count)))));
      c = dem::makeCubeCluster(edge, n);
    }
    const dem::MassProperties u = dem::unionMassProperties(c.centers, c.radii, 200);
    const dem::MassProperties& s = *c.shape;
    const double volErr = u.volume / s.volume - 1;
    const double inertiaErr = (u.inertiaPerMass - s.inertiaPerMass).norm() / s.inertiaPerMass.norm();
    const double centerErr = (u.center - s.center).norm() / std::cbrt(s.volume);
    c.comment += fmt::format("; sphere union vs shape: volume {:+.3f} %, inertia/mass {:.3f} %, centroid {:.3f} % of V^(1/3)",
                             100 * volErr, 100 * inertiaErr, 100 * centerErr);
    dem::writeClusterFile(out, c);
    std::printf("%s: %zu spheres (requested %ld), r = %.6g m\n  union volume %.6g m³ (shape %.6g, %+.3f %%)\n"
                "  union inertia/mass off by %.3f %% (Frobenius), centroid off by %.3f %% of V^(1/3)\n",
                out.c_str(), c.centers.size(), count, c.radii[0], u.volume, s.volume, 100 * volErr, 100 * inertiaErr,
                100 * centerErr);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "make_cluster: %s\n", e.what());
    return 2;
  }
  return 0;
}
