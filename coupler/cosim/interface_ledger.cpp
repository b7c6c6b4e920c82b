#include "interface_ledger.hpp"

#include <cmath>

#include <fmt/format.h>

#include "common/errors.hpp"
#include "common/log.hpp"
#include "common/summary.hpp"
#include "schemes/scheme.hpp"

namespace cosim {

InterfaceLedger::InterfaceLedger(const DataPath& data, Connections& peers) : peers_(peers) {
  const auto& routes = data.routes();
  for (const auto& rf : routes) {
    if (!rf.spec->conservative) continue;
    for (const auto& ru : routes) {
      if (ru.spec->conservative || ru.from != rf.to || ru.to != rf.from || ru.spec->fromMesh != rf.spec->toMesh ||
          ru.spec->toMesh != rf.spec->fromMesh || ru.spec->field != "displacement" || ru.components != rf.components)
        continue;
      pairs_.push_back({&rf, &ru, {}});
      peers[ru.to].keepAdvanced.insert(ru.read);
      peers[rf.to].keepAdvanced.insert(rf.read);
      break;
    }
  }
}

void InterfaceLedger::record(std::uint64_t window) {
  auto field = [](const Fields& m, const std::string& key) {
    const auto it = m.find(key);
    return it == m.end() ? std::span<const double>() : std::span<const double>(it->second);
  };
  for (auto& pair : pairs_) {
    const auto &rf = *pair.force, &ru = *pair.displacement;
    const Participant &a = peers_[rf.from], &b = peers_[rf.to];
    const auto [dA, dB] = pair.energy.window(field(a.outputs, rf.write), field(a.advanced, ru.read),
                                             field(b.advanced, rf.read), field(b.outputs, ru.write));
    common::logger("cosim")->debug("window {}: interface work {} {:.6e} J, {} {:.6e} J (so far {:.6e} / {:.6e} J)",
                                   window, a.spec.name, dA, b.spec.name, dB, pair.energy.workA(), pair.energy.workB());
  }
}

void InterfaceLedger::report(common::Summary& summary) const {
  for (const auto& pair : pairs_) {
    const std::string &a = peers_[pair.force->from].spec.name, &b = peers_[pair.force->to].spec.name;
    summary.set("interface_work_" + a, pair.energy.workA());
    summary.set("interface_work_" + b, pair.energy.workB());
    summary.set("interface_energy_error_" + a + "_" + b,
                pair.energy.scale() > 0 ? std::abs(pair.energy.mismatch()) / pair.energy.scale() : 0.0);
  }
}

// Over the whole run: a window-by-window check would trip on the first contact windows, where little has
// crossed and a one-window lag is all of it.
void InterfaceLedger::verify(const CouplingSpec& c, const Scheme& scheme) const {
  const IterationSettings* iteration = scheme.iteration();
  for (const auto& pair : pairs_) {
    const InterfaceEnergy& e = pair.energy;
    // Where nothing reached the interface both works are round-off and their ratio means nothing: below
    // 1e-18 J crossing (a millionth of the energy of a 1 µg grain at 1 mm/s) the check stands aside.
    if (!(std::abs(e.mismatch()) > c.energyTolerance * e.scale()) || e.scale() < 1e-18) continue;
    const auto& rf = *pair.force;
    const Participant &a = peers_[rf.from], &b = peers_[rf.to];
    // An iterating scheme: a tighter tolerance, or shorter windows; a weak one: an iterating one.
    const std::string tenth = iteration ? common::fixValue(0.1 * iteration->relativeTolerance) : "";
    const std::string half = common::wholeStepValue(c.endTime, 0.5 * c.window);
    const std::string fix =
        iteration ? fmt::format("coupling.tolerance.relative = {} (a tenth), or coupling.time_window = {} s (half)", tenth,
                                half)
        : scheme.strong()
            ? fmt::format("coupling.time_window = {} s (half)", half)
            : fmt::format("coupling.scheme: implicit with coupling.acceleration.type: iqn_ils: a weak scheme feeds one "
                             "side the interface a window late, and the lag does work");
    throw common::InstabilityError(
        {e.mismatch() > 0 ? "interface energy created by the coupling" : "interface energy lost by the coupling",
         fmt::format("interface {}/{} ↔ {}/{}", a.spec.name, rf.spec->fromMesh, b.spec.name, rf.spec->toMesh), c.endTime,
         fmt::format("over the run the interface forces did {:.4g} J of work on {}'s side and {:.4g} J on {}'s: {:.4g} J "
                     "that no physics made, {:.3g} of the energy that crossed the interface (allowed {:.3g}, key "
                     "coupling.energy_tolerance); the results are not trustworthy",
                     e.workA(), a.spec.name, e.workB(), b.spec.name, e.mismatch(), std::abs(e.mismatch()) / e.scale(),
                     c.energyTolerance),
         fix,
         iteration        ? std::vector<std::string>{"coupling.tolerance.relative=" + tenth}
         : scheme.strong() ? std::vector<std::string>{"coupling.time_window=" + half}
                           : std::vector<std::string>{"coupling.scheme=implicit", "coupling.acceleration.type=iqn_ils"}});
  }
}

void InterfaceLedger::archive(common::StateArchive& a) {
  for (std::size_t i = 0; i < pairs_.size(); ++i) a.io(fmt::format("interface_energy_{}", i), pairs_[i].energy);
}

}  // namespace cosim
