// Explicit serial (weak, Gauss–Seidel order): each participant advances once per window, with what the
// ones before it produced in this window and the later ones in the last.
#include "schemes.hpp"

namespace cosim {
namespace {
class ExplicitSerial final : public Scheme {
 public:
  WindowOutcome window(SchemeHost& host, std::uint32_t firstFlags) override {
    host.setIteration(0);
    for (std::size_t p = 0; p < host.participants(); ++p) {
      host.send(p, firstFlags);
      const std::size_t one[] = {p};
      host.collect(one);
      host.deliver(p);
    }
    return {};
  }
  bool strong() const override { return false; }
  std::string describe() const override { return "explicit_serial scheme"; }
};
}  // namespace

SchemeKeys readExplicitSerial(const common::Config& coupling, CouplingSpec& spec) {
  refuseIterationKeys(coupling, spec);
  return {[](const CouplingSpec&, const SchemeHost&) { return std::make_unique<ExplicitSerial>(); }, {}};
}
}  // namespace cosim
