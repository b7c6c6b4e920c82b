#include "common/gmsh_session.hpp"

#include <omp.h>

#include <array>
#include <cstdint>
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

void openGmshFile(const std::filesystem::path& file) {
  checkGmshHeader(file);
  gmsh::open(file.string());
}

TriangleMesh gmshReadTriangleMesh(const std::filesystem::path& file, const std::string& physical) {
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

}  // namespace common
