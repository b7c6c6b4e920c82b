#include "dem/bonds.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <numeric>

#include <Eigen/Geometry>

#include "cell_hash.hpp"

namespace dem {

void BondSet::create(const View& v, const LawOf& lawOf, const MassOf& massOf, double maxReach, const ShearOf& shearOf) {
  bonds_.clear();
  law_.clear();
  broken_ = 0;
  // Spheres in cells of edge maxReach: a pair within reach lies in neighbouring cells. Once, at the start.
  if (!(maxReach > 0.0)) maxReach = 1.0;  // no law bonds: the loop below bonds nothing
  detail::CellHash grid(maxReach);
  for (std::uint32_t s = 0; s < v.spheres; ++s) grid.insert(s, v.centre[s]);
  std::vector<std::uint32_t> near;
  for (std::uint32_t i = 0; i < v.spheres; ++i) {
    near.clear();
    grid.forEachNear(v.centre[i], [&](std::uint32_t j) {
      if (j > i) near.push_back(j);
      return true;
    });
    std::sort(near.begin(), near.end());
    for (auto j : near) {
      if (v.body[i] == v.body[j]) continue;
      const BondingLaw* law = lawOf(i, j);
      if (!law) continue;
      const double ri = v.radius[i], rj = v.radius[j];
      const double d = (v.centre[i] - v.centre[j]).norm();
      // Within reach, touching included (to round-off: a sample built with touching spheres bonds them).
      if (!(d <= law->bondReach(ri, rj) * (1.0 + 1e-12))) continue;
      Bond b = law->makeBond(ri, rj, massOf(i, j), ri + rj - d);
      b.a = i, b.b = j;
      if (shearOf) b.shearForce = shearOf(i, j);
      bonds_.push_back(b);
      law_.push_back(law);
    }
  }
  created_ = static_cast<std::int64_t>(bonds_.size());
  everBonded_.assign(v.spheres, 0);
  for (const Bond& b : bonds_) everBonded_[b.a] = everBonded_[b.b] = 1;
  force_.assign(bonds_.size(), BondForce{});
  point_.assign(bonds_.size(), Vec3::Zero());
  index(v.spheres);
}

void BondSet::index(std::size_t spheres) {
  partnerStart_.assign(spheres + 1, 0);
  for (const Bond& b : bonds_) ++partnerStart_[b.a + 1];
  for (std::size_t s = 0; s < spheres; ++s) partnerStart_[s + 1] += partnerStart_[s];
  partner_.resize(bonds_.size());
  std::vector<std::uint32_t> fill(partnerStart_.begin(), partnerStart_.end() - 1);
  for (const Bond& b : bonds_) partner_[fill[b.a]++] = b.b;  // bonds_ is in (a, b) order: sorted runs
}

bool BondSet::bonded(std::uint32_t i, std::uint32_t j) const {
  if (i > j) std::swap(i, j);
  if (i + 1 >= partnerStart_.size()) return false;
  const auto first = partner_.begin() + partnerStart_[i], last = partner_.begin() + partnerStart_[i + 1];
  return std::binary_search(first, last, j);
}

std::size_t BondSet::compute(const View& v, double dt) {
  elastic_ = damping_ = released_ = 0.0;
  std::size_t broke = 0;
  for (std::size_t k = 0; k < bonds_.size(); ++k) {
    Bond& bond = bonds_[k];
    const Vec3 d = v.centre[bond.a] - v.centre[bond.b];
    const double distance = d.norm();
    const Vec3 n = d / distance;
    const double ra = v.radius[bond.a], rb = v.radius[bond.b];
    const double overlap = ra + rb - distance;
    // The contact point halfway through the overlap (or the gap), as for touching spheres.
    const Vec3 p = v.centre[bond.b] + n * (rb - 0.5 * overlap);
    const auto ba = v.body[bond.a], bb = v.body[bond.b];
    const Vec3 va = v.velocity[ba] + v.angularVelocity[ba].cross(p - v.bodyPosition[ba]);
    const Vec3 vb = v.velocity[bb] + v.angularVelocity[bb].cross(p - v.bodyPosition[bb]);
    BondForce f = law_[k]->bondForce(bond, n, overlap, va - vb, dt);
    point_[k] = p;
    if (f.broke) {
      ++broke;
      released_ += f.released;
    } else {
      elastic_ += f.elastic;
      damping_ += f.damping;
    }
    force_[k] = f;
  }
  if (broke == 0) return 0;
  // Keep the survivors in order; the broken pairs are now the sphere-pair contacts' to find.
  std::size_t kept = 0;
  for (std::size_t k = 0; k < bonds_.size(); ++k) {
    if (force_[k].broke) continue;
    bonds_[kept] = bonds_[k], law_[kept] = law_[k], force_[kept] = force_[k], point_[kept] = point_[k];
    ++kept;
  }
  bonds_.resize(kept), law_.resize(kept), force_.resize(kept), point_.resize(kept);
  broken_ += static_cast<std::int64_t>(broke);
  index(partnerStart_.size() - 1);
  return broke;
}

void BondSet::scatter(const View& v, Vec3* force, Vec3* torque) const {
  for (std::size_t k = 0; k < bonds_.size(); ++k) {
    const Bond& bond = bonds_[k];
    const Vec3& f = force_[k].force;
    force[bond.a] += f;
    force[bond.b] -= f;
    if (torque) {
      torque[bond.a] += (point_[k] - v.centre[bond.a]).cross(f);
      torque[bond.b] += (point_[k] - v.centre[bond.b]).cross(Vec3(-f));
    }
  }
}

std::vector<BondSet::Line> BondSet::lines() const {
  std::vector<Line> out;
  out.reserve(bonds_.size());
  for (std::size_t k = 0; k < bonds_.size(); ++k) out.push_back({bonds_[k].a, bonds_[k].b, force_[k].normalForce});
  return out;
}

void BondSet::archive(common::StateArchive& a) {
  a.io("bonds", bonds_), a.io("force", force_), a.io("point", point_), a.io("partner_start", partnerStart_);
  a.io("partner", partner_), a.io("ever_bonded", everBonded_), a.io("created", created_), a.io("broken", broken_);
  a.io("elastic", elastic_), a.io("damping", damping_), a.io("released", released_);
}

void BondSet::replace(std::vector<Bond> bonds, std::vector<std::uint8_t> everBonded, const LawOf& lawOf, bool formed) {
  std::sort(bonds.begin(), bonds.end(), [](const Bond& x, const Bond& y) { return std::pair(x.a, x.b) < std::pair(y.a, y.b); });
  bonds_ = std::move(bonds);
  everBonded_ = std::move(everBonded);
  relink(lawOf);
  force_.assign(bonds_.size(), BondForce{});
  point_.assign(bonds_.size(), Vec3::Zero());
  index(everBonded_.size());
  received_ = received_ || formed;
}

void BondSet::relink(const LawOf& lawOf) {
  law_.resize(bonds_.size());
  for (std::size_t k = 0; k < bonds_.size(); ++k) law_[k] = lawOf(bonds_[k].a, bonds_[k].b);
}

std::vector<double> pieceMasses(std::size_t bodies, const std::vector<std::pair<std::uint64_t, std::uint64_t>>& links,
                                const std::vector<std::pair<std::uint64_t, double>>& masses) {
  std::vector<std::uint64_t> parent(bodies);
  std::iota(parent.begin(), parent.end(), std::uint64_t{0});
  auto find = [&](std::uint64_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  for (const auto& [a, b] : links) parent[find(a)] = find(b);
  std::vector<double> mass(bodies, 0.0);
  for (const auto& [b, m] : masses) mass[find(b)] += m;
  std::vector<double> out;
  for (double m : mass)
    if (m > 0.0) out.push_back(m);
  std::sort(out.begin(), out.end(), std::greater<>());
  return out;
}

}  // namespace dem
