// The nearest_neighbor mapping (cosim/mapping.hpp).
#include <algorithm>
#include <limits>
#include <stdexcept>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "common/geometry.hpp"
#include "mappings.hpp"

namespace cosim {

namespace {

class NearestNeighbor final : public Mapping {
 public:
  NearestNeighbor(const InterfaceMesh& from, const InterfaceMesh& to) {
    if (from.nodes.empty()) throw std::invalid_argument("nearest_neighbor mapping: the source mesh has no nodes");
    std::vector<Eigen::Triplet<double>> t;
    for (std::size_t i = 0; i < to.nodes.size(); ++i) {
      std::size_t best = 0;
      double d = std::numeric_limits<double>::infinity();
      for (std::size_t j = 0; j < from.nodes.size(); ++j) {
        const double dj = (from.nodes[j] - to.nodes[i]).squaredNorm();
        if (dj < d) {
          d = dj;
          best = j;
        }
      }
      t.emplace_back(static_cast<int>(i), static_cast<int>(best), 1.0);
    }
    setMatrix(t, to.nodes.size(), from.nodes.size());
  }
  std::string name() const override { return "nearest_neighbor"; }
};

}  // namespace

std::unique_ptr<Mapping> makeNearestNeighbor(const InterfaceMesh& from, const InterfaceMesh& to) {
  return std::make_unique<NearestNeighbor>(from, to);
}

}  // namespace cosim
