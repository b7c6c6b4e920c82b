#include "common/mesh_io.hpp"

#include <omp.h>

#include <algorithm>
#include <cstdint>
#include <fstream>
#include <map>
#include <mutex>
#include <unordered_map>

#include <fmt/format.h>
#include <gmsh.h>

#include "common/errors.hpp"
#include "common/memory.hpp"

namespace common {

namespace {

std::mutex& gmshMutex() {
  static std::mutex m;
  return m;
}

void ensureGmsh() {
  static bool initialised = false;
  if (initialised) return;
  gmsh::initialize(0, nullptr, false);
  gmsh::option::setNumber("General.Terminal", 0);
  gmsh::option::setNumber("General.Verbosity", 1);
  gmsh::option::setNumber("General.AbortOnError", 3);  // throw, never exit
  initialised = true;
}

// The counts a gmsh section header claims ($Nodes: numEntityBlocks numNodes minTag maxTag; $Elements the same;
// version 2: one count), read as text or, in a binary file, as size_t.
struct SectionHeader {
  double count = 0, maxTag = 0;
  bool found = false;
};

SectionHeader readSectionHeader(std::istream& in, bool binary, bool v4) {
  SectionHeader h;
  h.found = true;
  if (!v4) {
    in >> h.count;
    h.maxTag = h.count;
    return h;
  }
  if (binary) {
    std::uint64_t v[4] = {};
    in.read(reinterpret_cast<char*>(v), sizeof v);
    h.count = static_cast<double>(v[1]);
    h.maxTag = static_cast<double>(v[3]);
  } else {
    double blocks = 0, minTag = 0;
    in >> blocks >> h.count >> minTag >> h.maxTag;
  }
  return h;
}

}  // namespace

void checkGmshHeader(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) return;  // gmsh says why
  const double bytes = static_cast<double>(std::filesystem::file_size(file));
  bool binary = false, v4 = true;
  SectionHeader nodes, elements;
  std::string line;
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line == "$MeshFormat") {
      double version = 0;
      int type = 0, size = 0;
      in >> version >> type >> size;
      v4 = version >= 4;
      binary = type == 1;
      std::getline(in, line);
    } else if (line == "$Nodes") {
      nodes = readSectionHeader(in, binary, v4);
    } else if (line == "$Elements") {
      elements = readSectionHeader(in, binary, v4);
    }
    if (nodes.found && elements.found) break;
  }
  // Every node takes at least 8 bytes of the file (a tag and three coordinates: "1\n0 0 0\n", or 24 bytes of
  // binary coordinates), every element at least 8 ("1 2 3 4\n"); a header that claims more describes no
  // file of this size, and gmsh would allocate for it before finding out.
  auto refuse = [&](const std::string& why) {
    throw SimulationError(fmt::format("mesh file \"{}\": {}; the file is not a mesh gmsh can read.", file.string(), why));
  };
  for (const auto& [name, h] : {std::pair{"nodes", nodes}, std::pair{"elements", elements}}) {
    if (!h.found) continue;
    if (!(h.count >= 0) || h.count * 8 > bytes)
      refuse(fmt::format("its header claims {:.3g} {}, more than its {:.0f} bytes can hold", h.count, name, bytes));
    // gmsh may index its entities by tag (a pointer per tag up to the largest): a largest tag far beyond
    // the count allocates for the gaps.
    if (!(h.maxTag >= 0)) refuse(fmt::format("its header's largest {} tag is {}", name, h.maxTag));
    if (auto shortfall = memoryShortfall(std::max(h.count, h.maxTag) * 8.0,
                                         fmt::format("the {} tags up to {:.3g} of its header", name, h.maxTag)))
      refuse(*shortfall);
  }
}

GmshSession::GmshSession() : lock_(gmshMutex()), threads_(omp_get_max_threads()) {
  ensureGmsh();
  gmsh::clear();
}

GmshSession::~GmshSession() { omp_set_num_threads(threads_); }

std::vector<Eigen::Vector3d> gmshNodeCoordinates(const std::vector<std::size_t>& tags) {
  std::vector<std::size_t> all;
  std::vector<double> coords, param;
  gmsh::model::mesh::getNodes(all, coords, param, -1, -1, true, false);
  std::unordered_map<std::size_t, std::size_t> where;
  for (std::size_t i = 0; i < all.size(); ++i) where[all[i]] = i;
  std::vector<Eigen::Vector3d> out(tags.size());
  for (std::size_t i = 0; i < tags.size(); ++i) {
    const std::size_t k = where.at(tags[i]);
    out[i] = Eigen::Vector3d(coords[3 * k], coords[3 * k + 1], coords[3 * k + 2]);
  }
  return out;
}

void openGmshFile(const std::filesystem::path& file) {
  checkGmshHeader(file);
  gmsh::open(file.string());
}

TriangleMesh readTriangleMesh(const std::filesystem::path& file, const std::string& physical) {
  if (!std::filesystem::exists(file))
    throw SimulationError(fmt::format("mesh file \"{}\" does not exist.", file.string()));
  GmshSession session;
  TriangleMesh mesh;
  try {
    openGmshFile(file);
    std::vector<int> entities{-1};
    if (!physical.empty()) {
      entities.clear();
      gmsh::vectorpair groups;
      gmsh::model::getPhysicalGroups(groups, 2);
      std::string names;
      for (const auto& [dim, tag] : groups) {
        std::string name;
        gmsh::model::getPhysicalName(dim, tag, name);
        names += (names.empty() ? "" : ", ") + name;
        if (name == physical) gmsh::model::getEntitiesForPhysicalGroup(dim, tag, entities);
      }
      if (entities.empty())
        throw SimulationError(fmt::format("mesh file \"{}\" has no 2-D physical group \"{}\" (it has: {}).",
                                          file.string(), physical, names.empty() ? "none" : names));
    }
    std::unordered_map<std::size_t, std::uint32_t> index;
    std::vector<std::size_t> used;
    for (int entity : entities) {
      std::vector<std::size_t> elementTags, nodeTags;
      gmsh::model::mesh::getElementsByType(2, elementTags, nodeTags, entity);
      for (std::size_t e = 0; e < elementTags.size(); ++e) {
        std::array<std::uint32_t, 3> tri{};
        for (int k = 0; k < 3; ++k) {
          const std::size_t tag = nodeTags[3 * e + static_cast<std::size_t>(k)];
          auto [it, fresh] = index.try_emplace(tag, static_cast<std::uint32_t>(used.size()));
          if (fresh) used.push_back(tag);
          tri[static_cast<std::size_t>(k)] = it->second;
        }
        mesh.triangles.push_back(tri);
      }
    }
    if (mesh.triangles.empty())
      throw SimulationError(fmt::format("mesh file \"{}\" contains no 3-node triangles{}.", file.string(),
                                        physical.empty() ? "" : " in group \"" + physical + "\""));
    mesh.nodes = gmshNodeCoordinates(used);
  } catch (const SimulationError&) {
    throw;
  } catch (const std::exception& e) {
    throw SimulationError(fmt::format("gmsh cannot read mesh file \"{}\": {}", file.string(), e.what()));
  } catch (const std::string& e) {  // gmsh 4.8's API throws its last error as a std::string
    throw SimulationError(fmt::format("gmsh cannot read mesh file \"{}\": {}", file.string(), e));
  } catch (...) {
    throw SimulationError(fmt::format("gmsh cannot read mesh file \"{}\".", file.string()));
  }
  return mesh;
}

void writeStl(const std::filesystem::path& file, const TriangleMesh& mesh) {
  std::ofstream out(file);
  out << "solid mesh\n";
  for (const auto& t : mesh.triangles) {
    const Eigen::Vector3d &a = mesh.nodes[t[0]], &b = mesh.nodes[t[1]], &c = mesh.nodes[t[2]];
    Eigen::Vector3d n = (b - a).cross(c - a);
    if (n.norm() > 0) n.normalize();
    out << fmt::format(" facet normal {:.17g} {:.17g} {:.17g}\n  outer loop\n", n.x(), n.y(), n.z());
    for (const auto* p : {&a, &b, &c}) out << fmt::format("   vertex {:.17g} {:.17g} {:.17g}\n", p->x(), p->y(), p->z());
    out << "  endloop\n endfacet\n";
  }
  out << "endsolid mesh\n";
  if (!out) throw SimulationError(fmt::format("cannot write {}.", file.string()));
}

}  // namespace common
