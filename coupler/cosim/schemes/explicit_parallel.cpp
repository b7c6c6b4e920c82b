// Explicit parallel (weak, Jacobi): every participant advances once per window with what the others
// produced in the last, all at once (their solvers run concurrently, the coupler waits for the last).
#include <numeric>

#include "schemes.hpp"

namespace cosim {
namespace {
class ExplicitParallel final : public Scheme {
 public:
  WindowOutcome window(SchemeHost& host, std::uint32_t firstFlags) override {
    host.setIteration(0);
    std::vector<std::size_t> all(host.participants());
    std::iota(all.begin(), all.end(), std::size_t{0});
    for (std::size_t p : all) host.send(p, firstFlags);
    host.collect(all);
    for (std::size_t p : all) host.deliver(p);
    return {};
  }
  bool strong() const override { return false; }
  std::string describe() const override { return "explicit_parallel scheme"; }
};
}  // namespace

SchemeKeys readExplicitParallel(const common::Config& coupling, CouplingSpec& spec) {
  refuseIterationKeys(coupling, spec);
  return {[](const CouplingSpec&, const SchemeHost&) { return std::make_unique<ExplicitParallel>(); }, {}};
}
}  // namespace cosim
