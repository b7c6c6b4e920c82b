#pragma once
// Factories of the mappings, one per source file; registered by name in mapping.cpp.
#include <memory>

#include "cosim/mapping.hpp"

namespace cosim {
std::unique_ptr<Mapping> makeIdentity(const InterfaceMesh& from, const InterfaceMesh& to);
std::unique_ptr<Mapping> makeNearestNeighbor(const InterfaceMesh& from, const InterfaceMesh& to);
std::unique_ptr<Mapping> makeNearestProjection(const InterfaceMesh& from, const InterfaceMesh& to);
std::unique_ptr<Mapping> makeBarycentric(const InterfaceMesh& from, const InterfaceMesh& to);
}  // namespace cosim
