#include "cosim/mapping.hpp"

#include <algorithm>
#include <stdexcept>

#include <fmt/format.h>

#include "common/registry.hpp"
#include "mappings.hpp"

namespace cosim {
namespace {
using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// in has nIn nodes × c values, out nOut × c; the message names the direction of the call.
void checkSizes(const std::string& name, std::size_t in, std::size_t out, std::size_t nIn, std::size_t nOut, int c) {
  const auto cc = static_cast<std::size_t>(c);
  if (in != nIn * cc || out != nOut * cc)
    throw std::invalid_argument(fmt::format("{} mapping: field sizes {} → {} do not match meshes {} → {} nodes × {}",
                                            name, in, out, nIn, nOut, c));
}
}  // namespace

void Mapping::setMatrix(const std::vector<Eigen::Triplet<double>>& weights, std::size_t to, std::size_t from) {
  matrix_.resize(static_cast<Eigen::Index>(to), static_cast<Eigen::Index>(from));
  matrix_.setFromTriplets(weights.begin(), weights.end());
  copyIfSelection();
}

void Mapping::copyIfSelection() {
  if (matrix_.nonZeros() != matrix_.rows()) return;
  std::vector<std::uint32_t> select(static_cast<std::size_t>(matrix_.rows()));
  bool identity = matrix_.rows() == matrix_.cols();
  for (Eigen::Index i = 0; i < matrix_.outerSize(); ++i) {
    Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(matrix_, i);
    if (!it || it.value() != 1.0) return;
    select[static_cast<std::size_t>(i)] = static_cast<std::uint32_t>(it.col());
    identity = identity && it.col() == i;
  }
  if (identity) identity_ = true;
  else select_ = std::move(select);
}

void Mapping::consistent(std::span<const double> from, std::span<double> to, int c) const {
  checkSizes(name(), from.size(), to.size(), fromSize(), toSize(), c);
  if (identity_) {
    std::copy(from.begin(), from.end(), to.begin());
    return;
  }
  const auto cc = static_cast<std::size_t>(c);
  if (!select_.empty()) {
    for (std::size_t i = 0; i < select_.size(); ++i)
      std::copy_n(from.begin() + static_cast<std::ptrdiff_t>(select_[i] * cc), cc, to.begin() + static_cast<std::ptrdiff_t>(i * cc));
    return;
  }
  Eigen::Map<RowMajor>(to.data(), toSize(), c) = matrix_ * Eigen::Map<const RowMajor>(from.data(), fromSize(), c);
}

void Mapping::conservative(std::span<const double> to, std::span<double> from, int c) const {
  checkSizes(name(), to.size(), from.size(), toSize(), fromSize(), c);
  if (identity_) {
    std::copy(to.begin(), to.end(), from.begin());
    return;
  }
  const auto cc = static_cast<std::size_t>(c);
  if (!select_.empty()) {
    std::fill(from.begin(), from.end(), 0.0);
    for (std::size_t i = 0; i < select_.size(); ++i)
      for (std::size_t k = 0; k < cc; ++k) from[select_[i] * cc + k] += to[i * cc + k];
    return;
  }
  Eigen::Map<RowMajor>(from.data(), fromSize(), c) =
      matrix_.transpose() * Eigen::Map<const RowMajor>(to.data(), toSize(), c);
}

namespace {
using Factory = std::unique_ptr<Mapping> (*)(const InterfaceMesh&, const InterfaceMesh&);
struct Entry {
  const char* name;
  Factory make;
};
const Entry kMappings[] = {
    {"identity", makeIdentity}, {"nearest_neighbor", makeNearestNeighbor}, {"nearest_projection", makeNearestProjection},
    {"barycentric", makeBarycentric}};
constexpr common::Registry<Entry> kRegistry{kMappings, "mapping"};
}  // namespace

std::vector<std::string> mappingNames() { return kRegistry.names(); }

std::unique_ptr<Mapping> makeMapping(const std::string& name, const InterfaceMesh& from, const InterfaceMesh& to) {
  return kRegistry.at(name).make(from, to);
}

}  // namespace cosim
