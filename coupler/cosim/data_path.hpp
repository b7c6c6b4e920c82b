#pragma once
// The coupled run's data path: the exchanges as routes with their mappings, an ADVANCE made of a
// participant's inputs, a RESULT's outputs checked against what its HELLO declared, and the outputs
// mapped into their readers' inputs. The coupler is the hub: no data goes from participant to participant.

#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "connections.hpp"

namespace common {
class StateArchive;
}

namespace cosim {

/// A participant's solver diverged in the window and it can repeat it (RESULT flagged kDiverged).
struct ParticipantDiverged {
  std::string who, text;
};

class DataPath {
 public:
  struct Route {
    const ExchangeSpec* spec;
    std::size_t from, to;
    std::unique_ptr<Mapping> map;
    int components;
    std::string write, read;  // "mesh/field" at either end
  };

  DataPath(const CoupledScene& scene, Connections& peers, const Position& at);

  /// After the handshake: the routes and their mappings, checked against the HELLOs; the writes no
  /// exchange reads are marked unused. The fields on `schemeMeshes` are the scheme's: their reads start
  /// at zero and their writes are used.
  void build(const std::vector<std::string>& schemeMeshes = {});
  const std::vector<Route>& routes() const { return routes_; }
  /// The outputs of `p` that some exchange reads, in a fixed order.
  std::vector<std::string> readFields(std::size_t p) const;

  /// ADVANCE to `p` with its inputs; `checkpoint` non-empty: the file its on-disk checkpoint goes to.
  void advance(std::size_t p, std::uint32_t flags, double dt, const std::filesystem::path& checkpoint);
  /// The RESULTs of `ps`; throws ParticipantDiverged once every answer is in and one of them says so.
  void collect(std::span<const std::size_t> ps);
  void deliver(std::size_t p);

  double mappingSeconds() const { return mappingSeconds_; }
  /// The solvers' time on the run's critical path: of each collect(), the slowest of the RESULTs it
  /// waited for (a serial pass sums its participants, a parallel one takes the slower) [s].
  double criticalSolverSeconds() const { return criticalSolverSeconds_; }
  /// The largest ADVANCE's interface data [bytes].
  std::size_t largestAdvance() const;
  /// The participants' interface data and timings, written or read (a checkpoint of another scene,
  /// whose fields or sizes differ, is a common::ConfigError).
  void archive(common::StateArchive& a);

 private:
  void take(Participant& p, protocol::Message r);

  const CoupledScene& scene_;
  Connections& peers_;
  const Position& at_;
  std::vector<Route> routes_;
  double mappingSeconds_ = 0.0, criticalSolverSeconds_ = 0.0;
};

}  // namespace cosim
