// Implicit parallel (strong, Jacobi): each iteration advances every participant at once from the others'
// last iterate; the coupler sends every ADVANCE before it waits for any RESULT, so a window costs the
// slower participant's time, not the sum. The fixed point x̃ is every participant's read outputs stacked
// (forces and displacements together), one block per field: ImplicitIteration accelerates it as one
// vector, each field scaled by the residual-sum preconditioner, and tests each field on its own.
#include <numeric>

#include "implicit_iteration.hpp"
#include "schemes.hpp"

namespace cosim {

namespace {
std::unique_ptr<Scheme> make(const IterationSettings& settings, const SchemeHost& host) {
  std::vector<ImplicitIteration::Block> blocks;
  for (std::size_t p = 0; p < host.participants(); ++p)
    for (const auto& f : host.readFields(p)) blocks.push_back({p, {f}});
  return std::make_unique<ImplicitIteration>(settings, std::move(blocks), "implicit_parallel",
                                             [](SchemeHost& h, std::uint32_t flags) {
                                               std::vector<std::size_t> all(h.participants());
                                               std::iota(all.begin(), all.end(), std::size_t{0});
                                               for (std::size_t p : all) h.send(p, flags);
                                               h.collect(all);
                                             });
}
}  // namespace

SchemeKeys readImplicitParallel(const common::Config& coupling, CouplingSpec& spec) {
  return readIterating(coupling, spec, make);
}

}  // namespace cosim
