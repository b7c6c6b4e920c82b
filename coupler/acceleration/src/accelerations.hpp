#pragma once
// The accelerations, one per source file, each reading its own keys of `coupling.acceleration`;
// registered by name in acceleration.cpp.
#include "common/config.hpp"
#include "cosim/acceleration.hpp"

namespace cosim {
AccelerationMake readConstant(const common::Config& keys);
AccelerationMake readAitken(const common::Config& keys);
AccelerationMake readIqnIls(const common::Config& keys);
}  // namespace cosim
