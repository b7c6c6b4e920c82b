// Aitken's dynamic relaxation (Irons & Tuck 1969; Küttler & Wall 2008, eq. 44):
//   ω_k = −ω_{k−1} r_{k−1}ᵀ(r_k − r_{k−1}) / ‖r_k − r_{k−1}‖²,  x̃_{k+1} = x̃_k + ω_k r_k,
// starting each window from ω₀ (the `relaxation` parameter), |ω| capped at 10.
#include <algorithm>
#include <cmath>
#include <vector>

#include "accelerations.hpp"

namespace cosim {
namespace {
class Aitken final : public Acceleration {
 public:
  explicit Aitken(double w0) : w0_(w0), w_(w0) {}
  std::string name() const override { return "aitken"; }
  void next(std::span<const double> x, std::span<const double> hx, std::span<double> out) override {
    const std::size_t n = x.size();
    std::vector<double> r(n);
    for (std::size_t i = 0; i < n; ++i) r[i] = hx[i] - x[i];
    if (previous_.size() == n) {
      // In the weighted norm (setWeights) when one is set: fields of other units weigh alike.
      const bool weighted = weights_.size() == n;
      double num = 0.0, den = 0.0;
      for (std::size_t i = 0; i < n; ++i) {
        const double d = r[i] - previous_[i], w2 = weighted ? weights_[i] * weights_[i] : 1.0;
        num += w2 * previous_[i] * d;
        den += w2 * d * d;
      }
      if (den > 0.0) w_ = std::clamp(-w_ * num / den, -10.0, 10.0);
    } else {
      w_ = w0_;
    }
    for (std::size_t i = 0; i < n; ++i) out[i] = x[i] + w_ * r[i];
    previous_ = std::move(r);
  }
  void converged() override { previous_.clear(); }
  void archive(common::StateArchive&) override {}  // each window starts again from ω₀

 private:
  double w0_, w_;
  std::vector<double> previous_;
};
}  // namespace

AccelerationMake readAitken(const common::Config&) {
  return [](double relaxation) { return std::make_unique<Aitken>(relaxation); };
}
}  // namespace cosim
