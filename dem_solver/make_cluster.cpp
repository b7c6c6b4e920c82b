// make_cluster: writes a cluster file (dem/cluster.hpp format) that fills a box with n³ spheres and
// reports how well the sphere union matches the box's volume and inertia. Run with:
//   make_cluster --box 0.41 0.41 0.41 --count 8 --out configs/dem/clusters/cube_c2.yaml
#include <cmath>
#include <cstdio>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "common/errors.hpp"
#include "dem/cluster.hpp"

int main(int argc, char** argv) {
  CLI::App app("Generate a rigid cluster of spheres filling a cube", "make_cluster");
  double edge = 0.41;
  long count = 8;
  std::string out;
  app.add_option("--edge", edge, "cube edge [m]")->check(CLI::PositiveNumber);
  app.add_option("--count", count, "requested sphere count; the nearest cube n³ is used")->check(CLI::PositiveNumber);
  app.add_option("--out,-o", out, "cluster file to write")->required();
  CLI11_PARSE(app, argc, argv);
  try {
    const int n = std::max(1, static_cast<int>(std::lround(std::cbrt(static_cast<double>(count)))));
    dem::ClusterShape c = dem::makeCubeCluster(edge, n);
    const dem::MassProperties u = dem::unionMassProperties(c.centers, c.radii, 200);
    const dem::MassProperties& s = *c.shape;
    const double volErr = u.volume / s.volume - 1;
    const double inertiaErr = (u.inertiaPerMass - s.inertiaPerMass).norm() / s.inertiaPerMass.norm();
    c.comment += fmt::format("; sphere union vs cube: volume {:+.3f} %, inertia/mass {:.3f} %", 100 * volErr,
                             100 * inertiaErr);
    dem::writeClusterFile(out, c);
    std::printf("%s: %zu spheres (requested %ld), r = %.6g m\n  union volume %.6g m³ (cube %.6g, %+.3f %%)\n"
                "  union inertia/mass %.6g m² (cube %.6g, %.3f %% off, Frobenius)\n",
                out.c_str(), c.centers.size(), count, c.radii[0], u.volume, s.volume, 100 * volErr,
                u.inertiaPerMass(0, 0), s.inertiaPerMass(0, 0), 100 * inertiaErr);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "make_cluster: %s\n", e.what());
    return 2;
  }
  return 0;
}
