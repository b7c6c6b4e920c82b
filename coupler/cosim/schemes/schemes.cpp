#include "schemes.hpp"

#include "common/registry.hpp"

namespace cosim {

namespace {
struct Entry {
  const char* name;
  std::unique_ptr<Scheme> (*make)(const CouplingSpec&, const SchemeHost&);
};
const Entry kSchemes[] = {
    {"implicit", makeImplicitSerial},
    {"implicit_parallel", makeImplicitParallel},
    {"explicit_serial", makeExplicitSerial},
    {"explicit_parallel", makeExplicitParallel},
};
constexpr common::Registry<Entry> kRegistry{kSchemes, "coupling scheme"};
}  // namespace

std::vector<std::string> schemeNames() { return kRegistry.names(); }

std::unique_ptr<Scheme> makeScheme(const CouplingSpec& spec, const SchemeHost& host) {
  return kRegistry.at(spec.scheme).make(spec, host);
}

}  // namespace cosim
