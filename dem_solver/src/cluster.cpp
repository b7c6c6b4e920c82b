#include "dem/cluster.hpp"

#include "cell_hash.hpp"

#include <omp.h>

#include <algorithm>
#include <limits>
#include <cmath>
#include <fstream>
#include <unordered_map>

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include "common/config.hpp"
#include "common/errors.hpp"
#include "common/geometry.hpp"

namespace dem {

namespace {

constexpr double kPi = 3.14159265358979323846;

// Volume, centroid and inertia per mass from ∫dV, ∫x dV and ∫x xᵀ dV (about the origin, unit density).
MassProperties fromMoments(double volume, const Vec3& first, const Eigen::Matrix3d& second) {
  MassProperties m;
  m.volume = volume;
  m.center = first / volume;
  const Eigen::Matrix3d aboutCenter = second / volume - m.center * m.center.transpose();
  m.inertiaPerMass = aboutCenter.trace() * Eigen::Matrix3d::Identity() - aboutCenter;
  return m;
}

// Spheres that overlap at least one other (cell hashing, cells of 2 r_max).
std::vector<bool> overlapping(const std::vector<Vec3>& c, const std::vector<double>& r) {
  std::vector<bool> out(c.size(), false);
  if (c.size() < 2) return out;
  const double cell = 2.0 * *std::max_element(r.begin(), r.end());
  auto key = [&](const Eigen::Vector3i& k) {
    return (static_cast<std::int64_t>(k.x()) * 73856093) ^ (static_cast<std::int64_t>(k.y()) * 19349663) ^
           (static_cast<std::int64_t>(k.z()) * 83492791);
  };
  auto cellOf = [&](const Vec3& p) { return Eigen::Vector3i((p / cell).array().floor().cast<int>()); };
  std::unordered_multimap<std::int64_t, std::size_t> grid;
  for (std::size_t i = 0; i < c.size(); ++i) grid.emplace(key(cellOf(c[i])), i);
  for (std::size_t i = 0; i < c.size(); ++i) {
    const Eigen::Vector3i k = cellOf(c[i]);
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const Eigen::Vector3i q = k + Eigen::Vector3i(dx, dy, dz);
          auto [b, e] = grid.equal_range(key(q));
          for (auto it = b; it != e; ++it) {
            const std::size_t j = it->second;
            if (j != i && (c[i] - c[j]).norm() < r[i] + r[j] - 1e-14 * (r[i] + r[j])) out[i] = true;
          }
        }
  }
  return out;
}

}  // namespace

namespace {
// The common radius r = f s/2 of spheres on a lattice of spacing s whose union has volume `target`:
// bisection on f in [lo, hi] (the union volume grows with f).
double radiusForVolume(const std::vector<Vec3>& centers, double s, double target, double lo, double hi) {
  for (int it = 0; it < 30; ++it) {
    const double mid = 0.5 * (lo + hi);
    const std::vector<double> r(centers.size(), mid * s / 2);
    (unionMassProperties(centers, r, 160).volume < target ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi) * s / 2;
}
}  // namespace

MassProperties boxMassProperties(const Vec3& s) {
  MassProperties m;
  m.volume = s.prod();
  m.inertiaPerMass = Eigen::Vector3d(s.y() * s.y() + s.z() * s.z(), s.x() * s.x() + s.z() * s.z(),
                                     s.x() * s.x() + s.y() * s.y()).asDiagonal();
  m.inertiaPerMass /= 12.0;
  return m;
}

MassProperties unionMassProperties(const std::vector<Vec3>& c, const std::vector<double>& r, int resolution) {
  const std::size_t n = c.size();
  const std::vector<bool> over = overlapping(c, r);
  // Accumulate volume, first and second moments (about the origin) per unit density.
  double vol = 0.0;
  Vec3 first = Vec3::Zero();
  Eigen::Matrix3d second = Eigen::Matrix3d::Zero();  // ∫ x xᵀ dV
  std::vector<std::size_t> gridded;
  for (std::size_t i = 0; i < n; ++i) {
    if (over[i]) {
      gridded.push_back(i);
      continue;
    }
    const double v = 4.0 / 3.0 * kPi * r[i] * r[i] * r[i];
    vol += v;
    first += v * c[i];
    second += v * (c[i] * c[i].transpose() + 0.2 * r[i] * r[i] * Eigen::Matrix3d::Identity());
  }
  if (!gridded.empty()) {
    Eigen::Vector3d lo = Vec3::Constant(1e300), hi = Vec3::Constant(-1e300);
    double rmax = 0.0;
    for (auto i : gridded) {
      lo = lo.cwiseMin(c[i] - Vec3::Constant(r[i]));
      hi = hi.cwiseMax(c[i] + Vec3::Constant(r[i]));
      rmax = std::max(rmax, r[i]);
    }
    const double h = (hi - lo).maxCoeff() / resolution;
    const Eigen::Vector3i dims = ((hi - lo) / h).array().ceil().cast<int>().max(1);
    // Centre the grid on the box so symmetric unions give symmetric (exactly diagonal) tensors.
    const Vec3 mid = 0.5 * (lo + hi);
    lo = mid - 0.5 * h * dims.cast<double>();
    hi = mid + 0.5 * h * dims.cast<double>();
    // Bucket the spheres by the columns (x, y) they cover so each sample tests only nearby spheres.
    const double bucket = 2.0 * rmax;
    const Eigen::Vector2i bdims = (((hi - lo).head<2>() / bucket).array().floor().cast<int>() + 1);
    std::vector<std::vector<std::size_t>> buckets(static_cast<std::size_t>(bdims.prod()));
    for (auto i : gridded) {
      const Eigen::Vector2i a = ((c[i].head<2>() - Vec3::Constant(r[i]).head<2>() - lo.head<2>()) / bucket).array().floor().cast<int>().max(0);
      const Eigen::Vector2i b = ((c[i].head<2>() + Vec3::Constant(r[i]).head<2>() - lo.head<2>()) / bucket).array().floor().cast<int>().min(bdims.array() - 1);
      for (int y = a.y(); y <= b.y(); ++y)
        for (int x = a.x(); x <= b.x(); ++x) buckets[static_cast<std::size_t>(y * bdims.x() + x)].push_back(i);
    }
    const double dv = h * h * h;
    const int nz = dims.z();
    std::vector<double> vz(static_cast<std::size_t>(nz), 0.0);
    std::vector<Vec3> fz(static_cast<std::size_t>(nz), Vec3::Zero());
    std::vector<Eigen::Matrix3d> sz(static_cast<std::size_t>(nz), Eigen::Matrix3d::Zero());
#pragma omp parallel for schedule(dynamic)
    for (int k = 0; k < nz; ++k) {
      double v = 0;
      Vec3 f = Vec3::Zero();
      Eigen::Matrix3d s = Eigen::Matrix3d::Zero();
      for (int j = 0; j < dims.y(); ++j)
        for (int i = 0; i < dims.x(); ++i) {
          const Vec3 p = lo + h * Vec3(i + 0.5, j + 0.5, k + 0.5);
          const Eigen::Vector2i b = ((p.head<2>() - lo.head<2>()) / bucket).array().floor().cast<int>().min(bdims.array() - 1);
          bool inside = false;
          for (auto m : buckets[static_cast<std::size_t>(b.y() * bdims.x() + b.x())])
            if ((p - c[m]).squaredNorm() <= r[m] * r[m]) {
              inside = true;
              break;
            }
          if (!inside) continue;
          v += dv;
          f += dv * p;
          s += dv * p * p.transpose();
        }
      vz[static_cast<std::size_t>(k)] = v;
      fz[static_cast<std::size_t>(k)] = f;
      sz[static_cast<std::size_t>(k)] = s;
    }
    for (int k = 0; k < nz; ++k) {  // summed in slab order: deterministic
      vol += vz[static_cast<std::size_t>(k)];
      first += fz[static_cast<std::size_t>(k)];
      second += sz[static_cast<std::size_t>(k)];
    }
  }
  return fromMoments(vol, first, second);
}

ClusterShape makeCubeCluster(double edge, int n) {
  ClusterShape out;
  out.shape = boxMassProperties(Vec3::Constant(edge));
  if (n == 1) {
    out.centers.push_back(Vec3::Zero());
    out.radii.push_back(edge * std::cbrt(3.0 / (4.0 * kPi)));
    out.comment = fmt::format("cube of edge {} m: one sphere of the cube's volume", edge);
    return out;
  }
  const double s = edge / n;
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) out.centers.push_back(Vec3(i + 0.5, j + 0.5, k + 0.5) * s - Vec3::Constant(edge / 2));
  out.radii.assign(out.centers.size(), radiusForVolume(out.centers, s, edge * edge * edge, 1.0, std::sqrt(3.0)));
  out.comment = fmt::format("cube of edge {} m: {}^3 spheres on a cubic lattice, r = {:.6g} m (union volume = cube volume)",
                            edge, n, out.radii[0]);
  return out;
}

ClusterShape makeCubeLattice(double edge, int n) {
  ClusterShape out;
  const double s = edge / n;
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) out.centers.push_back(Vec3(i + 0.5, j + 0.5, k + 0.5) * s - Vec3::Constant(edge / 2));
  out.radii.assign(out.centers.size(), 0.5 * s);
  out.comment = fmt::format("cube of edge {} m: {}^3 touching spheres on a cubic lattice, r = {:.6g} m", edge, n, 0.5 * s);
  return out;
}

ClusterShape makeBoxLattice(double spacing, const Eigen::Vector3i& n) {
  ClusterShape out;
  const Vec3 half = 0.5 * spacing * n.cast<double>();
  for (int k = 0; k < n.z(); ++k)
    for (int j = 0; j < n.y(); ++j)
      for (int i = 0; i < n.x(); ++i) out.centers.push_back(spacing * Vec3(i + 0.5, j + 0.5, k + 0.5) - half);
  out.radii.assign(out.centers.size(), 0.5 * spacing);
  out.comment = fmt::format("box of {} × {} × {} touching spheres on a cubic lattice, r = {:.6g} m", n.x(), n.y(), n.z(),
                            0.5 * spacing);
  return out;
}

std::pair<double, std::pair<std::size_t, std::size_t>> largestOverlap(const std::vector<Vec3>& centers,
                                                                     const std::vector<double>& radii) {
  std::pair<double, std::pair<std::size_t, std::size_t>> worst{-std::numeric_limits<double>::infinity(), {0, 0}};
  if (centers.size() < 2) return worst;
  const double rmax = *std::max_element(radii.begin(), radii.end());
  detail::CellHash grid(2.0 * rmax);
  for (std::size_t i = 0; i < centers.size(); ++i) {
    grid.forEachNear(centers[i], [&](std::uint32_t j) {
      const double reach = radii[i] + radii[j];
      const double overlap = (reach - (centers[i] - centers[j]).norm()) / reach;
      if (overlap > worst.first) worst = {overlap, {j, i}};
      return true;
    });
    grid.insert(static_cast<std::uint32_t>(i), centers[i]);
  }
  return worst;
}

MassProperties meshMassProperties(const common::TriangleMesh& mesh) {
  double vol = 0.0;
  Vec3 first = Vec3::Zero();
  Eigen::Matrix3d second = Eigen::Matrix3d::Zero();
  for (const auto& t : mesh.triangles) {
    const Vec3 &a = mesh.nodes[t[0]], &b = mesh.nodes[t[1]], &c = mesh.nodes[t[2]];
    const double v = a.dot(b.cross(c)) / 6.0;  // signed volume of the tetrahedron (0, a, b, c)
    const Vec3 sum = a + b + c;                // + the origin vertex
    vol += v;
    first += v * sum / 4.0;
    // ∫ x xᵀ over a tetrahedron = V/20 (Σ p pᵀ + (Σ p)(Σ p)ᵀ), vertices p incl. the origin.
    second += v / 20.0 * (a * a.transpose() + b * b.transpose() + c * c.transpose() + sum * sum.transpose());
  }
  if (vol < 0) {  // inward-oriented triangles: every term flips sign
    vol = -vol;
    first = -first;
    second = -second;
  }
  if (!(vol > 0)) throw common::SimulationError("the surface mesh encloses no volume (is it closed?).");
  return fromMoments(vol, first, second);
}

bool insideMesh(const common::TriangleMesh& mesh, const Vec3& p) {
  // Σ solid angles (Van Oosterom & Strackee 1983) / 4π: ±1 inside, 0 outside.
  double omega = 0.0;
  for (const auto& t : mesh.triangles) {
    const Vec3 a = mesh.nodes[t[0]] - p, b = mesh.nodes[t[1]] - p, c = mesh.nodes[t[2]] - p;
    const double la = a.norm(), lb = b.norm(), lc = c.norm();
    const double num = a.dot(b.cross(c));
    const double den = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
    omega += 2.0 * std::atan2(num, den);
  }
  return std::abs(omega) > 2.0 * kPi;
}

ClusterShape fillMesh(const common::TriangleMesh& mesh, std::size_t count) {
  ClusterShape out;
  const MassProperties props = meshMassProperties(mesh);
  out.shape = props;
  common::Aabb box;
  for (const auto& x : mesh.nodes) box.expand(x);
  const double s = std::cbrt(props.volume / static_cast<double>(std::max<std::size_t>(count, 1)));
  const Eigen::Array3i n = (box.extent().array() / s).ceil().cast<int>().max(1);
  const Vec3 origin = box.center() - 0.5 * s * n.cast<double>().matrix();
  for (int k = 0; k < n.z(); ++k)
    for (int j = 0; j < n.y(); ++j)
      for (int i = 0; i < n.x(); ++i) {
        const Vec3 p = origin + s * Vec3(i + 0.5, j + 0.5, k + 0.5);
        if (insideMesh(mesh, p)) out.centers.push_back(p);
      }
  if (out.centers.empty()) {  // smaller than one lattice cell: one sphere of the same volume at the centroid
    out.centers.push_back(props.center);
    out.radii.push_back(std::cbrt(3.0 * props.volume / (4.0 * kPi)));
    return out;
  }
  out.radii.assign(out.centers.size(), radiusForVolume(out.centers, s, props.volume, 0.5, 2.0));
  return out;
}

ClusterShape readClusterFile(const std::filesystem::path& file) {
  const common::Config cfg = common::Config::load(file);
  ClusterShape out;
  out.comment = cfg.get<std::string>("comment", "");
  for (const auto& s : cfg.at("spheres").elements()) {
    const auto v = s.as<std::vector<double>>();
    if (v.size() != 4) s.fail("expected [x, y, z, r].");
    if (!(v[3] > 0)) s.fail("the radius (4th value) must be > 0.");
    out.centers.emplace_back(v[0], v[1], v[2]);
    out.radii.push_back(v[3]);
  }
  if (out.centers.empty()) cfg.failAt("spheres", "a cluster needs at least one sphere.");
  if (common::Config shape = cfg.child("shape")) {
    MassProperties m;
    m.volume = shape.get("volume", common::Interval::positive());
    m.center = shape.get<Eigen::Vector3d>("center", Vec3::Zero());
    const common::Config rows = shape.at("inertia_per_mass");
    const auto elems = rows.elements();
    if (elems.size() != 3) rows.fail("expected a 3×3 matrix [[..], [..], [..]].");
    for (int i = 0; i < 3; ++i) m.inertiaPerMass.row(i) = elems[static_cast<std::size_t>(i)].as<Eigen::Vector3d>();
    if ((m.inertiaPerMass - m.inertiaPerMass.transpose()).norm() > 1e-9 * m.inertiaPerMass.norm())
      rows.fail("the inertia tensor must be symmetric.");
    out.shape = m;
  }
  cfg.checkUnknownKeys();
  return out;
}

void writeClusterFile(const std::filesystem::path& file, const ClusterShape& c) {
  YAML::Emitter y;
  y.SetDoublePrecision(12);
  y << YAML::BeginMap;
  if (!c.comment.empty()) y << YAML::Key << "comment" << YAML::Value << c.comment;
  if (c.shape) {
    y << YAML::Key << "shape" << YAML::Value << YAML::BeginMap;
    y << YAML::Key << "volume" << YAML::Value << c.shape->volume;
    y << YAML::Key << "center" << YAML::Value << YAML::Flow
      << std::vector<double>{c.shape->center.x(), c.shape->center.y(), c.shape->center.z()};
    y << YAML::Key << "inertia_per_mass" << YAML::Value << YAML::BeginSeq;
    for (int i = 0; i < 3; ++i)
      y << YAML::Flow
        << std::vector<double>{c.shape->inertiaPerMass(i, 0), c.shape->inertiaPerMass(i, 1), c.shape->inertiaPerMass(i, 2)};
    y << YAML::EndSeq << YAML::EndMap;
  }
  y << YAML::Key << "spheres" << YAML::Value << YAML::BeginSeq;
  for (std::size_t i = 0; i < c.centers.size(); ++i)
    y << YAML::Flow << std::vector<double>{c.centers[i].x(), c.centers[i].y(), c.centers[i].z(), c.radii[i]};
  y << YAML::EndSeq << YAML::EndMap;
  std::ofstream out(file);
  out << y.c_str() << '\n';
  if (!out) throw common::SimulationError(fmt::format("cannot write cluster file {}.", file.string()));
}

}  // namespace dem
