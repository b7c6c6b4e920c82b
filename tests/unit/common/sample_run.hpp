#pragma once
// A small results file exercising every part of common::H5Writer; used by its unit test and, through
// write_sample_run, by the test of tools/plot_timeseries.py.

#include <cmath>
#include <filesystem>
#include <vector>

#include "common/h5_writer.hpp"

// Writes a small run: two time series, a 2-triangle mesh with 3 snapshots (one with moved nodes),
// particle snapshots whose count changes. Returns nothing; the file is `path`.
inline void writeSampleRun(const std::filesystem::path& path) {
  common::H5Writer w(path);
  w.addSeries("energy", {"kinetic", "potential"});
  w.addSeries("block", {"z", "vz"});
  for (int i = 0; i <= 100; ++i) {
    const double t = 0.01 * i;
    const double k = 0.5 * std::cos(6.0 * t) * std::cos(6.0 * t);
    w.append("energy", t, std::vector<double>{k, 0.5 - k});
    w.append("block", t, std::vector<double>{2.0 - 4.905 * t * t, -9.81 * t});
  }
  const std::vector<double> nodes{0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
  const std::vector<std::int64_t> cells{0, 1, 2, 0, 2, 3};
  w.addMesh("membrane", nodes, cells, common::CellType::kTriangle);
  for (int s = 0; s < 3; ++s) {
    std::vector<double> u(12, 0.0), stress{1.0 * s, 2.0 * s};
    for (int n = 0; n < 4; ++n) u[3 * n + 2] = -0.01 * s * n;
    std::vector<double> moved = nodes;
    for (std::size_t i = 0; i < 12; ++i) moved[i] += u[i];
    w.writeMeshSnapshot("membrane", 0.1 * s, s == 2 ? std::span<const double>(moved) : std::span<const double>(),
                        {common::Field{"displacement", 3, u}}, {common::Field{"stress", 1, stress}});
  }
  for (int s = 0; s < 2; ++s) {
    const std::size_t n = 2 + s;
    std::vector<double> pos(3 * n), radius(n, 0.05);
    for (std::size_t i = 0; i < 3 * n; ++i) pos[i] = 0.1 * static_cast<double>(i);
    w.writeParticles("spheres", 0.5 * s, pos, {common::Field{"radius", 1, radius}});
  }
}

