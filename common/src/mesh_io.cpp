#include "common/mesh_io.hpp"

#include <dlfcn.h>

#include <algorithm>
#include <cstdint>
#include <fstream>
#include <mutex>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "common/errors.hpp"
#include "common/memory.hpp"

namespace common {

namespace {

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

namespace {

// The mesh reader module's entry (common/src/mesh_reader_module.cpp): false with `error` set when gmsh
// cannot read the file.
using ReadEntry = bool (*)(const char* file, const char* physical, TriangleMesh* mesh, std::string* error);

// Loads the module on the first call: beside the executable (build tree: bin/../lib; installed:
// bin/../LIBDIR), else where this build put it.
ReadEntry meshReader() {
  static std::mutex mutex;
  static ReadEntry entry = nullptr;
  const std::lock_guard lock(mutex);
  if (entry) return entry;
  std::error_code ec;
  const auto exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  std::vector<std::filesystem::path> candidates;
  auto consider = [&](const std::filesystem::path& path) {
    if (std::find(candidates.begin(), candidates.end(), path) == candidates.end()) candidates.push_back(path);
  };
  if (!ec)
    for (const char* dir : {"../lib", "../" COSIM_INSTALL_LIBDIR})
      consider((exe.parent_path() / dir / COSIM_MESH_READER_FILE).lexically_normal());
  consider(COSIM_MESH_READER_BUILT);
  std::string tried;
  for (const auto& path : candidates) {
    if (void* module = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL)) {
      if (auto* f = reinterpret_cast<ReadEntry>(dlsym(module, "cosim_read_triangle_mesh"))) return entry = f;
      tried += fmt::format("\n  {}: no entry cosim_read_triangle_mesh", path.string());
    } else {
      tried += fmt::format("\n  {}", dlerror());
    }
  }
  throw SimulationError(fmt::format(
      "reading a mesh needs the module {} (built with the solvers, installed beside them); it could not be "
      "loaded:{}",
      COSIM_MESH_READER_FILE, tried));
}

}  // namespace

TriangleMesh readTriangleMesh(const std::filesystem::path& file, const std::string& physical) {
  if (!std::filesystem::exists(file))
    throw SimulationError(fmt::format("mesh file \"{}\" does not exist.", file.string()));
  TriangleMesh mesh;
  std::string error;
  if (!meshReader()(file.c_str(), physical.c_str(), &mesh, &error)) throw SimulationError(error);
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
