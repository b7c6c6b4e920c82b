#pragma once
// The interface energy of a coupled run (InterfaceEnergy, interface_energy.hpp) for every interface whose
// force goes one way and displacement the other: recorded after each final window, reported in the
// summary, and checked at the end of the run (exit 3 when the coupling made or lost energy).

#include <cstdint>
#include <vector>

#include "data_path.hpp"
#include "interface_energy.hpp"

namespace common {
class Summary;
}

namespace cosim {

class Scheme;

class InterfaceLedger {
 public:
  /// Pairs the routes: a conservative force from A to B with the displacement from B back to A on the same
  /// meshes. The participants keep a copy of the inputs the ledger reads (Participant::advanced).
  InterfaceLedger(const DataPath& data, Connections& peers);
  std::size_t size() const { return pairs_.size(); }
  /// After a window that stands, with the data its last iteration used.
  void record(std::uint64_t window);
  void report(common::Summary& summary) const;
  /// At the end of the run, over everything that crossed the interface: throws common::InstabilityError
  /// when the mismatch exceeds coupling.energy_tolerance; the scheme chooses the fix it proposes.
  void verify(const CouplingSpec& coupling, const Scheme& scheme) const;
  void archive(common::StateArchive& a);

 private:
  struct Pair {
    const DataPath::Route *force, *displacement;
    InterfaceEnergy energy;
  };
  const Connections& peers_;
  std::vector<Pair> pairs_;
};

}  // namespace cosim
