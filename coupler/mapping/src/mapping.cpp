#include "cosim/mapping.hpp"

#include <algorithm>
#include <stdexcept>

#include <fmt/format.h>

#include "mappings.hpp"

namespace cosim {
void Mapping::consistent(std::span<const double> from, std::span<double> to, int c) const {
  const auto cc = static_cast<std::size_t>(c);
  if (from.size() != fromSize() * cc || to.size() != toSize() * cc)
    throw std::invalid_argument(fmt::format("{} mapping: field sizes {} → {} do not match meshes {} → {} nodes × {}",
                                            name(), from.size(), to.size(), fromSize(), toSize(), c));
  if (identity_) {
    std::copy(from.begin(), from.end(), to.begin());
    return;
  }
  Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> in(from.data(), fromSize(), c);
  Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> out(to.data(), toSize(), c);
  out = matrix_ * in;
}

void Mapping::conservative(std::span<const double> to, std::span<double> from, int c) const {
  const auto cc = static_cast<std::size_t>(c);
  if (from.size() != fromSize() * cc || to.size() != toSize() * cc)
    throw std::invalid_argument(fmt::format("{} mapping: field sizes {} → {} do not match meshes {} → {} nodes × {}",
                                            name(), to.size(), from.size(), toSize(), fromSize(), c));
  if (identity_) {
    std::copy(to.begin(), to.end(), from.begin());
    return;
  }
  Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> in(to.data(), toSize(), c);
  Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> out(from.data(), fromSize(), c);
  out = matrix_.transpose() * in;
}

namespace {
using Factory = std::unique_ptr<Mapping> (*)(const InterfaceMesh&, const InterfaceMesh&);
struct Entry {
  const char* name;
  Factory make;
};
// The explicit list of mappings (a static library would drop self-registering objects).
const Entry kMappings[] = {
    {"identity", makeIdentity}, {"nearest_neighbor", makeNearestNeighbor}, {"nearest_projection", makeNearestProjection}};
}  // namespace

std::vector<std::string> mappingNames() {
  std::vector<std::string> names;
  for (const auto& e : kMappings) names.emplace_back(e.name);
  return names;
}

std::unique_ptr<Mapping> makeMapping(const std::string& name, const InterfaceMesh& from, const InterfaceMesh& to) {
  for (const auto& e : kMappings)
    if (name == e.name) return e.make(from, to);
  throw std::invalid_argument(fmt::format("unknown mapping \"{}\"", name));
}

}  // namespace cosim
