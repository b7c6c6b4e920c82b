#include "sphere_pairs.hpp"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <numeric>

#include "contact/batch_law.hpp"
#include "contact/tangential.hpp"

namespace dem {

namespace {
// Above this many lone spheres the contact pass prefetches (SpherePairView::prefetch): their per-sphere
// arrays (120 bytes a sphere) no longer fit the per-core L2 cache with the candidates' state.
constexpr std::size_t kPrefetchSpheres = 20000;
}  // namespace

void SpherePairs::assign(const StepContext& ctx, std::vector<Triple>& pairs) {
  const Spheres& spheres = ctx.spheres;
  const Bodies& bodies = ctx.bodies;
  contacts_.assign(pairs, ctx.laws.size(), ctx.rolling);
  // R* and m* are fixed for a pair: set once here, not per step in the force pass.
  ContactSet& ss = contacts_;
  ss.effRadius.resize(ss.size());  // the first build: assign() found none to keep
  ss.effMass.resize(ss.size());
  // δ of the last pass where it touched (its history's), else 0: the pass reads it to find the pairs that
  // just opened (SpherePairView::overlap), then writes every candidate's.
  detail::resizeOver(ss.overlap, ss.size());
  const auto nss = static_cast<std::ptrdiff_t>(ss.size());
#pragma omp parallel for schedule(static) if (nss > kParallelMin)
  for (std::ptrdiff_t k = 0; k < nss; ++k) {
    ss.overlap[k] = ss.history[k].lastOverlap;
    if (ss.effRadius[k] > 0.0) continue;  // a surviving pair's, kept by assign()
    const auto i = ss.a[k], j = ss.b[k], bi = spheres.body[i], bj = spheres.body[j];
    const double ri = spheres.radius[i], rj = spheres.radius[j];
    ss.effRadius[k] = ri * rj / (ri + rj);
    ss.effMass[k] = detail::reduced(bodies.mass[bi], bodies.mass[bj], infiniteMass(bodies.fixed[bi]), infiniteMass(bodies.fixed[bj]));
  }
  if (ctx.rolling)  // the rolling pass reads them from the contact points
    for (std::size_t k = 0; k < ss.size(); ++k) ss.point[k].effRadius = ss.effRadius[k], ss.point[k].effMass = ss.effMass[k];
}

void SpherePairs::computeForces(const StepContext& ctx, double& wait) {
  const Spheres& spheres = ctx.spheres;
  const Bodies& bodies = ctx.bodies;
  const bool rolling = ctx.rolling;
  ContactSet& ss = contacts_;
  std::vector<double>& threadSeconds = work_->threadSeconds;
  threadSeconds.resize(static_cast<std::size_t>(std::max(1, omp_get_max_threads())));
  // Without rolling resistance nothing reads the pairs' contact points or forces after the pass
  // (bodyContacts takes the bodies' sums): not stored, 32 to 136 bytes per touching pair and step. The
  // energies are summed in the pass unless rolling resistance adds to them after.
  const SpherePairView pairs{ss.a.data(), ss.b.data(), ss.effRadius.data(), ss.effMass.data(), ss.overlap.data(),
                             ss.point.data(), rolling, ss.history.data(), rolling ? ss.force.data() : nullptr,
                             ctx.centres, spheres.radius.data(), spheres.body.data(),
                             bodies.position.data(), bodies.velocity.data(), bodies.angularVelocity.data(),
                             ctx.loneSpheres, ctx.force, ctx.rotation ? ctx.torque : nullptr,
                             rolling ? nullptr : energy_.data(),
                             ctx.loneSpheres && spheres.size() > kPrefetchSpheres, threadSeconds.data()};
  energy_ = {};
  energySummed_ = pairs.energy != nullptr;
  for (std::size_t l = 0; l < ctx.laws.size(); ++l) {
    const auto [begin, end] = ss.ranges[l];
    if (begin == end) continue;
    std::fill(threadSeconds.begin(), threadSeconds.end(), 0.0);
    ctx.laws[l]->computeSpherePairs(pairs, begin, end, ctx.settings.dt);
    const double slowest = *std::max_element(threadSeconds.begin(), threadSeconds.end());
    const double mean = std::accumulate(threadSeconds.begin(), threadSeconds.end(), 0.0) /
                        static_cast<double>(std::count_if(threadSeconds.begin(), threadSeconds.end(),
                                                          [](double t) { return t > 0.0; }));
    if (slowest > 0.0) wait += slowest - mean;
  }
}

void SpherePairs::applyRollingResistance(const StepContext& ctx) {
  // A couple per touching contact whose law has μ_r > 0, after the forces are summed to the spheres (its
  // dissipation joins the contact's friction energy, summed by step()). I = 2/5 m R² per sphere caps it.
  const double dt = ctx.settings.dt;
  const Spheres& spheres = ctx.spheres;
  const Bodies& bodies = ctx.bodies;
  ContactSet& ss = contacts_;
  for (std::size_t k = 0; k < ss.size(); ++k) {
    const double muR = ctx.laws[static_cast<std::size_t>(ss.law[k])]->rollingFriction();
    const ContactPoint& p = ss.point[k];
    if (muR == 0.0 || p.overlap <= 0.0) continue;
    const auto a = ss.a[k], b = ss.b[k], ba = spheres.body[a], bb = spheres.body[b];
    const double ia = ctx.rollingInertia(a), ib = ctx.rollingInertia(b);
    const double eff = detail::reduced(ia, ib, infiniteMass(bodies.fixed[ba]), infiniteMass(bodies.fixed[bb]));
    const Vec3 m = detail::rollingTorque(p.normal, bodies.angularVelocity[ba] - bodies.angularVelocity[bb], p.effRadius,
                                         eff, muR, ss.force[k].normalForce, dt, ss.force[k]);
    ctx.torque[a] += m;
    ctx.torque[b] -= m;
  }
}

double SpherePairs::overlap(std::size_t k, const Spheres& spheres) const {
  const ContactSet& ss = contacts_;
  const double stored = ss.overlap[k];
  if (stored > 0.0) return stored;
  // Open: −d² is stored (SpherePairView::overlap).
  return std::min(spheres.radius[ss.a[k]] + spheres.radius[ss.b[k]] - std::sqrt(-stored), 0.0);
}

void SpherePairs::addStiffness(const std::vector<std::unique_ptr<ContactLaw>>& laws, const Spheres& spheres,
                               const Bodies& bodies, BodyStiffness& out) const {
  // Each touching pair's terms (the law's stiffness, the couplings' square roots) are computed on every
  // thread, a block of contacts at a time, each thread taking a run of the block, and handed to the thread
  // that adds the sums of the term's body. Each thread then adds the terms handed to it, the lists in the
  // order of the runs: every body's sum has the order of one pass over the contacts, the same bits on any
  // number of threads. The bodies are dealt to the threads in groups of 64 (512 bytes of each sum), round
  // the threads: a block's contacts touch a narrow band of bodies (they are sorted by sphere), which
  // contiguous ranges would leave to one thread. Until 2026-12-06 every thread scanned all of a block's
  // terms for its own. The block bounds the lists to two 24-byte terms per contact of it, about 768 kB in all,
  // whatever the number of pairs.
  const ContactSet& pairs = contacts_;
  constexpr std::size_t kTermBlock = 1 << 14;
  const std::size_t nt = static_cast<std::ptrdiff_t>(pairs.size()) > kParallelMin ? omp_get_max_threads() : 1;
  auto termsOf = [&](std::size_t i) {
    const auto k = laws[static_cast<std::size_t>(pairs.law[i])]->normalTangent(pairs.effRadius[i], pairs.effMass[i],
                                                                            pairs.overlap[i]);
    return BodyStiffness::pairTerms(bodies, spheres.body[pairs.a[i]], spheres.body[pairs.b[i]], k.stiffness, k.damping);
  };
  if (nt == 1) {  // the same order without the lists
    for (std::size_t i = 0; i < pairs.size(); ++i)
      if (pairs.overlap[i] > 0.0) out.add(termsOf(i));
    return;
  }
  struct Term {
    std::uint32_t body;
    double k, c;
  };
  // handed[s][r]: the terms of run s for the bodies of thread r, in contact order.
  detail::PerThread<std::vector<std::vector<Term>>> handed(nt, std::vector<std::vector<Term>>(nt));
  auto adderOf = [&](std::uint32_t body) { return static_cast<std::size_t>(body / 64) % nt; };
  for (std::size_t from = 0; from < pairs.size(); from += kTermBlock) {
    const std::size_t n = std::min(kTermBlock, pairs.size() - from);
    detail::forEachPart(static_cast<int>(nt), [&](std::size_t s) {
      std::vector<std::vector<Term>>& lists = handed[s];
      for (std::vector<Term>& l : lists) l.clear();
      for (std::size_t i = from + n * s / nt; i < from + n * (s + 1) / nt; ++i) {
        if (!(pairs.overlap[i] > 0.0)) continue;
        const BodyStiffness::PairTerms p = termsOf(i);
        lists[adderOf(p.a)].push_back({p.a, p.ka, p.ca});
        lists[adderOf(p.b)].push_back({p.b, p.kb, p.cb});
      }
    });
    detail::forEachPart(static_cast<int>(nt), [&](std::size_t r) {
      for (std::size_t s = 0; s < nt; ++s)
        for (const Term& t : handed[s][r]) out.add(t.body, t.k, t.c);
    });
  }
}

}  // namespace dem
