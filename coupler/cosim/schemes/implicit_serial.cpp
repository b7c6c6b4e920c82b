// Implicit serial (strong, Gauss–Seidel): each iteration runs the participants one after the other, each
// with what the ones before it produced in this iteration. The fixed point x̃ is what the last participant
// writes for the others (ImplicitIteration does the rest: residuals, acceleration, repeats).
#include "implicit_iteration.hpp"
#include "schemes.hpp"

namespace cosim {
namespace {

class ImplicitSerial final : public Scheme {
 public:
  ImplicitSerial(const CouplingSpec& spec, const SchemeHost& host)
      : spec_(spec), iteration_(spec, blocksOf(host, host.participants() - 1)) {}

  WindowOutcome window(SchemeHost& host, std::uint32_t firstFlags) override {
    const std::size_t last = host.participants() - 1;
    return iteration_.window(host, firstFlags, [last](SchemeHost& h, std::uint32_t flags) {
      for (std::size_t p = 0; p <= last; ++p) {
        h.send(p, flags);
        const std::size_t one[] = {p};
        h.collect(one);
        // The last participant's outputs reach the others after the acceleration, not also as they came.
        if (p != last) h.deliver(p);
      }
    });
  }
  bool strong() const override { return true; }
  std::string describe() const override { return "implicit scheme, " + spec_.acceleration + " acceleration"; }
  void archive(common::StateArchive& a) override { iteration_.archive(a); }
  void acceptWindow(SchemeHost& host, const WindowOutcome& w) override { iteration_.accept(host, w.converged); }
  void abandonWindow() override { iteration_.abandon(); }

 private:
  // One block: the last participant's read outputs, tested together (a stacked norm; its fields are of
  // one kind, what one participant writes back at one interface or several).
  static std::vector<ImplicitIteration::Block> blocksOf(const SchemeHost& host, std::size_t p) {
    return {{p, host.readFields(p)}};
  }

  const CouplingSpec& spec_;
  ImplicitIteration iteration_;
};
}  // namespace

std::unique_ptr<Scheme> makeImplicitSerial(const CouplingSpec& spec, const SchemeHost& host) {
  return std::make_unique<ImplicitSerial>(spec, host);
}
}  // namespace cosim
