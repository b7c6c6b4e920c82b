// The mesh reader module (libcosim_mesh_reader.so): common::readTriangleMesh loads it with dlopen on a
// scene's first mesh, so that gmsh's libraries are mapped only by a run that reads one
// (common/gmsh_session.hpp). Errors come back as text: no exception crosses the module's edge.
#include <exception>
#include <string>

#include "common/gmsh_session.hpp"

extern "C" __attribute__((visibility("default"))) bool cosim_read_triangle_mesh(const char* file, const char* physical,
                                                                                common::TriangleMesh* mesh,
                                                                                std::string* error) {
  try {
    *mesh = common::gmshReadTriangleMesh(file, physical);
    return true;
  } catch (const std::exception& e) {
    *error = e.what();
  } catch (...) {
    *error = std::string("gmsh cannot read mesh file \"") + file + "\".";
  }
  return false;
}
