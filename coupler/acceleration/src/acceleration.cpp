#include "cosim/acceleration.hpp"

#include "accelerations.hpp"
#include "common/config.hpp"
#include "common/registry.hpp"

namespace cosim {

namespace {

struct Entry {
  const char* name;
  /// Reads its own keys of `coupling.acceleration` (relaxation is everyone's) into its make.
  AccelerationMake (*read)(const common::Config& keys);
};

const Entry kAccelerations[] = {
    {"constant", readConstant},
    {"aitken", readAitken},
    {"iqn_ils", readIqnIls},
};
constexpr common::Registry<Entry> kRegistry{kAccelerations, "acceleration"};

}  // namespace

std::vector<std::string> accelerationNames() { return kRegistry.names(); }

AccelerationSpec readAcceleration(const common::Config& c) {
  AccelerationSpec spec;
  spec.type = c.choice("type", accelerationNames());
  spec.relaxation = c.get("relaxation", spec.relaxation, common::Interval{0, 2, true, false});
  spec.make = kRegistry.at(spec.type).read(c);
  return spec;
}

AccelerationSpec defaultAcceleration() {
  AccelerationSpec spec;
  spec.make = kRegistry.at(spec.type).read(common::Config{});
  return spec;
}

std::unique_ptr<Acceleration> makeAcceleration(const std::string& type, double relaxation) {
  return kRegistry.at(type).read(common::Config{})(relaxation);
}

}  // namespace cosim
