#include "lattice/volume_geometry.hpp"

#include <algorithm>
#include <map>
#include <set>
#include <stdexcept>
#include <unordered_map>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <gmsh.h>

#include "common/memory.hpp"
#include "common/gmsh_session.hpp"

namespace lattice {

ClosedSurface VolumeGeometry::closedSurface() const {
  std::vector<Triangle> all;
  for (const auto& s : surfaces) all.insert(all.end(), s.triangles.begin(), s.triangles.end());
  return ClosedSurface(vertices, std::move(all));
}

namespace {

std::vector<int> tagsOf(const gmsh::vectorpair& dimTags) {
  std::set<int> tags;
  for (const auto& dt : dimTags) tags.insert(std::abs(dt.second));
  return {tags.begin(), tags.end()};
}

gmsh::vectorpair boundaryOf(int dim, const std::vector<int>& tags) {
  gmsh::vectorpair in, out;
  for (int t : tags) in.emplace_back(dim, t);
  gmsh::model::getBoundary(in, out, false, false, false);
  return out;
}

VolumeGeometry read(const std::filesystem::path& file, int volumeTag, double meshSize, double scale) {
  VolumeGeometry g;
  try {
    common::openGmshFile(file);
  } catch (const std::exception& e) {
    throw std::invalid_argument(fmt::format("gmsh cannot read \"{}\": {}", file.string(), e.what()));
  }
  gmsh::vectorpair volumes;
  gmsh::model::getEntities(volumes, 3);
  const std::vector<int> tags = tagsOf(volumes);
  if (tags.empty())
    throw std::invalid_argument(fmt::format("\"{}\" defines no volume (3-D entity); the specimen needs a closed volume "
                                            "(e.g. `Volume` or `Extrude` in a .geo file, a solid in a .step file)",
                                            file.string()));
  if (volumeTag == 0) {
    if (tags.size() > 1)
      throw std::invalid_argument(fmt::format("\"{}\" has {} volumes (tags {}); choose one with specimen.geometry.volume",
                                              file.string(), tags.size(), fmt::join(tags, ", ")));
    volumeTag = tags.front();
  } else if (std::find(tags.begin(), tags.end(), volumeTag) == tags.end()) {
    throw VolumeTagError(fmt::format("\"{}\" has no volume {} (its volumes: {})", file.string(), volumeTag, fmt::join(tags, ", ")));
  }
  g.volume = volumeTag;
  // The rods the specimen will need, from the volume's bounding box (rod length = 2 × the surface mesh
  // size): refused before gmsh meshes surfaces at a size that alone could take hours (issue 30).
  // A .msh file is meshed already (and gmsh gives a discrete volume no bounding box): the scene checks
  // the rod count from the surface mesh's bounds instead.
  if (file.extension() != ".msh") {
    double x0 = 0, y0 = 0, z0 = 0, x1 = 0, y1 = 0, z1 = 0;
    gmsh::model::getBoundingBox(3, volumeTag, x0, y0, z0, x1, y1, z1);
    const double lx = (x1 - x0) * scale, ly = (y1 - y0) * scale, lz = (z1 - z0) * scale, rod = 2.0 * meshSize;
    const double rods = 16.0 * lx * ly * lz / (rod * rod * rod);
    if (auto shortfall = common::memoryShortfall(500.0 * rods, fmt::format("about {:.3g} rods", rods)))
      throw std::invalid_argument(fmt::format("rod_length {} m in volume {} ({:.4g} × {:.4g} × {:.4g} m bounding box) {}; "
                                              "raise specimen.rod_length",
                                              rod, volumeTag, lx, ly, lz, *shortfall));
  }
  const bool meshFile = file.extension() == ".msh";
  try {
    if (!meshFile) {
      gmsh::option::setNumber("Mesh.MeshSizeMax", meshSize / scale);
      gmsh::model::mesh::generate(2);
    }
  } catch (const std::exception& e) {
    throw std::invalid_argument(fmt::format("gmsh cannot mesh the surfaces of \"{}\": {}", file.string(), e.what()));
  }
  const std::vector<int> surfaces = tagsOf(boundaryOf(3, {volumeTag}));
  if (surfaces.empty()) throw std::invalid_argument(fmt::format("volume {} of \"{}\" has no boundary surfaces", volumeTag, file.string()));
  const std::vector<int> curves = tagsOf(boundaryOf(2, surfaces));
  const std::vector<int> points = tagsOf(boundaryOf(1, curves));

  std::unordered_map<std::size_t, std::uint32_t> index;  // gmsh node tag → vertex
  std::vector<std::size_t> used;
  auto vertex = [&](std::size_t tag) {
    auto [it, fresh] = index.try_emplace(tag, static_cast<std::uint32_t>(used.size()));
    if (fresh) used.push_back(tag);
    return it->second;
  };
  for (int s : surfaces) {
    std::vector<std::size_t> elements, nodes;
    gmsh::model::mesh::getElementsByType(2, elements, nodes, s);  // type 2: 3-node triangle
    if (elements.empty())
      throw std::invalid_argument(fmt::format("surface {} of volume {} in \"{}\" has no 3-node triangles{}", s, volumeTag,
                                              file.string(),
                                              meshFile ? " (save the .msh with its surface elements: Mesh.SaveAll = 1, first order)" : ""));
    VolumeGeometry::Surface surface{s, {}};
    for (std::size_t e = 0; e < elements.size(); ++e)
      surface.triangles.push_back({vertex(nodes[3 * e]), vertex(nodes[3 * e + 1]), vertex(nodes[3 * e + 2])});
    g.surfaces.push_back(std::move(surface));
  }
  for (int c : curves) {
    std::vector<std::size_t> elements, nodes;
    gmsh::model::mesh::getElementsByType(1, elements, nodes, c);  // type 1: 2-node line
    std::vector<std::array<std::uint32_t, 2>> segments;
    for (std::size_t e = 0; e < elements.size(); ++e)
      if (index.count(nodes[2 * e]) && index.count(nodes[2 * e + 1])) segments.push_back({index[nodes[2 * e]], index[nodes[2 * e + 1]]});
    if (!segments.empty()) g.curves.push_back(std::move(segments));
  }
  for (int p : points) {
    std::vector<std::size_t> nodeTags;
    std::vector<double> coords, param;
    gmsh::model::mesh::getNodes(nodeTags, coords, param, 0, p);
    for (auto t : nodeTags)
      if (index.count(t)) g.corners.push_back(index[t]);
  }
  g.vertices = common::gmshNodeCoordinates(used);
  for (auto& v : g.vertices) v *= scale;
  return g;
}

}  // namespace

VolumeGeometry readVolumeGeometry(const std::filesystem::path& file, int volumeTag, double meshSize, double scale) {
  if (!std::filesystem::exists(file)) throw std::invalid_argument(fmt::format("the file \"{}\" does not exist", file.string()));
  common::GmshSession session;
  try {
    return read(file, volumeTag, meshSize, scale);
  } catch (const std::invalid_argument&) {
    throw;  // VolumeTagError included
  } catch (const std::exception& e) {
    throw std::invalid_argument(fmt::format("gmsh failed on \"{}\": {}", file.string(), e.what()));
  } catch (...) {
    throw std::invalid_argument(fmt::format("gmsh failed on \"{}\"", file.string()));
  }
}

}  // namespace lattice
