#include "fem/mesh.hpp"

#include <algorithm>
#include <unordered_map>

#include <fmt/format.h>
#include <gmsh.h>

#include "common/errors.hpp"
#include "common/gmsh_session.hpp"

namespace fem {

namespace {

// gmsh element type → (dimension, nodes): 1 line2, 2 tri3, 4 tet4, 15 point.
int nodesOf(int type) {
  switch (type) {
    case 1: return 2;
    case 2: return 3;
    case 4: return 4;
    case 15: return 1;
    default: return 0;
  }
}

// Collects the current gmsh model's physical groups into a Mesh (inside a GmshSession).
Mesh collect(const std::string& what) {
  Mesh mesh;
  std::vector<std::size_t> tags;
  std::vector<double> coords, param;
  gmsh::model::mesh::getNodes(tags, coords, param, -1, -1, true, false);
  std::unordered_map<std::size_t, std::uint32_t> index;
  for (std::size_t i = 0; i < tags.size(); ++i) {
    index.emplace(tags[i], static_cast<std::uint32_t>(mesh.nodes.size()));
    mesh.nodes.emplace_back(coords[3 * i], coords[3 * i + 1], coords[3 * i + 2]);
  }
  gmsh::vectorpair groups;
  gmsh::model::getPhysicalGroups(groups);
  for (const auto& [dim, tag] : groups) {
    std::string name;
    gmsh::model::getPhysicalName(dim, tag, name);
    if (name.empty()) name = fmt::format("{}", tag);
    Mesh::Group& g = mesh.groups[name];
    g.dim = dim;
    std::vector<int> entities;
    gmsh::model::getEntitiesForPhysicalGroup(dim, tag, entities);
    for (int e : entities) {
      std::vector<int> types;
      std::vector<std::vector<std::size_t>> elementTags, nodeTags;
      gmsh::model::mesh::getElements(types, elementTags, nodeTags, dim, e);
      for (std::size_t t = 0; t < types.size(); ++t) {
        const int n = nodesOf(types[t]);
        if (n == 0)
          throw common::SimulationError(fmt::format("{}: physical group \"{}\" has gmsh elements of type {}; only "
                                                    "linear lines, triangles and tetrahedra are supported.",
                                                    what, name, types[t]));
        for (auto nt : nodeTags[t]) g.connectivity.push_back(index.at(nt));
      }
    }
    g.nodes = g.connectivity;
    std::sort(g.nodes.begin(), g.nodes.end());
    g.nodes.erase(std::unique(g.nodes.begin(), g.nodes.end()), g.nodes.end());
  }
  // Drop nodes no element uses (gmsh keeps geometry points) by renumbering densely.
  std::vector<std::int64_t> used(mesh.nodes.size(), -1);
  std::vector<Eigen::Vector3d> kept;
  for (auto& [name, g] : mesh.groups)
    for (auto n : g.nodes)
      if (used[n] < 0) used[n] = 0;
  for (std::size_t i = 0; i < used.size(); ++i)
    if (used[i] >= 0) {
      used[i] = static_cast<std::int64_t>(kept.size());
      kept.push_back(mesh.nodes[i]);
    }
  for (auto& [name, g] : mesh.groups) {
    for (auto& n : g.connectivity) n = static_cast<std::uint32_t>(used[n]);
    for (auto& n : g.nodes) n = static_cast<std::uint32_t>(used[n]);
  }
  mesh.nodes = std::move(kept);
  return mesh;
}

}  // namespace

std::vector<std::string> Mesh::groupNames() const {
  std::vector<std::string> names;
  for (const auto& [n, g] : groups) names.push_back(n);
  return names;
}

Mesh readMesh(const std::filesystem::path& file) {
  if (!std::filesystem::exists(file))
    throw common::SimulationError(fmt::format("mesh file \"{}\" does not exist.", file.string()));
  common::GmshSession session;
  try {
    common::openGmshFile(file);
    Mesh m = collect(fmt::format("mesh file \"{}\"", file.string()));
    if (m.groups.empty())
      throw common::SimulationError(fmt::format("mesh file \"{}\" has no physical groups; name the surfaces, lines "
                                                "and volumes the scene refers to.",
                                                file.string()));
    return m;
  } catch (const common::SimulationError&) {
    throw;
  } catch (const std::exception& e) {
    throw common::SimulationError(fmt::format("gmsh cannot read mesh file \"{}\": {}", file.string(), e.what()));
  } catch (const std::string& e) {  // gmsh 4.8's API throws its last error as a std::string
    throw common::SimulationError(fmt::format("gmsh cannot read mesh file \"{}\": {}", file.string(), e));
  } catch (...) {
    throw common::SimulationError(fmt::format("gmsh cannot read mesh file \"{}\" (truncated, or not a mesh).", file.string()));
  }
}

Mesh rectangleMesh(double lx, double ly, double size, bool structured, const Eigen::Vector3d& origin) {
  common::GmshSession session;
  gmsh::model::add("rectangle");
  const int s = gmsh::model::occ::addRectangle(origin.x(), origin.y(), origin.z(), lx, ly);
  gmsh::model::occ::synchronize();
  gmsh::vectorpair boundary;
  gmsh::model::getBoundary({{2, s}}, boundary, false, false, false);
  std::vector<int> left, right, bottom, top, all;
  for (const auto& [dim, tag] : boundary) {
    const int c = std::abs(tag);
    all.push_back(c);
    double xmin, ymin, zmin, xmax, ymax, zmax;
    gmsh::model::getBoundingBox(1, c, xmin, ymin, zmin, xmax, ymax, zmax);
    // Classify by the edge's midpoint (OCC pads bounding boxes by ~1e-7).
    const double xm = 0.5 * (xmin + xmax) - origin.x(), ym = 0.5 * (ymin + ymax) - origin.y();
    const double tol = 1e-3 * std::min(lx, ly);
    if (std::abs(xm) < tol) left.push_back(c);
    else if (std::abs(xm - lx) < tol) right.push_back(c);
    else if (std::abs(ym) < tol) bottom.push_back(c);
    else top.push_back(c);
    if (structured) {
      const double length = std::max(xmax - xmin, ymax - ymin);
      gmsh::model::mesh::setTransfiniteCurve(c, std::max(2, static_cast<int>(std::lround(length / size)) + 1));
    }
  }
  if (structured) gmsh::model::mesh::setTransfiniteSurface(s, "Alternate");
  gmsh::option::setNumber("Mesh.MeshSizeMax", size);
  gmsh::option::setNumber("Mesh.MeshSizeMin", size);
  // Explicit, distinct tags: gmsh 4.8 can hand out the same automatic tag twice within a dimension.
  gmsh::model::addPhysicalGroup(2, {s}, 1);
  gmsh::model::setPhysicalName(2, 1, "surface");
  int nextTag = 1;
  auto addLines = [&](const std::vector<int>& curves, const std::string& name) {
    const int p = gmsh::model::addPhysicalGroup(1, curves, ++nextTag);
    gmsh::model::setPhysicalName(1, p, name);
  };
  addLines(all, "boundary");
  addLines(left, "left");
  addLines(right, "right");
  addLines(bottom, "bottom");
  addLines(top, "top");
  gmsh::model::mesh::generate(2);
  Mesh m = collect("rectangle mesh");
  // The node nearest the centre, as a group of its own (probes, point loads).
  const Eigen::Vector3d c = origin + Eigen::Vector3d(lx / 2, ly / 2, 0);
  std::uint32_t best = 0;
  for (std::uint32_t i = 0; i < m.nodes.size(); ++i)
    if ((m.nodes[i] - c).squaredNorm() < (m.nodes[best] - c).squaredNorm()) best = i;
  m.groups["center"] = Mesh::Group{0, {best}, {best}};
  return m;
}

Mesh boxMesh(const Eigen::Vector3d& size, double h, const Eigen::Vector3d& origin) {
  common::GmshSession session;
  gmsh::model::add("box");
  const int v = gmsh::model::occ::addBox(origin.x(), origin.y(), origin.z(), size.x(), size.y(), size.z());
  gmsh::model::occ::synchronize();
  gmsh::model::addPhysicalGroup(3, {v}, 1);
  gmsh::model::setPhysicalName(3, 1, "volume");
  gmsh::vectorpair faces;
  gmsh::model::getBoundary({{3, v}}, faces, false, false, false);
  const char* names[3][2] = {{"xmin", "xmax"}, {"ymin", "ymax"}, {"zmin", "zmax"}};
  int tag = 1;
  for (const auto& [dim, f] : faces) {
    double x0, y0, z0, x1, y1, z1;
    gmsh::model::getBoundingBox(2, std::abs(f), x0, y0, z0, x1, y1, z1);
    const Eigen::Vector3d lo(x0, y0, z0), hi(x1, y1, z1);
    const Eigen::Vector3d extent = hi - lo;
    int axis = 0;
    extent.minCoeff(&axis);  // the face is thin along its normal axis
    const double mid = 0.5 * (lo[axis] + hi[axis]) - origin[axis];
    const bool high = std::abs(mid - size[axis]) < std::abs(mid);
    gmsh::model::addPhysicalGroup(2, {std::abs(f)}, ++tag);
    gmsh::model::setPhysicalName(2, tag, names[axis][high ? 1 : 0]);
  }
  gmsh::option::setNumber("Mesh.MeshSizeMax", h);
  gmsh::option::setNumber("Mesh.MeshSizeMin", h);
  gmsh::model::mesh::generate(3);
  return collect("box mesh");
}

Mesh lineMesh(const Eigen::Vector3d& a, const Eigen::Vector3d& b, int n) {
  common::GmshSession session;
  gmsh::model::add("line");
  const int pa = gmsh::model::occ::addPoint(a.x(), a.y(), a.z());
  const int pb = gmsh::model::occ::addPoint(b.x(), b.y(), b.z());
  const int l = gmsh::model::occ::addLine(pa, pb);
  gmsh::model::occ::synchronize();
  gmsh::model::mesh::setTransfiniteCurve(l, n + 1);
  int nextTag = 0;
  auto group = [&](int dim, const std::vector<int>& tags, const std::string& name) {
    const int p = gmsh::model::addPhysicalGroup(dim, tags, ++nextTag);
    gmsh::model::setPhysicalName(dim, p, name);
  };
  group(1, {l}, "line");
  group(0, {pa}, "start");
  group(0, {pb}, "end");
  gmsh::model::mesh::generate(1);
  return collect("line mesh");
}

}  // namespace fem
