// The identity mapping (cosim/mapping.hpp).
#include <algorithm>
#include <limits>
#include <stdexcept>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "common/geometry.hpp"
#include "mappings.hpp"

namespace cosim {

namespace {

class Identity final : public Mapping {
 public:
  Identity(const InterfaceMesh& from, const InterfaceMesh& to) {
    if (from.nodes.size() != to.nodes.size())
      throw std::invalid_argument(fmt::format("identity mapping needs the same nodes on both sides ({} vs {})",
                                              from.nodes.size(), to.nodes.size()));
    double scale = 0.0;
    for (const auto& x : from.nodes) scale = std::max(scale, x.cwiseAbs().maxCoeff());
    for (std::size_t i = 0; i < from.nodes.size(); ++i)
      if ((from.nodes[i] - to.nodes[i]).norm() > 1e-9 * std::max(scale, 1.0))
        throw std::invalid_argument(fmt::format(
            "identity mapping: node {} differs between the meshes ({} vs {}); use nearest_neighbor or nearest_projection",
            i, fmt::join(from.nodes[i].data(), from.nodes[i].data() + 3, ", "),
            fmt::join(to.nodes[i].data(), to.nodes[i].data() + 3, ", ")));
    matrix_.resize(static_cast<Eigen::Index>(to.nodes.size()), static_cast<Eigen::Index>(from.nodes.size()));
    matrix_.setIdentity();
    identity_ = true;
  }
  std::string name() const override { return "identity"; }
};

}  // namespace

std::unique_ptr<Mapping> makeIdentity(const InterfaceMesh& from, const InterfaceMesh& to) {
  return std::make_unique<Identity>(from, to);
}

}  // namespace cosim
