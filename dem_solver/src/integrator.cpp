#include "integrator.hpp"

#include <omp.h>

#include <algorithm>
#include <array>
#include <cmath>

#include "avx2_rows.hpp"
#include "common/errors.hpp"
#include "contact/batch_law.hpp"
#include "ordered_sum.hpp"
#include "per_thread.hpp"

namespace dem {

namespace {
// Torque-free rotation of a rigid body over dt with world angular momentum L held fixed, by the symplectic
// splitting of Dullweber, Leimkuhler & McLachlan (1997): exact rotations about the principal axes
// 1 (dt/2), 2 (dt/2), 3 (dt), 2 (dt/2), 1 (dt/2). Each conserves L exactly; the energy error is bounded.
Quat freeRotation(Quat q, const Vec3& L, const Vec3& I, double dt) {
  Vec3 pi = q.conjugate() * L;  // body-frame angular momentum
  auto rotate = [&](int axis, double tau) {
    const double angle = tau * pi[axis] / I[axis];
    const Eigen::AngleAxisd r(angle, Vec3::Unit(axis));
    q = (q * Quat(r)).normalized();
    pi = r.inverse() * pi;
  };
  rotate(0, 0.5 * dt);
  rotate(1, 0.5 * dt);
  rotate(2, dt);
  rotate(1, 0.5 * dt);
  rotate(0, 0.5 * dt);
  return q;
}

#if defined(__x86_64__) && defined(__GNUC__)
using detail::loadRows, detail::rowDots, detail::storeRows, detail::vadd, detail::vdiv, detail::vmul;

// The vectorised integrator's loop (Integrator::loneVector) for bodies b0 .. b0 + n, four
// at a time with AVX2. The update is the same for each component, so four bodies' Vec3 rows (12
// doubles) are worked on as they lie in memory, their masses and the gravity spread to match; only the
// energy terms' dot products are transposed into lanes (GCC's own vectorisation of the stride-3 arrays
// moved them element by element, on the x86-64 baseline; transposing every row in and out cost more
// shuffles than arithmetic). The same operations in the same order, so the same bits. Lone spheres'
// inertia is isotropic: I holds one moment per body, spread like the masses. Without external forces
// (kExternal false) E is not read: its zeros are added as constants, for the same bits and 24 bytes a
// body less to load (this loop is bound by memory traffic). Returns how many bodies it did (a multiple
// of 4).
template <bool kRotation, bool kExternal>
DEM_TARGET_AVX2 std::ptrdiff_t integrateLoneFourAvx2(double* X, double* V, double* W, double* L, const double* F,
                                                     const double* T, const double* E, const double* I, const double* M,
                                                     std::ptrdiff_t b0, std::ptrdiff_t n, double dt, const Vec3& g,
                                                     double* pe, double* ke1, double* ke2, double* ex) {
  const __m256d DT = _mm256_set1_pd(dt), half = _mm256_set1_pd(0.5);
  const __m256d G[3] = {_mm256_setr_pd(g.x(), g.y(), g.z(), g.x()), _mm256_setr_pd(g.y(), g.z(), g.x(), g.y()),
                        _mm256_setr_pd(g.z(), g.x(), g.y(), g.z())};
  std::ptrdiff_t i = 0;
  for (; i + 4 <= n; i += 4) {
    const std::ptrdiff_t b = b0 + i, k = 3 * b;
    const __m256d m = _mm256_loadu_pd(M + b);
    // m0 m0 m0 m1 | m1 m1 m2 m2 | m2 m3 m3 m3: each body's mass under its row's components.
    const __m256d mr[3] = {_mm256_permute4x64_pd(m, 0b01000000), _mm256_permute4x64_pd(m, 0b10100101),
                           _mm256_permute4x64_pd(m, 0b11111110)};
    __m256d x[3], v0[3], f[3], e[3] = {_mm256_setzero_pd(), _mm256_setzero_pd(), _mm256_setzero_pd()}, v1[3];
    loadRows(X + k, x), loadRows(V + k, v0), loadRows(F + k, f);
    if constexpr (kExternal) loadRows(E + k, e);
    _mm256_storeu_pd(pe + i, vmul(m, rowDots(G, x)));
    for (int r = 0; r < 3; ++r) {
      const __m256d total = vadd(vadd(f[r], vmul(mr[r], G[r])), e[r]);
      v1[r] = vadd(v0[r], vmul(vdiv(total, mr[r]), DT));
      x[r] = vadd(x[r], vmul(v1[r], DT));
    }
    storeRows(V + k, v1);
    storeRows(X + k, x);
    _mm256_storeu_pd(ke1 + i, vmul(vmul(half, m), rowDots(v0, v1)));
    _mm256_storeu_pd(ex + i, vmul(rowDots(e, v0), DT));
    if constexpr (kRotation) {
      __m256d w0[3], l[3], t[3], w1[3];
      loadRows(W + k, w0), loadRows(L + k, l), loadRows(T + k, t);
      const __m256d moment = _mm256_loadu_pd(I + b);
      const __m256d inertia[3] = {_mm256_permute4x64_pd(moment, 0b01000000), _mm256_permute4x64_pd(moment, 0b10100101),
                                  _mm256_permute4x64_pd(moment, 0b11111110)};
      for (int r = 0; r < 3; ++r) l[r] = vadd(l[r], vmul(t[r], DT));
      _mm256_storeu_pd(ke2 + i, vmul(half, rowDots(w0, l)));
      for (int r = 0; r < 3; ++r) w1[r] = vdiv(l[r], inertia[r]);
      storeRows(L + k, l);
      storeRows(W + k, w1);
    }
  }
  return i;
}
#endif
}  // namespace

void Integrator::prepare(const Bodies& bodies, bool loneSpheres) {
  prepared_.loneSpheres = loneSpheres;
  prepared_.loneInertia.clear();
  if (prepared_.loneSpheres)
    for (const Vec3& I : bodies.inertia) prepared_.loneInertia.push_back(I.x());
  prepared_.anyFixed = std::any_of(bodies.fixed.begin(), bodies.fixed.end(), [](auto f) { return f != 0; });
}

// The general integrator (advance()), for bodies that are lone spheres: the same arithmetic in the same order
// (same bits), without the per-body dispatch and with the energy sums in registers — through a reference
// to memory each body's additions waited on the previous body's store.
template <bool kRotation, bool kCundall>
void Integrator::lone(Bodies& bodies, const SimulationSettings& settings, std::array<double, 5>& sums) {
  const double dt = settings.dt;
  const Vec3 g = settings.gravity;
  const double lambda = settings.localDamping;
  Bodies& B = bodies;
  const auto nb = static_cast<std::ptrdiff_t>(B.size());
  struct Sums {
    double kinetic = 0.0, potential = 0.0, cundall = 0.0, external = 0.0;
  };
  auto body = [&](std::ptrdiff_t b, Sums& sum) __attribute__((always_inline)) {
    if (B.fixed[b]) {
      B.position[b] += B.velocity[b] * dt;
      return;
    }
    const double m = B.mass[b];
    sum.potential -= m * g.dot(B.position[b]);
    Vec3 f = B.force[b] + m * g + B.externalForce[b];
    Vec3 t = B.torque[b];
    const Vec3 v0 = B.velocity[b], w0 = B.angularVelocity[b];
    if constexpr (kCundall) {
      for (int k = 0; k < 3; ++k) {
        const double df = lambda * std::abs(f[k]) * (v0[k] > 0 ? 1.0 : v0[k] < 0 ? -1.0 : 0.0);
        f[k] -= df;
        sum.cundall += df * v0[k] * dt;
        const double dtq = lambda * std::abs(t[k]) * (w0[k] > 0 ? 1.0 : w0[k] < 0 ? -1.0 : 0.0);
        t[k] -= dtq;
        sum.cundall += dtq * w0[k] * dt;
      }
    }
    const Vec3 v1 = v0 + f / m * dt;
    B.velocity[b] = v1;
    B.position[b] += v1 * dt;
    sum.kinetic += 0.5 * m * v0.dot(v1);
    sum.external += B.externalForce[b].dot(v0) * dt;
    if constexpr (kRotation) {
      const Vec3 L1 = B.angularMomentum[b] + t * dt;
      B.angularMomentum[b] = L1;
      sum.kinetic += 0.5 * w0.dot(L1);
      B.angularVelocity[b] = L1 / B.inertia[b].x();
    }
  };
  // orderedSum's partition and order of sums, so the bits are the general integrator's on any threads.
  auto add = [&](const Sums& s) {
    sums[0] += s.kinetic, sums[1] += s.potential, sums[2] += s.cundall, sums[3] += s.external;
  };
  const int nt = nb > kParallelMin ? omp_get_max_threads() : 1;
  if (nt == 1) {
    Sums mine;
    for (std::ptrdiff_t b = 0; b < nb; ++b) body(b, mine);
    add(mine);
    return;
  }
  detail::PerThread<Sums> partial(static_cast<std::size_t>(nt));
#pragma omp parallel num_threads(nt)
  {
    Sums mine;
#pragma omp for schedule(static)
    for (std::ptrdiff_t b = 0; b < nb; ++b) body(b, mine);
    partial[static_cast<std::size_t>(omp_get_thread_num())] = mine;
  }
  partial.forEach(add);
}

// lone() without local damping or fixed bodies, vectorised across bodies: blocks of 64
// bodies are moved in a loop without branches, each body's energy terms kept aside, then added to the
// sums body by body in the same order — the same bits. Threads take equal contiguous runs of bodies
// (orderedSum's partition when the bodies divide evenly).
template <bool kRotation>
void Integrator::loneVector(Bodies& bodies, const SimulationSettings& settings, bool externalForces,
                            std::array<double, 5>& sums) {
  const double dt = settings.dt;
  const double gx = settings.gravity.x(), gy = settings.gravity.y(), gz = settings.gravity.z();
  Bodies& B = bodies;
  const auto nb = static_cast<std::ptrdiff_t>(B.size());
  if (nb == 0) return;
  double* X = B.position.data()->data();
  double* V = B.velocity.data()->data();
  double* W = B.angularVelocity.data()->data();
  double* L = B.angularMomentum.data()->data();
  const double* F = B.force.data()->data();
  const double* T = B.torque.data()->data();
  const double* E = B.externalForce.data()->data();
  const double* I = B.inertia.data()->data();
  COSIM_ASSERT(prepared_.loneInertia.size() == B.size(), "lone-sphere inertia out of date: bodies added after initialize()");
  const double* moment = prepared_.loneInertia.data();
  const double* M = B.mass.data();
  struct Sums {
    double kinetic = 0.0, potential = 0.0, external = 0.0;
  };
  auto range = [&](std::ptrdiff_t lo, std::ptrdiff_t hi, Sums& sum) {
    constexpr std::ptrdiff_t kChunk = 64;
    alignas(64) double pe[kChunk], ke1[kChunk], ke2[kChunk], ex[kChunk];
    for (std::ptrdiff_t b0 = lo; b0 < hi; b0 += kChunk) {
      const std::ptrdiff_t n = std::min(kChunk, hi - b0);
      std::ptrdiff_t done = 0;
#if defined(__x86_64__) && defined(__GNUC__)
      if (detail::useAvx2())
        done = externalForces ? integrateLoneFourAvx2<kRotation, true>(X, V, W, L, F, T, E, moment, M, b0, n, dt,
                                                                        settings.gravity, pe, ke1, ke2, ex)
                               : integrateLoneFourAvx2<kRotation, false>(X, V, W, L, F, T, E, moment, M, b0, n, dt,
                                                                         settings.gravity, pe, ke1, ke2, ex);
#endif
#pragma omp simd
      for (std::ptrdiff_t i = done; i < n; ++i) {
        const std::ptrdiff_t b = b0 + i, k = 3 * b;
        const double m = M[b];
        const double x0 = X[k], x1 = X[k + 1], x2 = X[k + 2];
        const double v0x = V[k], v0y = V[k + 1], v0z = V[k + 2];
        pe[i] = m * ((gx * x0 + gy * x1) + gz * x2);
        const double fx = (F[k] + m * gx) + E[k], fy = (F[k + 1] + m * gy) + E[k + 1], fz = (F[k + 2] + m * gz) + E[k + 2];
        const double v1x = v0x + fx / m * dt, v1y = v0y + fy / m * dt, v1z = v0z + fz / m * dt;
        V[k] = v1x, V[k + 1] = v1y, V[k + 2] = v1z;
        X[k] = x0 + v1x * dt, X[k + 1] = x1 + v1y * dt, X[k + 2] = x2 + v1z * dt;
        ke1[i] = 0.5 * m * ((v0x * v1x + v0y * v1y) + v0z * v1z);
        ex[i] = ((E[k] * v0x + E[k + 1] * v0y) + E[k + 2] * v0z) * dt;
        if constexpr (kRotation) {
          const double w0x = W[k], w0y = W[k + 1], w0z = W[k + 2];
          const double l1x = L[k] + T[k] * dt, l1y = L[k + 1] + T[k + 1] * dt, l1z = L[k + 2] + T[k + 2] * dt;
          ke2[i] = 0.5 * ((w0x * l1x + w0y * l1y) + w0z * l1z);
          L[k] = l1x, L[k + 1] = l1y, L[k + 2] = l1z;
          const double inertia = I[k];
          W[k] = l1x / inertia, W[k + 1] = l1y / inertia, W[k + 2] = l1z / inertia;
        }
      }
      for (std::ptrdiff_t i = 0; i < n; ++i) {
        sum.potential -= pe[i];
        sum.kinetic += ke1[i];
        sum.external += ex[i];
        if constexpr (kRotation) sum.kinetic += ke2[i];
      }
    }
  };
  const int nt = nb > kParallelMin ? omp_get_max_threads() : 1;
  detail::PerThread<Sums> partial(static_cast<std::size_t>(nt));
  detail::forEachPart(nt, [&](std::size_t part) {
    const auto t = static_cast<std::ptrdiff_t>(part), chunk = (nb + nt - 1) / nt;
    Sums mine;  // stored to `partial` once: range() stores its sums around each block's AVX2 call
    range(std::min(nb, t * chunk), std::min(nb, (t + 1) * chunk), mine);
    partial[part] = mine;
  });
  partial.forEach([&](const Sums& p) { sums[0] += p.kinetic, sums[1] += p.potential, sums[3] += p.external; });
}

Integrator::StepEnergy Integrator::advance(Bodies& bodies, const Spheres& spheres,
                                            const SimulationSettings& settings, bool rotation, bool externalForces) {
  const double dt = settings.dt;
  // The scene gives v(0): the first kick is half a step, v(dt/2) = v(0) + a(0) dt/2, so a constant
  // acceleration is integrated exactly (x0 + v0 t + a t²/2); every later kick is a whole step.
  const bool first = steps_ == 0;
  const double kick = first ? 0.5 * dt : dt;
  const Vec3 g = settings.gravity;
  const double lambda = settings.localDamping;
  // kinetic, potential, Cundall, external work, and at the first step the shadow form's shift (below)
  std::array<double, 5> sums{};
  const auto nb = static_cast<std::ptrdiff_t>(bodies.size());
  if (prepared_.loneSpheres && !first) {
    if (rotation) {
      if (lambda > 0.0) lone<true, true>(bodies, settings, sums);
      else if (prepared_.anyFixed) lone<true, false>(bodies, settings, sums);
      else loneVector<true>(bodies, settings, externalForces, sums);
    } else {
      if (lambda > 0.0) lone<false, true>(bodies, settings, sums);
      else if (prepared_.anyFixed) lone<false, false>(bodies, settings, sums);
      else loneVector<false>(bodies, settings, externalForces, sums);
    }
  } else detail::orderedSum(nb, sums, [&](std::ptrdiff_t b, std::array<double, 5>& sum) {
    double& kinetic = sum[0];
    double& potential = sum[1];
    double& cundall = sum[2];
    double& external = sum[3];
    double& shift = sum[4];  // first step: shadow kinetic energy at t = 0 minus ½ m v(0)²
    if (bodies.fixed[b]) {
      bodies.position[b] += bodies.velocity[b] * dt;
      return;
    }
    const double m = bodies.mass[b];
    potential -= m * g.dot(bodies.position[b]);
    Vec3 f = bodies.force[b] + m * g + bodies.externalForce[b];
    Vec3 t = bodies.torque[b];
    const Vec3 v0 = bodies.velocity[b], w0 = bodies.angularVelocity[b];
    if (lambda > 0.0) {
      // Cundall & Strack local damping, per component against the velocity (YADE NewtonIntegrator form).
      for (int k = 0; k < 3; ++k) {
        const double df = lambda * std::abs(f[k]) * (v0[k] > 0 ? 1.0 : v0[k] < 0 ? -1.0 : 0.0);
        f[k] -= df;
        cundall += df * v0[k] * dt;
        const double dtq = lambda * std::abs(t[k]) * (w0[k] > 0 ? 1.0 : w0[k] < 0 ? -1.0 : 0.0);
        t[k] -= dtq;
        cundall += dtq * w0[k] * dt;
      }
    }
    const Vec3 v1 = v0 + f / m * kick;
    bodies.velocity[b] = v1;
    bodies.position[b] += v1 * dt;
    // The shadow form ½ m v(t−dt/2)·v(t+dt/2); at t = 0, v(−dt/2) = v(0) − a(0) dt/2 = 2 v(0) − v(dt/2).
    const Vec3 vm = first ? Vec3(2.0 * v0 - v1) : v0;
    kinetic += 0.5 * m * vm.dot(v1);
    if (first) shift += 0.5 * m * (vm.dot(v1) - v0.squaredNorm());
    external += bodies.externalForce[b].dot(v0) * dt;
    if (rotation) {
      const Vec3 L0 = bodies.angularMomentum[b];
      const Vec3 L1 = L0 + t * kick;
      bodies.angularMomentum[b] = L1;
      const Vec3& I = bodies.inertia[b];
      Quat& q = bodies.orientation[b];
      // At t = 0, ω(−dt/2) from L(−dt/2) = 2 L(0) − L(dt/2) in the orientation at t = 0.
      const Vec3 wm = first ? Vec3(2.0 * w0 - q * (q.conjugate() * L1).cwiseQuotient(I)) : w0;
      kinetic += 0.5 * wm.dot(L1);
      if (first) shift += 0.5 * (wm.dot(L1) - w0.dot(L0));
      if (I.x() == I.y() && I.y() == I.z()) {
        const Vec3 w1 = L1 / I.x();
        bodies.angularVelocity[b] = w1;
        // A lone sphere at its centre looks the same in any orientation: skip the trigonometry.
        if (bodies.sphereCount[b] > 1 || spheres.local[bodies.firstSphere[b]].squaredNorm() > 0.0) {
          const double angle = w1.norm() * dt;
          if (angle > 0.0) q = (Quat(Eigen::AngleAxisd(angle, w1.normalized())) * q).normalized();
        }
      } else {
        q = freeRotation(q, L1, I, dt);
        bodies.angularVelocity[b] = q * (q.conjugate() * L1).cwiseQuotient(I);
      }
    }
  });
  ++steps_;
  time_ = static_cast<double>(steps_) * dt;  // no drift from summing dt
  return {sums[0], sums[1], sums[2], sums[3], sums[4]};
}

}  // namespace dem
