// Constant under-relaxation: x̃_{k+1} = x̃_k + ω r_k.
#include "accelerations.hpp"

namespace cosim {
namespace {
class Constant final : public Acceleration {
 public:
  explicit Constant(double w) : w_(w) {}
  std::string name() const override { return "constant"; }
  void next(std::span<const double> x, std::span<const double> hx, std::span<double> out) override {
    for (std::size_t i = 0; i < x.size(); ++i) out[i] = x[i] + w_ * (hx[i] - x[i]);
  }
  void converged() override {}
  void archive(common::StateArchive&) override {}  // nothing outlives a window

 private:
  double w_;
};
}  // namespace

AccelerationMake readConstant(const common::Config&) {
  return [](double relaxation) { return std::make_unique<Constant>(relaxation); };
}
}  // namespace cosim
