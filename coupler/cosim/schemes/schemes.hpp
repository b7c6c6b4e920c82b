#pragma once
// Factories of the schemes, one per source file; registered by name in schemes.cpp.
#include "scheme.hpp"

namespace common {
class Config;
}

namespace cosim {
/// A scheme's own keys under `coupling:`, read into `spec`; the entries of coupling.tolerance.fields come
/// back to be checked against the exchanges once those are read.
using FieldToleranceKeys = std::vector<std::pair<std::string, common::Config>>;
/// The implicit schemes' (implicit_iteration.cpp): max_iterations, tolerance, require_convergence,
/// extrapolation, acceleration, and the adaptive windows' min_time_window and grow_after.
FieldToleranceKeys readImplicitKeys(const common::Config& coupling, CouplingSpec& spec);
/// The explicit schemes' (schemes.cpp): none; an implicit scheme's key is a located error.
FieldToleranceKeys refuseIterationKeys(const common::Config& coupling, CouplingSpec& spec);

std::unique_ptr<Scheme> makeExplicitSerial(const CouplingSpec& spec, const SchemeHost& host);
std::unique_ptr<Scheme> makeExplicitParallel(const CouplingSpec& spec, const SchemeHost& host);
std::unique_ptr<Scheme> makeImplicitSerial(const CouplingSpec& spec, const SchemeHost& host);
std::unique_ptr<Scheme> makeImplicitParallel(const CouplingSpec& spec, const SchemeHost& host);
std::unique_ptr<Scheme> makeBridging(const CouplingSpec& spec, const SchemeHost& host);
/// The bridging scheme's (bridging.cpp): `constraint`; an implicit scheme's key is a located error.
FieldToleranceKeys readBridgingKeys(const common::Config& coupling, CouplingSpec& spec);
/// The meshes the bridging scheme owns: `bridge` (the overlap) and `bridge_energy` (one node).
extern const std::vector<std::string> kBridgeMeshes;
}  // namespace cosim
