#include "dem/restitution.hpp"

#include <cmath>
#include <map>
#include <mutex>
#include <stdexcept>
#include <utility>

#include <fmt/format.h>

namespace dem {

namespace {

double acceleration(NormalModel model, double c, double s, double v) {
  const double sp = std::max(s, 0.0);
  double f;
  if (model == NormalModel::kLinear)
    f = sp + c * v;
  else
    f = sp * std::sqrt(sp) + c * std::sqrt(1.5) * std::sqrt(std::sqrt(sp)) * v;
  return -std::max(f, 0.0);
}

}  // namespace

DimensionlessImpact solveImpact(NormalModel model, double c) {
  const double h = 2e-4;
  double t = 0.0, s = 0.0, v = 1.0, sMax = 0.0;
  for (long step = 0; step < 10'000'000; ++step) {
    const double k1s = v, k1v = acceleration(model, c, s, v);
    const double k2s = v + 0.5 * h * k1v, k2v = acceleration(model, c, s + 0.5 * h * k1s, k2s);
    const double k3s = v + 0.5 * h * k2v, k3v = acceleration(model, c, s + 0.5 * h * k2s, k3s);
    const double k4s = v + h * k3v, k4v = acceleration(model, c, s + h * k3s, k4s);
    const double sNew = s + h / 6 * (k1s + 2 * k2s + 2 * k3s + k4s);
    const double vNew = v + h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v);
    if (sNew <= 0.0 && step > 0) {
      // Linear interpolation of the crossing; the force is ~0 there, so the velocity is nearly flat.
      const double f = s / (s - sNew);
      return {-(v + f * (vNew - v)), t + f * h, sMax};
    }
    s = sNew;
    v = vNew;
    t += h;
    sMax = std::max(sMax, s);
  }
  throw std::runtime_error("solveImpact: the scaled collision did not end");
}

double dampingForRestitution(NormalModel model, double e) {
  if (!(e > 0.0 && e <= 1.0)) throw std::invalid_argument(fmt::format("restitution {} is outside (0, 1]", e));
  if (e == 1.0) return 0.0;
  static std::mutex mutex;
  static std::map<std::pair<int, double>, double> cache;
  std::lock_guard lock(mutex);
  const auto key = std::make_pair(static_cast<int>(model), e);
  if (auto it = cache.find(key); it != cache.end()) return it->second;
  double lo = 0.0, hi = 1.0;
  while (solveImpact(model, hi).restitution > e) {
    hi *= 2;
    if (hi > 50)
      throw std::invalid_argument(fmt::format("restitution {} is below what the dashpot can reach ({:.3g})", e,
                                              solveImpact(model, 50).restitution));
  }
  // e(c) decreases monotonically; bisect until e is matched to 1e-10.
  for (int i = 0; i < 200 && hi - lo > 1e-12; ++i) {
    const double mid = 0.5 * (lo + hi);
    const double em = solveImpact(model, mid).restitution;
    if (std::abs(em - e) < 1e-10) {
      lo = hi = mid;
      break;
    }
    (em > e ? lo : hi) = mid;
  }
  const double c = 0.5 * (lo + hi);
  cache[key] = c;
  return c;
}

double linearRestitutionClamped(double zeta) {
  if (zeta == 0.0) return 1.0;
  const double pi = 3.14159265358979323846;
  if (zeta < 1.0 / std::sqrt(2.0)) {
    const double w = std::sqrt(1 - zeta * zeta);
    return std::exp(-zeta / w * (pi - std::atan(2 * zeta * w / (1 - 2 * zeta * zeta))));
  }
  if (zeta < 1.0) {
    const double w = std::sqrt(1 - zeta * zeta);
    return std::exp(-zeta / w * std::atan(2 * zeta * w / (2 * zeta * zeta - 1)));
  }
  const double w = std::sqrt(zeta * zeta - 1);
  return std::exp(-zeta / w * std::log((zeta + w) / (zeta - w)));
}

}  // namespace dem
