#pragma once
// Factories of the schemes, one per source file; registered by name in schemes.cpp.
#include "scheme.hpp"

namespace cosim {
std::unique_ptr<Scheme> makeExplicitSerial(const CouplingSpec& spec, const SchemeHost& host);
std::unique_ptr<Scheme> makeExplicitParallel(const CouplingSpec& spec, const SchemeHost& host);
std::unique_ptr<Scheme> makeImplicitSerial(const CouplingSpec& spec, const SchemeHost& host);
std::unique_ptr<Scheme> makeImplicitParallel(const CouplingSpec& spec, const SchemeHost& host);
}  // namespace cosim
