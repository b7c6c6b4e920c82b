#pragma once
// The schemes' entries, one per source file, registered by name in schemes.cpp. Each reads its own keys
// of `coupling:` and gives back its make with what they said bound in: no settings struct holds every
// scheme's fields.
#include "common/config.hpp"
#include "scheme.hpp"

namespace cosim {
/// The entries of coupling.tolerance.fields, to be checked against the exchanges once those are read.
using FieldToleranceKeys = std::vector<std::pair<std::string, common::Config>>;
/// A scheme's reading of its keys: its make, and its field tolerances' entries.
struct SchemeKeys {
  std::function<std::unique_ptr<Scheme>(const CouplingSpec&, const SchemeHost&)> make;
  FieldToleranceKeys fieldTolerances;
};

/// An implicit scheme's keys (implicit_iteration.cpp): max_iterations, tolerance, require_convergence,
/// extrapolation, acceleration into its IterationSettings, bound into `make`; the adaptive windows'
/// min_time_window and grow_after into `spec`.
using IterationMake = std::unique_ptr<Scheme> (*)(const IterationSettings&, const SchemeHost&);
SchemeKeys readIterating(const common::Config& coupling, CouplingSpec& spec, IterationMake make);
/// A weak scheme's: none; an implicit scheme's key is a located error (schemes.cpp).
void refuseIterationKeys(const common::Config& coupling, CouplingSpec& spec);

SchemeKeys readExplicitSerial(const common::Config& coupling, CouplingSpec& spec);
SchemeKeys readExplicitParallel(const common::Config& coupling, CouplingSpec& spec);
SchemeKeys readImplicitSerial(const common::Config& coupling, CouplingSpec& spec);
SchemeKeys readImplicitParallel(const common::Config& coupling, CouplingSpec& spec);
/// The bridging scheme's (bridging.cpp): `constraint`; an implicit scheme's key is a located error.
SchemeKeys readBridging(const common::Config& coupling, CouplingSpec& spec);
/// The meshes the bridging scheme owns: `bridge` (the overlap) and `bridge_energy` (one node).
extern const std::vector<std::string> kBridgeMeshes;
}  // namespace cosim
