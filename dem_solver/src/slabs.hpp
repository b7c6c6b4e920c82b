#pragma once
// How a run on several ranks shares space (dem_solver/src/ranked_simulation.hpp): slabs along one axis, cut where
// the spheres' count reaches k/P of all, so that each rank holds about as many spheres — recursive
// bisection in one direction. A rank owns the spheres whose centres are in its slab; it also holds, as
// ghosts, the spheres of other slabs within a width of its own. Pure geometry: no MPI here.
#include <algorithm>
#include <cstddef>
#include <vector>

namespace dem {

struct Slabs {
  int axis = 0;              ///< 0, 1, 2: x, y, z
  std::vector<double> cuts;  ///< the P − 1 boundaries between the slabs, ascending [m]

  int ranks() const { return static_cast<int>(cuts.size()) + 1; }
  template <class Archive>
  void archive(Archive& a) {
    a.io("axis", axis), a.io("cuts", cuts);
  }
  /// The rank whose slab holds coordinate `x` along the axis (a centre on a cut: the upper slab).
  int owner(double x) const {
    return static_cast<int>(std::upper_bound(cuts.begin(), cuts.end(), x) - cuts.begin());
  }
  /// Calls `f(r)` for each rank other than `self` whose slab comes within `width` of `x`: those that need
  /// a sphere there as a ghost.
  template <class F>
  void near(double x, double width, int self, F&& f) const {
    for (int r = owner(x - width), last = owner(x + width); r <= last; ++r)
      if (r != self) f(r);
  }

  /// Cuts for `ranks` slabs from a histogram of the centres along `axis`: `counts[i]` centres in bin i of
  /// equal bins over [lo, hi]. Cut k is where the count reaches k/P of the total, interpolated linearly in
  /// its bin (so a bin's spheres may fall on either side: the shares differ by up to a bin's count).
  static Slabs fromHistogram(int axis, double lo, double hi, const std::vector<double>& counts, int ranks) {
    Slabs s;
    s.axis = axis;
    double total = 0.0;
    for (double c : counts) total += c;
    const double bin = (hi - lo) / static_cast<double>(counts.size());
    double below = 0.0;  // centres in the bins before i
    std::size_t i = 0;
    for (int k = 1; k < ranks; ++k) {
      const double target = total * k / ranks;
      while (i < counts.size() && below + counts[i] < target) below += counts[i++];
      if (i == counts.size()) {
        s.cuts.push_back(hi);
        continue;
      }
      const double fraction = counts[i] > 0.0 ? (target - below) / counts[i] : 0.0;
      s.cuts.push_back(lo + (static_cast<double>(i) + fraction) * bin);
    }
    return s;
  }
};

}  // namespace dem
