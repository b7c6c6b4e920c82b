#include "fem/element.hpp"

#include <fmt/format.h>

#include "common/errors.hpp"

namespace fem {

void Element::addPressure(double, const Vec3&, std::span<double>) const {
  throw common::ConfigError(fmt::format("a pressure load needs surface elements; \"{}\" has none.", name()));
}

}  // namespace fem
