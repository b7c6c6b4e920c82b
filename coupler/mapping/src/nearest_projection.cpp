// The nearest_projection mapping (cosim/mapping.hpp).
#include <algorithm>
#include <limits>
#include <stdexcept>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "common/geometry.hpp"
#include "mappings.hpp"

namespace cosim {

namespace {

class NearestProjection final : public Mapping {
 public:
  NearestProjection(const InterfaceMesh& from, const InterfaceMesh& to) {
    if (from.triangles.empty())
      throw std::invalid_argument("nearest_projection mapping: the source mesh has no triangles (use nearest_neighbor)");
    std::vector<Eigen::Triplet<double>> t;
    for (std::size_t i = 0; i < to.nodes.size(); ++i) {
      // Closest point over all source triangles; its barycentric weights interpolate linear fields exactly.
      common::ClosestPoint best;
      best.distanceSquared = std::numeric_limits<double>::infinity();
      std::size_t tri = 0;
      for (std::size_t k = 0; k < from.triangles.size(); ++k) {
        const auto& T = from.triangles[k];
        const auto cp = common::closestPointOnTriangle(to.nodes[i], from.nodes[T[0]], from.nodes[T[1]], from.nodes[T[2]]);
        if (cp.distanceSquared < best.distanceSquared) {
          best = cp;
          tri = k;
        }
      }
      // A node that coincides with a source vertex (to 1e-9 of the edge, as the identity mapping's
      // tolerance) takes that vertex's value alone, so meshes that share nodes map by copying.
      for (auto& w : best.bary)
        if (w >= 1.0 - 1e-9) {
          best.bary = {0.0, 0.0, 0.0};
          w = 1.0;
          break;
        }
      for (int k = 0; k < 3; ++k)
        if (best.bary[static_cast<std::size_t>(k)] != 0.0)
          t.emplace_back(static_cast<int>(i), static_cast<int>(from.triangles[tri][static_cast<std::size_t>(k)]),
                         best.bary[static_cast<std::size_t>(k)]);
    }
    setMatrix(t, to.nodes.size(), from.nodes.size());
  }
  std::string name() const override { return "nearest_projection"; }
};

}  // namespace

std::unique_ptr<Mapping> makeNearestProjection(const InterfaceMesh& from, const InterfaceMesh& to) {
  return std::make_unique<NearestProjection>(from, to);
}

}  // namespace cosim
