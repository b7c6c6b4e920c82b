#include "lattice/sieve_curve.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

#include <fmt/format.h>

namespace lattice {

SieveCurve SieveCurve::fuller(double dMin, double dMax, double exponent, int classes) {
  if (!(dMin > 0 && dMax > dMin)) throw std::invalid_argument(fmt::format("need 0 < d_min < d_max, got {} and {}", dMin, dMax));
  if (!(exponent > 0)) throw std::invalid_argument(fmt::format("the exponent must be > 0, got {}", exponent));
  SieveCurve c;
  // Geometric classes: Fuller's curve is a power law, so equal ratios give comparable class shares.
  const double ratio = std::pow(dMax / dMin, 1.0 / classes);
  double d = dMin;
  for (int i = 0; i <= classes; ++i, d *= ratio) {
    const double di = i == classes ? dMax : d;
    c.d_.push_back(di);
    c.p_.push_back(std::pow(di / dMax, exponent));
  }
  const double p0 = c.p_.front();
  for (double& p : c.p_) p = (p - p0) / (1.0 - p0);
  return c;
}

SieveCurve SieveCurve::table(std::vector<double> diameters, std::vector<double> passing) {
  if (diameters.size() != passing.size() || diameters.size() < 2)
    throw std::invalid_argument("a sieve table needs at least two rows of [diameter, passing]");
  for (std::size_t i = 0; i < diameters.size(); ++i) {
    if (!(diameters[i] > 0)) throw std::invalid_argument(fmt::format("row {}: diameter {} is not > 0", i, diameters[i]));
    if (i > 0 && !(diameters[i] > diameters[i - 1]))
      throw std::invalid_argument(fmt::format("row {}: diameter {} is not larger than the previous {}", i, diameters[i], diameters[i - 1]));
    if (i > 0 && passing[i] < passing[i - 1])
      throw std::invalid_argument(fmt::format("row {}: passing {} is below the previous row's {}; a sieve curve never decreases",
                                              i, passing[i], passing[i - 1]));
  }
  if (!(passing.back() > passing.front()))
    throw std::invalid_argument("the passing fraction does not grow from the first to the last row");
  SieveCurve c;
  c.d_ = std::move(diameters);
  const double p0 = passing.front(), p1 = passing.back();
  for (double p : passing) c.p_.push_back((p - p0) / (p1 - p0));
  return c;
}

double SieveCurve::passing(double d) const {
  if (d <= d_.front()) return 0.0;
  if (d >= d_.back()) return 1.0;
  const auto it = std::upper_bound(d_.begin(), d_.end(), d);
  const std::size_t i = static_cast<std::size_t>(it - d_.begin());
  const double t = (d - d_[i - 1]) / (d_[i] - d_[i - 1]);
  return p_[i - 1] + t * (p_[i] - p_[i - 1]);
}

std::vector<double> SieveCurve::sample(double volume, std::mt19937_64& rng) const {
  std::vector<double> out;
  auto sphere = [](double d) { return std::numbers::pi / 6.0 * d * d * d; };
  // What a class could not fill (its share below half a sphere) passes to the next smaller class, so
  // the total stays within half the smallest sphere of the target.
  double carry = 0.0;
  for (std::size_t i = d_.size() - 1; i > 0; --i) {
    const double share = (p_[i] - p_[i - 1]) * volume + carry;
    std::uniform_real_distribution<double> pick(d_[i - 1], d_[i]);
    double filled = 0.0;
    while (true) {
      const double d = pick(rng);
      if (filled + 0.5 * sphere(d) > share) break;
      out.push_back(d);
      filled += sphere(d);
    }
    carry = share - filled;
  }
  std::sort(out.begin(), out.end(), std::greater<>());
  return out;
}

}  // namespace lattice
