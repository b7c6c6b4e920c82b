#include "common/mesh_io.hpp"

#include <omp.h>

#include <fstream>
#include <map>
#include <mutex>
#include <unordered_map>

#include <fmt/format.h>
#include <gmsh.h>

#include "common/errors.hpp"

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

}  // namespace

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

TriangleMesh readTriangleMesh(const std::filesystem::path& file, const std::string& physical) {
  if (!std::filesystem::exists(file))
    throw SimulationError(fmt::format("mesh file \"{}\" does not exist.", file.string()));
  GmshSession session;
  TriangleMesh mesh;
  try {
    gmsh::open(file.string());
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
