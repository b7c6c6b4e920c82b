#include "interface_energy.hpp"

#include <algorithm>
#include <cmath>

namespace cosim {

namespace {
// f · (u − last), then last = u.
double work(std::span<const double> f, std::span<const double> u, std::vector<double>& last) {
  double w = 0.0;
  const std::size_t n = std::min({f.size(), u.size(), last.size()});
  for (std::size_t i = 0; i < n; ++i) w += f[i] * (u[i] - last[i]);
  last.assign(u.begin(), u.end());
  return w;
}
}  // namespace

std::pair<double, double> InterfaceEnergy::window(std::span<const double> forceA, std::span<const double> displacementA,
                             std::span<const double> forceB, std::span<const double> displacementB) {
  if (!started_) {
    lastA_.assign(displacementA.begin(), displacementA.end());
    lastB_.assign(displacementB.begin(), displacementB.end());
    started_ = true;
    return {0.0, 0.0};
  }
  const double a = work(forceA, displacementA, lastA_), b = work(forceB, displacementB, lastB_);
  workA_ += a;
  workB_ += b;
  scale_ = std::max({scale_, std::abs(workA_), std::abs(workB_)});
  return {a, b};
}

}  // namespace cosim
