#include "fem/bridging.hpp"

#include <unordered_map>

#include <fmt/format.h>

#include "common/errors.hpp"

namespace fem {

void weighBridgingZone(Model& model, const common::BridgingZone& zone) {
  for (auto& block : model.blocks) {
    const auto& conn = block->connectivity();
    const auto per = static_cast<std::size_t>(block->nodesPerElement());
    std::vector<double> w(block->size());
    bool weighted = false;
    for (std::size_t e = 0; e < w.size(); ++e) {
      Vec3 centroid = Vec3::Zero();
      for (std::size_t k = 0; k < per; ++k) centroid += model.reference[conn[per * e + k]];
      w[e] = zone.massWeight(centroid / static_cast<double>(per));
      weighted = weighted || w[e] < 1.0;
    }
    if (weighted) block->setWeights(std::move(w));
  }
}

BridgeCells bridgeCells(const Model& model, const common::BridgingZone& zone) {
  BridgeCells out;
  std::unordered_map<std::uint32_t, std::uint32_t> local;
  for (const auto& block : model.blocks) {
    const int per = block->nodesPerElement();
    if (block->weights().empty()) continue;  // no element of it in the zone
    if (out.nodesPerCell != 0 && out.nodesPerCell != per)
      throw common::ConfigError("bridging: the overlap holds elements of different kinds; one kind (truss, "
                                "membrane_tri3 or tet4) may overlap the particles");
    out.nodesPerCell = per;
    const auto& conn = block->connectivity();
    const auto n = static_cast<std::size_t>(per);
    for (std::size_t e = 0; e < block->size(); ++e) {
      bool touches = false;
      for (std::size_t k = 0; k < n; ++k) touches = touches || zone.overlaps(model.reference[conn[n * e + k]]);
      if (!touches) continue;
      for (std::size_t k = 0; k < n; ++k) {
        const std::uint32_t node = conn[n * e + k];
        const auto [it, added] = local.try_emplace(node, static_cast<std::uint32_t>(out.nodes.size()));
        if (added) out.nodes.push_back(node);
        out.cells.push_back(it->second);
      }
    }
  }
  if (out.cells.empty())
    throw common::ConfigError("bridging: no element lies in the zone (every element's centroid has weight 1): the "
                              "zone's `full` and `none` must span elements of the mesh");
  return out;
}

}  // namespace fem
