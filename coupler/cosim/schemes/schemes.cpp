#include "schemes.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "common/config.hpp"
#include "common/registry.hpp"

namespace cosim {

namespace {
struct Entry {
  const char* name;
  SchemeKeys (*read)(const common::Config&, CouplingSpec&);
  const std::vector<std::string>* meshes = nullptr;  // the meshes it sends and reads itself
};
const Entry kSchemes[] = {
    {"implicit", readImplicitSerial},
    {"implicit_parallel", readImplicitParallel},
    {"explicit_serial", readExplicitSerial},
    {"explicit_parallel", readExplicitParallel},
    {"bridging", readBridging, &kBridgeMeshes},
};
constexpr common::Registry<Entry> kRegistry{kSchemes, "coupling scheme"};

// What readIterationKeys reads: under an explicit scheme each would be silently without effect.
const char* const kIterationKeys[] = {"max_iterations", "tolerance",       "require_convergence", "extrapolation",
                                      "acceleration",   "min_time_window", "grow_after"};
}  // namespace

void refuseIterationKeys(const common::Config& c, CouplingSpec& spec) {
  spec.minWindow = spec.window;  // a weak scheme never repeats a window, so never halves one
  std::vector<std::string> present;
  for (const char* key : kIterationKeys)
    if (c.child(key)) present.push_back(key);
  if (present.empty()) return;
  std::vector<std::string> removal;
  for (const auto& key : present) removal.push_back(fmt::format("--set coupling.{}=null", key));
  c.failAt(present.front(),
           fmt::format("is a key of the implicit schemes (implicit, implicit_parallel), which iterate a window; {} "
                       "does not iterate a window to a tolerance and would ignore it. Remove {} from the scene, or on the "
                       "command line: {}",
                       spec.scheme, fmt::join(present, ", "), fmt::join(removal, " ")));
}

std::vector<std::string> schemeNames() { return kRegistry.names(); }

std::vector<std::string> schemeMeshes(const CouplingSpec& spec) {
  const auto* own = kRegistry.at(spec.scheme).meshes;
  return own ? *own : std::vector<std::string>{};
}

FieldToleranceKeys readSchemeKeys(const common::Config& coupling, CouplingSpec& spec) {
  SchemeKeys keys = kRegistry.at(spec.scheme).read(coupling, spec);
  spec.makeScheme = std::move(keys.make);
  return std::move(keys.fieldTolerances);
}

}  // namespace cosim
