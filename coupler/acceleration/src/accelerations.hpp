#pragma once
// Factories of the accelerations, one per source file; registered by name in acceleration.cpp.
#include "cosim/acceleration.hpp"

namespace cosim {
std::unique_ptr<Acceleration> makeConstant(const AccelerationParams& p);
std::unique_ptr<Acceleration> makeAitken(const AccelerationParams& p);
std::unique_ptr<Acceleration> makeIqnIls(const AccelerationParams& p);
}  // namespace cosim
