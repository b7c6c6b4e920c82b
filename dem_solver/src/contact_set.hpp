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

namespace dem {

namespace detail {

// `v` resized to n elements whose values are all about to be written: when it must grow, to n and an
// eighth more, its old values not copied. A vector's own growth doubles the capacity: the candidates'
// arrays and their spares would then hold up to twice the candidates (7 MB of 14 at 20,000 spheres).
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
  // candidates: `point` holds R*, m* and this step's δ; its normal, point and relative velocity are
  // written only with rolling resistance (PlaneWalls::computeContacts).
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

  /// The arrays assign() writes the new candidates into before they swap with these: kept from build to
  /// build (with the capacity of the last), so a rebuild allocates and clears nothing.
  struct Spare {
    std::vector<std::uint32_t> a, b;
    std::vector<int> law;
    std::vector<ContactHistory> history;
    std::vector<double> effRadius, effMass;
    std::size_t heapBytes() const { return common::heapBytes(a, b, law, history, effRadius, effMass); }
  };

  /// Replaces the candidates by `pairs` (law, a, b), keeping the history of pairs that survive. Both
  /// lists are sorted by (law, a, b) (`pairs` usually arrives so): the histories pass by a merge.
  /// `pointsAndForces` false: `point` and `force` are left empty (sphere pairs without rolling
  /// resistance read neither; at 50,000 spheres they are 27 MB to write at every rebuild).
  void assign(std::vector<std::tuple<int, std::uint32_t, std::uint32_t>>& pairs, std::size_t lawCount, Spare& spare,
              bool pointsAndForces = true) {
    const std::size_t n = pairs.size(), old = a.size();
    const int nt = static_cast<std::ptrdiff_t>(n) > kParallelMin ? omp_get_max_threads() : 1;
    bool sorted = true;
#pragma omp parallel for schedule(static) reduction(&& : sorted) num_threads(nt) if (nt > 1)
    for (std::size_t i = 1; i < n; ++i) sorted = sorted && !(pairs[i] < pairs[i - 1]);
    if (!sorted) std::sort(pairs.begin(), pairs.end());
    // R* and m* of surviving sphere pairs too; 0: a new pair (the caller computes them).
    const bool pairState = !effRadius.empty();
    detail::resizeOver(spare.a, n), detail::resizeOver(spare.b, n), detail::resizeOver(spare.law, n);
    detail::resizeOver(spare.history, n);
    if (pairState) detail::resizeOver(spare.effRadius, n), detail::resizeOver(spare.effMass, n);
    // The merge in thread runs of the new list, each starting where its first pair would be in the old;
    // every entry of the spare arrays is written.
    auto oldKey = [&](std::size_t k) { return std::tuple(law[k], a[k], b[k]); };
    const auto threads = static_cast<std::size_t>(nt);
    detail::forEachPart(nt, [&](std::size_t t) {
      const std::size_t i0 = n * t / threads, i1 = n * (t + 1) / threads;
      std::size_t lo = 0, hi = old;  // the first old candidate not before pairs[i0]
      while (i0 < i1 && lo < hi) {
        const std::size_t mid = lo + (hi - lo) / 2;
        if (oldKey(mid) < pairs[i0])
          lo = mid + 1;
        else
          hi = mid;
      }
      for (std::size_t i = i0, k = lo; i < i1; ++i) {
        std::tie(spare.law[i], spare.a[i], spare.b[i]) = pairs[i];
        while (k < old && oldKey(k) < pairs[i]) ++k;
        const bool kept = k < old && oldKey(k) == pairs[i];
        spare.history[i] = kept && history[k].lastOverlap > 0.0 ? history[k] : ContactHistory{};
        if (pairState) spare.effRadius[i] = kept ? effRadius[k] : 0.0, spare.effMass[i] = kept ? effMass[k] : 0.0;
      }
    });
    a.swap(spare.a), b.swap(spare.b), law.swap(spare.law), history.swap(spare.history);
    if (pairState) effRadius.swap(spare.effRadius), effMass.swap(spare.effMass);
    point.assign(pointsAndForces ? n : 0, ContactPoint{});
    force.assign(pointsAndForces ? n : 0, ContactForce{});
    ranges.assign(lawCount, {0, 0});
    for (std::size_t l = 0; l < lawCount; ++l) {  // `law` is sorted
      const auto [first, last] = std::equal_range(law.begin(), law.end(), static_cast<int>(l));
      ranges[l] = {static_cast<std::size_t>(first - law.begin()), static_cast<std::size_t>(last - law.begin())};
    }
  }
};

using Triple = std::tuple<int, std::uint32_t, std::uint32_t>;  // (law, a, b) of a candidate

/// The candidate searches' per-thread lists, kept from build to build (no allocation in a rebuild).
struct CandidateLists {
  std::vector<std::vector<Triple>> local;  // per thread, its candidates
  std::vector<Triple> joined;              // the threads' lists joined in order
  std::size_t heapBytes() const { return common::heapBytes(local, joined); }
};

namespace detail {

// Called by every thread of a parallel region once local[thread] holds its list: the lists joined in thread
// order into `out`, each thread copying its own.
inline void joinInOrder(const std::vector<std::vector<Triple>>& local, std::size_t thread, std::vector<Triple>& out) {
  std::size_t offset = 0;
  for (std::size_t t = 0; t < thread; ++t) offset += local[t].size();
#pragma omp single
  {
    std::size_t total = 0;
    for (const auto& l : local) total += l.size();
    out.resize(total);
  }
  std::copy(local[thread].begin(), local[thread].end(), out.begin() + static_cast<std::ptrdiff_t>(offset));
}

// The reduced value of a pair, a b / (a + b) (mass m*, inertia I*); a fixed body counts as infinite.
inline double reduced(double a, double b, bool fixedA, bool fixedB) {
  if (fixedA) return b;
  if (fixedB) return a;
  return a * b / (a + b);
}

}  // namespace detail
}  // namespace dem
