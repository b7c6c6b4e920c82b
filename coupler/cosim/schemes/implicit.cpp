// Implicit serial (strong, Gauss–Seidel): each iteration runs the participants one after the other, each
// with what the ones before it produced in this iteration. The fixed point x̃ is what the last participant
// writes for the others, one block tested as a whole (ImplicitIteration does the rest: residuals,
// acceleration, repeats).
#include "implicit_iteration.hpp"
#include "schemes.hpp"

namespace cosim {

namespace {
std::unique_ptr<Scheme> make(const IterationSettings& settings, const SchemeHost& host) {
  const std::size_t last = host.participants() - 1;
  return std::make_unique<ImplicitIteration>(
      settings, std::vector<ImplicitIteration::Block>{{last, host.readFields(last)}}, "implicit",
      [last](SchemeHost& h, std::uint32_t flags) {
        for (std::size_t p = 0; p <= last; ++p) {
          h.send(p, flags);
          const std::size_t one[] = {p};
          h.collect(one);
          // The last participant's outputs reach the others after the acceleration, not also as they came.
          if (p != last) h.deliver(p);
        }
      });
}
}  // namespace

SchemeKeys readImplicitSerial(const common::Config& coupling, CouplingSpec& spec) {
  return readIterating(coupling, spec, make);
}

}  // namespace cosim
