#pragma once
// Contact candidates of one kind with their histories (ContactSet), shared by the sphere pairs and the
// plane walls of dem::Simulation, and what their candidate searches share.
#include <omp.h>

#include <algorithm>
#include <cstdint>
#include <tuple>
#include <utility>
#include <vector>

#include "common/heap_bytes.hpp"
#include "common/state_archive.hpp"
#include "contact/batch_law.hpp"
#include "dem/contact_law.hpp"
#include "per_thread.hpp"

namespace dem {

namespace detail {

// `v` resized to n elements whose values are all about to be written: when it must grow, to n and an
// eighth more, its old values not copied. A vector's own growth doubles the capacity: a per-candidate
// array would then hold up to twice the candidates.
template <class T>
void resizeOver(std::vector<T>& v, std::size_t n) {
  if (n > v.capacity()) {
    v.clear();
    v.shrink_to_fit();
    v.reserve(n + n / 8);
  }
  v.resize(n);
}

}  // namespace detail

/// Contact candidates of one kind, sorted by (law, a, b) so each law's batch is contiguous.
struct ContactSet {
  std::vector<std::uint32_t> a, b;
  std::vector<int> law;
  std::vector<ContactPoint> point;
  std::vector<ContactHistory> history;
  std::vector<ContactForce> force;
  std::vector<std::pair<std::size_t, std::size_t>> ranges;  // per law (Interactions::laws()): [begin, end)
  // Sphere pairs only: R*, m* and this step's δ, compact for the contact pass (SpherePairView); their
  // `point` and `force` exist only with rolling resistance (its pass reads them). Sphere–plane
  // candidates: `point` holds R*, m* and this step's δ; its normal, point and relative velocity, and
  // `force`, are written only with rolling resistance (PlaneWalls::computeContacts; without it the pass
  // sums the energies).
  std::vector<double> effRadius, effMass, overlap;

  std::size_t size() const { return a.size(); }
  void archive(common::StateArchive& ar) {
    ar.io("a", a), ar.io("b", b), ar.io("law", law), ar.io("point", point), ar.io("history", history);
    ar.io("force", force), ar.io("ranges", ranges), ar.io("eff_radius", effRadius), ar.io("eff_mass", effMass);
    ar.io("overlap", overlap);
  }
  std::size_t heapBytes() const {
    return common::heapBytes(a, b, law, point, history, force, ranges, effRadius, effMass, overlap);
  }

  /// Replaces the candidates by `pairs` (law, a, b), keeping the history (and R*, m*) of pairs that
  /// survive. Both lists hold each key once, sorted by (law, a, b) (`pairs` is sorted here if it is not).
  /// The histories move in place, so that a rebuild does not hold old and new candidates side by side
  /// (a second copy would be 186 MB at 10⁶ spheres, a fifth of the run's memory); on several threads
  /// only the sources a thread's run takes from another run are copied aside, as many as the list
  /// shifted there. `pointsAndForces` false: `point` and `force` are left empty (sphere pairs without
  /// rolling resistance read neither; at 50,000 spheres they are 27 MB to write at every rebuild).
  void assign(std::vector<std::tuple<int, std::uint32_t, std::uint32_t>>& pairs, std::size_t lawCount,
              bool pointsAndForces = true);
};

using Triple = std::tuple<int, std::uint32_t, std::uint32_t>;  // (law, a, b) of a candidate

/// The candidate searches' lists, kept from build to build: thread 0 writes into `joined`, which then
/// takes the other threads' lists after its own (joinInOrder); every list cleared before a search.
struct CandidateLists {
  detail::PerThread<std::vector<Triple>> local;  // per thread but 0, its candidates
  std::vector<Triple> joined;              // the threads' lists joined in order
  std::size_t heapBytes() const { return common::heapBytes(local, joined); }
};

namespace detail {

// Called by every thread of a parallel region once each has written its list, thread 0 into `out` itself
// (the candidates are then not held twice over, 36 MB at 10⁶ spheres on one thread) and the others into
// local[thread]: the lists joined in thread order into `out`, each thread copying its own. `out` and
// every local list were empty before the threads wrote them.
inline void joinInOrder(const PerThread<std::vector<Triple>>& local, std::size_t thread, std::vector<Triple>& out) {
  std::size_t offset = out.size();
  for (std::size_t t = 1; t < thread; ++t) offset += local[t].size();
#pragma omp barrier
#pragma omp single
  {
    std::size_t total = out.size();
    for (std::size_t t = 1; t < local.size(); ++t) total += local[t].size();
    out.resize(total);
  }
  if (thread > 0)
    std::copy(local[thread].begin(), local[thread].end(), out.begin() + static_cast<std::ptrdiff_t>(offset));
}

// The reduced value of a pair, a b / (a + b) (mass m*, inertia I*); a fixed body counts as infinite.
inline double reduced(double a, double b, bool fixedA, bool fixedB) {
  if (fixedA) return b;
  if (fixedB) return a;
  return a * b / (a + b);
}

}  // namespace detail

// The merge in place. Both lists are sorted, so a surviving candidate's old index k(i) grows with its new
// index i. Each thread takes a run [i0, i1) of the new list; its sources lie in the old run [lo, hi) of the
// same keys. Within its run a thread moves the candidates that move left (k > i) in ascending order and
// those that move right (k < i) in descending order: a candidate's old place is then read before it is
// written, since k(i) is monotone. Sources in another thread's run are copied aside before any thread
// writes; old places at or past the new size are written by none. The new keys are written last, once
// no thread reads the old ones.
inline void ContactSet::assign(std::vector<Triple>& pairs, std::size_t lawCount, bool pointsAndForces) {
  const std::size_t n = pairs.size(), old = a.size();
  const int nt = static_cast<std::ptrdiff_t>(std::max(n, old)) > kParallelMin ? omp_get_max_threads() : 1;
  bool sorted = true;
#pragma omp parallel for schedule(static) reduction(&& : sorted) num_threads(nt) if (nt > 1)
  for (std::size_t i = 1; i < n; ++i) sorted = sorted && !(pairs[i] < pairs[i - 1]);
  if (!sorted) std::sort(pairs.begin(), pairs.end());
  // R* and m* of surviving sphere pairs too; 0: a new pair (the caller computes them).
  const bool pairState = !effRadius.empty();
  const std::size_t size = std::max(n, old);
  auto grow = [size](auto& v) {
    if (size > v.capacity()) v.reserve(size + size / 8);  // the old values are kept
    v.resize(size);
  };
  grow(a), grow(b), grow(law), grow(history);
  if (pairState) grow(effRadius), grow(effMass);
  struct Carried {
    ContactHistory history;
    double effRadius = 0.0, effMass = 0.0;
  };
  // The keys as (law, a·2³² + b), read through pointers the stores below cannot move.
  const int* const oldLaw = law.data();
  const std::uint32_t *const oldA = a.data(), *const oldB = b.data();
  const Triple* const key = pairs.data();
  auto ab = [](std::uint32_t x, std::uint32_t y) { return std::uint64_t{x} << 32 | y; };
  auto compare = [&](std::size_t k, std::size_t i) {  // old k against new i: < 0, 0, > 0
    const int dl = oldLaw[k] - std::get<0>(key[i]);
    if (dl != 0) return dl;
    const std::uint64_t x = ab(oldA[k], oldB[k]), y = ab(std::get<1>(key[i]), std::get<2>(key[i]));
    return (x > y) - (x < y);
  };
  const auto parts = static_cast<std::size_t>(nt);
  std::vector<std::size_t> first(parts + 1), lo(parts + 1, old);
  for (std::size_t t = 0; t <= parts; ++t) first[t] = n * t / parts;
  std::vector<std::vector<Carried>> aside(parts);
  detail::forEachPart(nt, [&](std::size_t t) {  // lo[t]: the first old candidate not before pairs[first[t]]
    if (first[t] == n) return;
    std::size_t l = 0, h = old;
    while (l < h) {
      const std::size_t mid = l + (h - l) / 2;
      if (compare(mid, first[t]) < 0)
        l = mid + 1;
      else
        h = mid;
    }
    lo[t] = l;
  });
  // The sources of run t that another run writes: old places [lo, i0) and [i1, min(hi, n)).
  auto leftEnd = [&](std::size_t t) { return std::max(lo[t], std::min(lo[t + 1], first[t])); };
  auto rightBegin = [&](std::size_t t) { return std::min(lo[t + 1], std::max(lo[t], first[t + 1])); };
  detail::forEachPart(nt, [&](std::size_t t) {
    const std::size_t rightEnd = std::max(rightBegin(t), std::min(lo[t + 1], n));
    std::vector<Carried>& c = aside[t];
    c.reserve(leftEnd(t) - lo[t] + rightEnd - rightBegin(t));
    auto keep = [&](std::size_t k) {
      c.push_back({history[k], pairState ? effRadius[k] : 0.0, pairState ? effMass[k] : 0.0});
    };
    for (std::size_t k = lo[t]; k < leftEnd(t); ++k) keep(k);
    for (std::size_t k = rightBegin(t); k < rightEnd; ++k) keep(k);
  });
  detail::forEachPart(nt, [&](std::size_t t) {
    const std::size_t i0 = first[t], i1 = first[t + 1], l = lo[t], h = lo[t + 1];
    const std::size_t left = leftEnd(t) - l, right = rightBegin(t);
    ContactHistory* const hist = history.data();
    double *const radius = effRadius.data(), *const mass = effMass.data();
    auto put = [&](std::size_t i, const ContactHistory& h, double r, double m) {
      hist[i] = h.lastOverlap > 0.0 ? h : ContactHistory{};
      if (pairState) radius[i] = r, mass[i] = m;
    };
    auto move = [&](std::size_t i, std::size_t k) {
      put(i, hist[k], pairState ? radius[k] : 0.0, pairState ? mass[k] : 0.0);
    };
    for (std::size_t i = i0, k = l; i < i1; ++i) {  // leftward moves within the run, ascending
      while (k < h && compare(k, i) < 0) ++k;
      if (k < h && k > i && k < i1 && compare(k, i) == 0) move(i, k);
    }
    for (std::size_t i = i1, k = h; i-- > i0;) {  // the rest, descending; k: one past the candidate
      while (k > l && compare(k - 1, i) > 0) --k;
      if (k > l && compare(k - 1, i) == 0) {
        const std::size_t from = k - 1;
        if (from >= i0 && from < i1) {
          if (from <= i) move(i, from);  // from > i: moved in the ascending pass
        } else if (from >= n) {
          move(i, from);  // an old place past the new size, written by no run
        } else {
          const Carried& c = aside[t][from < i0 ? from - l : left + (from - right)];
          put(i, c.history, c.effRadius, c.effMass);
        }
      } else {
        put(i, ContactHistory{}, 0.0, 0.0);  // a new candidate
      }
    }
  });
  detail::forEachPart(nt, [&](std::size_t t) {
    for (std::size_t i = first[t]; i < first[t + 1]; ++i) std::tie(law[i], a[i], b[i]) = pairs[i];
  });
  a.resize(n), b.resize(n), law.resize(n), history.resize(n);
  if (pairState) effRadius.resize(n), effMass.resize(n);
  point.assign(pointsAndForces ? n : 0, ContactPoint{});
  force.assign(pointsAndForces ? n : 0, ContactForce{});
  ranges.assign(lawCount, {0, 0});
  for (std::size_t l = 0; l < lawCount; ++l) {  // `law` is sorted
    const auto [firstOf, lastOf] = std::equal_range(law.begin(), law.end(), static_cast<int>(l));
    ranges[l] = {static_cast<std::size_t>(firstOf - law.begin()), static_cast<std::size_t>(lastOf - law.begin())};
  }
}

}  // namespace dem
