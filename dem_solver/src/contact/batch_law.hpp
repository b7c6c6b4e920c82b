#pragma once
// The batch loop every contact law shares. A law supplies `blockForce`, the forces of a block of touching
// contacts held as structure of arrays (ContactBlock); this loop gathers the touching candidates into
// blocks, calls the law, and writes forces and histories back (and, for sphere pairs, computes the
// geometry first and scatters the forces to the spheres after). The law's loop over a block has no
// branches (selects), so the compiler vectorises it: one contact is a long chain of square roots and
// divisions, and several contacts in lock-step hide their latency.
#include <algorithm>
#include <array>

#include <Eigen/Geometry>

#include "dem/contact_law.hpp"

namespace dem::detail {

inline constexpr int kBlock = 64;

/// Touching contacts (δ > 0), structure of arrays, at most kBlock.
struct ContactBlock {
  int n = 0;
  std::array<std::size_t, kBlock> index;  ///< candidate index in the batch
  // Inputs: ContactPoint.
  alignas(64) double nx[kBlock], ny[kBlock], nz[kBlock];  ///< normal, b → a
  alignas(64) double vx[kBlock], vy[kBlock], vz[kBlock];  ///< v_a − v_b at the contact point
  alignas(64) double overlap[kBlock], effRadius[kBlock], effMass[kBlock];
  // History, read and updated (ContactHistory; lastOverlap is read only: the loop stores δ after).
  alignas(64) double sx[kBlock], sy[kBlock], sz[kBlock], lastOverlap[kBlock], lastHalf[kBlock];
  // Outputs: ContactForce.
  alignas(64) double fx[kBlock], fy[kBlock], fz[kBlock], fn[kBlock];
  alignas(64) double elastic[kBlock], damping[kBlock], friction[kBlock];

  void push(std::size_t k, const ContactPoint& p, const ContactHistory& h) {
    const int i = n++;
    index[static_cast<std::size_t>(i)] = k;
    nx[i] = p.normal.x(), ny[i] = p.normal.y(), nz[i] = p.normal.z();
    vx[i] = p.relVelocity.x(), vy[i] = p.relVelocity.y(), vz[i] = p.relVelocity.z();
    overlap[i] = p.overlap, effRadius[i] = p.effRadius, effMass[i] = p.effMass;
    sx[i] = h.shearForce.x(), sy[i] = h.shearForce.y(), sz[i] = h.shearForce.z();
    lastOverlap[i] = h.lastOverlap, lastHalf[i] = h.lastHalfCompliance;
  }
  /// Lane i's results into the candidate's history and force.
  void pull(int i, ContactHistory& h, ContactForce& f) const {
    h.shearForce = Vec3(sx[i], sy[i], sz[i]);
    h.lastOverlap = overlap[i];
    h.lastHalfCompliance = lastHalf[i];
    f.force = Vec3(fx[i], fy[i], fz[i]);
    f.normalForce = fn[i];
    f.elasticEnergy = elastic[i];
    f.dampingEnergy = damping[i];
    f.frictionEnergy = friction[i];
  }
};

template <class Derived>
class BatchLaw : public ContactLaw {
 public:
  void compute(std::span<const ContactPoint> points, std::span<ContactHistory> history, std::span<ContactForce> out,
               double dt) const final {
    const auto& law = static_cast<const Derived&>(*this);
    const auto n = static_cast<std::ptrdiff_t>(points.size());
    const std::ptrdiff_t chunks = (n + kChunk - 1) / kChunk;
#pragma omp parallel if (n > kParallelMin)
    {
      ContactBlock block;
      auto flush = [&] {
        law.blockForce(block, dt);
        for (int i = 0; i < block.n; ++i) {
          const std::size_t k = block.index[static_cast<std::size_t>(i)];
          block.pull(i, history[k], out[k]);
        }
        block.n = 0;
      };
#pragma omp for schedule(static)
      for (std::ptrdiff_t c = 0; c < chunks; ++c) {
        for (std::ptrdiff_t k = c * kChunk; k < std::min(n, (c + 1) * kChunk); ++k) {
          const auto kk = static_cast<std::size_t>(k);
          if (points[kk].overlap <= 0.0) {
            out[kk] = ContactForce{};
            history[kk] = ContactHistory{};
            continue;
          }
          block.push(kk, points[kk], history[kk]);
          if (block.n == kBlock) flush();
        }
        if (block.n > 0) flush();
      }
    }
  }

  void computeSpherePairs(const SpherePairView& v, std::size_t begin, std::size_t end, double dt) const final {
    const auto& law = static_cast<const Derived&>(*this);
    auto pointVelocity = [&](std::uint32_t body, const Vec3& x) -> Vec3 {
      return v.velocity[body] + v.angularVelocity[body].cross(x - v.bodyPosition[body]);
    };
    const auto first = static_cast<std::ptrdiff_t>(begin), last = static_cast<std::ptrdiff_t>(end);
    const std::ptrdiff_t chunks = (last - first + kChunk - 1) / kChunk;
    // Scattering to shared sphere sums must stay on one thread, in candidate order.
#pragma omp parallel if (last - first > kParallelMin && v.sphereForce == nullptr)
    {
      ContactBlock block;
      auto flush = [&] {
        law.blockForce(block, dt);
        for (int i = 0; i < block.n; ++i) {
          const std::size_t k = block.index[static_cast<std::size_t>(i)];
          ContactForce& f = v.force[k];
          block.pull(i, v.history[k], f);
          if (!v.sphereForce) continue;
          const auto a = v.a[k], b = v.b[k];
          v.sphereForce[a] += f.force;
          v.sphereForce[b] += -f.force;
          if (v.sphereTorque) {
            const Vec3& x = v.point[k].point;
            v.sphereTorque[a] += (x - v.position[a]).cross(f.force);
            v.sphereTorque[b] += (x - v.position[b]).cross(Vec3(-f.force));
          }
        }
        block.n = 0;
      };
#pragma omp for schedule(static)
      for (std::ptrdiff_t c = 0; c < chunks; ++c) {
        for (std::ptrdiff_t k = first + c * kChunk; k < std::min(last, first + (c + 1) * kChunk); ++k) {
          const auto kk = static_cast<std::size_t>(k);
          const auto i = v.a[kk], j = v.b[kk];
          ContactPoint& p = v.point[kk];
          const Vec3 d = v.position[i] - v.position[j];
          const double dist = d.norm();
          const double ri = v.radius[i], rj = v.radius[j];
          p.overlap = ri + rj - dist;
          if (p.overlap <= 0.0 || dist == 0.0) {
            p.overlap = std::min(p.overlap, 0.0);
            v.force[kk] = ContactForce{};
            v.history[kk] = ContactHistory{};
            continue;
          }
          p.normal = d * (1.0 / dist);
          p.point = v.position[j] + p.normal * (rj - 0.5 * p.overlap);
          p.relVelocity = pointVelocity(v.body[i], p.point) - pointVelocity(v.body[j], p.point);
          block.push(kk, p, v.history[kk]);
          if (block.n == kBlock) flush();
        }
        if (block.n > 0) flush();
      }
    }
  }

 private:
  static constexpr std::ptrdiff_t kChunk = 1024;  // candidates per OpenMP work item
};

}  // namespace dem::detail
