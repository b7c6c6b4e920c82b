#include "cosim/acceleration.hpp"

#include <stdexcept>

#include <fmt/format.h>

#include "accelerations.hpp"

namespace cosim {

namespace {
using Factory = std::unique_ptr<Acceleration> (*)(const AccelerationParams&);
struct Entry {
  const char* name;
  Factory make;
};
// The explicit list (a static library would drop self-registering objects).
const Entry kAccelerations[] = {{"constant", makeConstant}, {"aitken", makeAitken}, {"iqn_ils", makeIqnIls}};
}  // namespace

std::vector<std::string> accelerationNames() {
  std::vector<std::string> names;
  for (const auto& e : kAccelerations) names.emplace_back(e.name);
  return names;
}

std::unique_ptr<Acceleration> makeAcceleration(const std::string& name, const AccelerationParams& params) {
  for (const auto& e : kAccelerations)
    if (name == e.name) return e.make(params);
  throw std::invalid_argument(fmt::format("unknown acceleration \"{}\"", name));
}

}  // namespace cosim
