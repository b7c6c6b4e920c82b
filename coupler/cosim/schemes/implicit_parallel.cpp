// Implicit parallel (strong, Jacobi): each iteration advances every participant at once from the others'
// last iterate; the coupler sends every ADVANCE before it waits for any RESULT, so a window costs the
// slower participant's time, not the sum. The fixed point x̃ is every participant's read outputs stacked
// (forces and displacements together); ImplicitIteration accelerates it as one vector, each field scaled
// by the residual-sum preconditioner, and tests each field on its own.
#include <numeric>

#include "implicit_iteration.hpp"
#include "schemes.hpp"

namespace cosim {
namespace {

class ImplicitParallel final : public Scheme {
 public:
  ImplicitParallel(const CouplingSpec& spec, const SchemeHost& host) : spec_(spec), iteration_(spec, blocksOf(host)) {}

  WindowOutcome window(SchemeHost& host, std::uint32_t firstFlags) override {
    return iteration_.window(host, firstFlags, [](SchemeHost& h, std::uint32_t flags) {
      std::vector<std::size_t> all(h.participants());
      std::iota(all.begin(), all.end(), std::size_t{0});
      for (std::size_t p : all) h.send(p, flags);
      h.collect(all);
    });
  }
  bool strong() const override { return true; }
  std::string describe() const override {
    return "implicit_parallel scheme, " + spec_.acceleration + " acceleration";
  }
  void archive(common::StateArchive& a) override { iteration_.archive(a); }
  void acceptWindow(SchemeHost& host, const WindowOutcome& w) override { iteration_.accept(host, w.converged); }
  void abandonWindow() override { iteration_.abandon(); }

 private:
  static std::vector<ImplicitIteration::Block> blocksOf(const SchemeHost& host) {
    std::vector<ImplicitIteration::Block> blocks;
    for (std::size_t p = 0; p < host.participants(); ++p)
      for (const auto& f : host.readFields(p)) blocks.push_back({p, {f}});
    return blocks;
  }

  const CouplingSpec& spec_;
  ImplicitIteration iteration_;
};
}  // namespace

std::unique_ptr<Scheme> makeImplicitParallel(const CouplingSpec& spec, const SchemeHost& host) {
  return std::make_unique<ImplicitParallel>(spec, host);
}
}  // namespace cosim
