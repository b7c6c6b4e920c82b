#include "cosim/acceleration.hpp"

#include "accelerations.hpp"
#include "common/config.hpp"
#include "common/registry.hpp"

namespace cosim {

namespace {
using common::Interval;

struct Entry {
  const char* name;
  std::unique_ptr<Acceleration> (*make)(const AccelerationParams&);
  /// Its own keys of `coupling.acceleration` (relaxation is everyone's).
  void (*readKeys)(const common::Config&, AccelerationParams&);
};

void noKeys(const common::Config&, AccelerationParams&) {}

void iqnIlsKeys(const common::Config& c, AccelerationParams& p) {
  p.reusedWindows = c.get<int>("reused_windows", p.reusedWindows);
  p.maxColumns = c.get<int>("max_columns", p.maxColumns);
  p.filter = c.get("filter", p.filter, Interval::positive());
  p.filterType = qrFilterNamed(c.choice("filter_type", qrFilterNames(), "qr2"));
  const std::string active = c.choice("active_set", {"keep", "mask", "drop"}, "keep");
  p.activeSet = active == "mask"   ? AccelerationParams::ActiveSet::kMask
                : active == "drop" ? AccelerationParams::ActiveSet::kDrop
                                   : AccelerationParams::ActiveSet::kKeep;
}

const Entry kAccelerations[] = {
    {"constant", makeConstant, noKeys},
    {"aitken", makeAitken, noKeys},
    {"iqn_ils", makeIqnIls, iqnIlsKeys},
};
constexpr common::Registry<Entry> kRegistry{kAccelerations, "acceleration"};
}  // namespace

std::vector<std::string> accelerationNames() { return kRegistry.names(); }

std::unique_ptr<Acceleration> makeAcceleration(const std::string& name, const AccelerationParams& params) {
  return kRegistry.at(name).make(params);
}

std::string readAcceleration(const common::Config& c, AccelerationParams& params) {
  const std::string type = c.choice("type", accelerationNames());
  params.relaxation = c.get("relaxation", params.relaxation, Interval{0, 2, true, false});
  kRegistry.at(type).readKeys(c, params);
  return type;
}

}  // namespace cosim
