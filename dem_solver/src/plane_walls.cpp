#include "plane_walls.hpp"

#include <omp.h>

#include <array>

#include "contact/batch_law.hpp"
#include "contact/tangential.hpp"
#include "per_thread.hpp"

namespace dem {

void PlaneWalls::rebuildCandidates(const StepContext& ctx) {
  const Spheres& spheres = ctx.spheres;
  const std::size_t ns = spheres.size();
  const double skin = ctx.settings.skin;
  // Threads take contiguous runs of spheres; their lists joined in order are the one-thread list.
  const int nt = static_cast<std::ptrdiff_t>(ns) > kParallelMin ? omp_get_max_threads() : 1;
  auto& local = work_->lists.local;
  local.resize(static_cast<std::size_t>(nt));
  local.forEach([](std::vector<Triple>& l) { l.clear(); });
  std::vector<Triple>& wallPairs = work_->lists.joined;
  wallPairs.clear();
#pragma omp parallel num_threads(nt) if (nt > 1)
  {
    const auto thread = static_cast<std::size_t>(omp_get_thread_num());
    auto& mine = thread == 0 ? wallPairs : local[thread];
#pragma omp for schedule(static)
    for (std::ptrdiff_t si = 0; si < static_cast<std::ptrdiff_t>(ns); ++si) {
      const auto s = static_cast<std::uint32_t>(si);
      if (ghost(ctx.bodies.fixed[spheres.body[s]])) continue;  // its own rank computes its wall contacts
      for (std::uint32_t w = 0; w < walls_.size(); ++w) {
        const double d = (spheres.position[s] - walls_[w].point).dot(walls_[w].normal);
        const int law = ctx.lawOf[spheres.material[s] * ctx.materials + walls_[w].material];
        if (law >= 0 && d < spheres.radius[s] + skin) mine.emplace_back(law, s, w);
      }
    }
    detail::joinInOrder(local, thread, wallPairs);
  }
  contacts_.assign(wallPairs, ctx.laws.size());
  ContactSet& sw = contacts_;
  for (std::size_t k = 0; k < sw.size(); ++k) {
    sw.point[k].effRadius = spheres.radius[sw.a[k]];
    sw.point[k].effMass = ctx.bodies.mass[spheres.body[sw.a[k]]];
  }
}

void PlaneWalls::computeContacts(const StepContext& ctx) {
  // The plane candidates' geometry, law and sums in one pass, in candidate order: through contact points
  // written out and read back by three loops and three thread teams they cost as much as the pairs'
  // integration. Threads take runs of candidates cut between spheres (the candidates are sorted by
  // sphere), so each adds to its own spheres; their plane forces and energies are added in thread order.
  // Without rolling resistance the contacts' forces are not stored, only their energies summed
  // (energy()): nothing else reads them.
  ContactSet& sw = contacts_;
  const Bodies& bodies = ctx.bodies;
  const Spheres& spheres = ctx.spheres;
  const Vec3* centre = ctx.centres;
  Vec3* force = ctx.force;
  Vec3* torque = ctx.torque;
  const double dt = ctx.settings.dt;
  const bool rotation = ctx.rotation, rolling = ctx.rolling, loneSpheres = ctx.loneSpheres;
  const int nt = static_cast<std::ptrdiff_t>(sw.size()) > kParallelMin ? omp_get_max_threads() : 1;
  work_->blocks.resize(static_cast<std::size_t>(nt));
  // Per thread, per plane; one thread's planes a false-sharing range from the next one's.
  const std::size_t stride = walls_.size() + (detail::kFalseSharingRange + sizeof(Vec3) - 1) / sizeof(Vec3);
  std::vector<Vec3> partial(stride * static_cast<std::size_t>(nt), Vec3::Zero());
  energySummed_ = !rolling;
  std::vector<std::array<double, 3>> energy(static_cast<std::size_t>(nt), std::array<double, 3>{});
  for (std::size_t l = 0; l < ctx.laws.size(); ++l) {
    // Plain variables, not a structured binding: the lambda below captures them (clang 14 cannot).
    const std::size_t begin = sw.ranges[l].first, end = sw.ranges[l].second;
    if (begin == end) continue;
    const ContactLaw& law = *ctx.laws[l];
    const std::vector<std::size_t> cut = detail::runsBySideA(sw.a.data(), begin, end, nt);
    detail::forEachPart(nt, [&](std::size_t t) {
      if (!work_->blocks[t]) work_->blocks[t] = std::make_unique<detail::ContactBlock>();
      detail::ContactBlock& block = *work_->blocks[t];
      Vec3* planeForce = partial.data() + t * stride;
      std::array<Vec3, detail::kBlock> arm;  // contact point − sphere centre, per lane
      double elastic = energy[t][0], damping = energy[t][1], friction = energy[t][2];  // in registers
      auto flush = [&] {
        law.computeBlock(block, dt);
        for (int i = 0; i < block.n; ++i) {
          const std::size_t k = block.index[static_cast<std::size_t>(i)];
          if (rolling) {  // the rolling pass reads the force
            block.pull(i, sw.history[k], sw.force[k]);
          } else {
            block.pullHistory(i, sw.history[k]);
            elastic += block.elastic[i], damping += block.damping[i], friction += block.friction[i];
          }
          const Vec3 f(block.fx[i], block.fy[i], block.fz[i]);
          const auto s = sw.a[k];
          force[s] += f;
          if (rotation) torque[s] += arm[static_cast<std::size_t>(i)].cross(f);
          planeForce[sw.b[k]] -= f;
        }
        block.n = 0;
      };
      for (std::size_t k = cut[t]; k < cut[t + 1]; ++k) {
        // The candidates' spheres lie along the walls, scattered through the sphere arrays: fetch ahead.
        if (constexpr std::size_t kAhead = 8; k + kAhead < end) {
          const auto ahead = sw.a[k + kAhead];
          __builtin_prefetch(centre + ahead);
          if (loneSpheres) {
            __builtin_prefetch(bodies.velocity.data() + ahead);
            __builtin_prefetch(bodies.angularVelocity.data() + ahead);
            __builtin_prefetch(force + ahead, 1);
            __builtin_prefetch(torque + ahead, 1);
          }
        }
        const auto s = sw.a[k];
        const PlaneWall& w = walls_[sw.b[k]];
        ContactPoint& c = sw.point[k];
        const double r = spheres.radius[s];
        c.overlap = r - (centre[s] - w.point).dot(w.normal);
        if (c.overlap <= 0.0) {
          if (sw.history[k].lastOverlap != 0.0) sw.history[k] = ContactHistory{}, sw.force[k] = ContactForce{};
          continue;
        }
        // Normal, point and relative velocity are stored only for the rolling pass (their only reader).
        ContactPoint p;
        p.overlap = c.overlap, p.effRadius = c.effRadius, p.effMass = c.effMass;
        p.normal = w.normal;
        p.point = centre[s] - p.normal * (r - 0.5 * p.overlap);
        const auto body = spheres.body[s];
        p.relVelocity =
            bodies.velocity[body] + bodies.angularVelocity[body].cross(p.point - bodies.position[body]) - w.velocity;
        if (rolling) c = p;
        arm[static_cast<std::size_t>(block.n)] = p.point - centre[s];
        block.push(k, p, sw.history[k]);
        if (block.n == detail::kBlock) flush();
      }
      if (block.n > 0) flush();
      energy[t] = {elastic, damping, friction};
    });
  }
  energy_ = {};
  for (const auto& e : energy)
    for (std::size_t k = 0; k < 3; ++k) energy_[k] += e[k];
  for (std::size_t w = 0; w < walls_.size(); ++w) {
    forces_[w] = partial[w];
    for (std::size_t t = 1; t < static_cast<std::size_t>(nt); ++t) forces_[w] += partial[t * stride + w];
  }
}

void PlaneWalls::applyRollingResistance(const StepContext& ctx) {
  ContactSet& sw = contacts_;
  for (std::size_t k = 0; k < sw.size(); ++k) {
    const double muR = ctx.laws[static_cast<std::size_t>(sw.law[k])]->rollingFriction();
    const ContactPoint& p = sw.point[k];
    if (muR == 0.0 || p.overlap <= 0.0) continue;
    const auto s = sw.a[k];
    ctx.torque[s] += detail::rollingTorque(p.normal, ctx.bodies.angularVelocity[ctx.spheres.body[s]], p.effRadius,
                                           ctx.rollingInertia(s), muR, sw.force[k].normalForce, ctx.settings.dt,
                                           sw.force[k]);
  }
}

std::vector<double> PlaneWalls::contactStiffness(const std::vector<std::unique_ptr<ContactLaw>>& laws) const {
  std::vector<double> k(walls_.size(), 0.0);
  const ContactSet& walls = contacts_;
  for (std::size_t i = 0; i < walls.size(); ++i) {
    const ContactPoint& p = walls.point[i];
    if (!(p.overlap > 0.0)) continue;
    k[walls.b[i]] +=
        laws[static_cast<std::size_t>(walls.law[i])]->normalTangent(p.effRadius, p.effMass, p.overlap).stiffness;
  }
  return k;
}

void PlaneWalls::addStiffness(const std::vector<std::unique_ptr<ContactLaw>>& laws, const Spheres& spheres,
                              BodyStiffness& out) const {
  const ContactSet& walls = contacts_;
  for (std::size_t i = 0; i < walls.size(); ++i) {
    const ContactPoint& p = walls.point[i];
    if (!(p.overlap > 0.0)) continue;
    const auto t = laws[static_cast<std::size_t>(walls.law[i])]->normalTangent(p.effRadius, p.effMass, p.overlap);
    out.add(spheres.body[walls.a[i]], t.stiffness, t.damping);
  }
}

void PlaneWalls::move(double dt, double& wallWork) {
  for (std::size_t w = 0; w < walls_.size(); ++w) {
    wallWork += -forces_[w].dot(walls_[w].velocity) * dt;
    walls_[w].point += walls_[w].velocity * dt;
  }
}

}  // namespace dem
