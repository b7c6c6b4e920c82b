#pragma once
#include <filesystem>
#include <string>

#include "lattice/scene.hpp"

namespace lattice {
/// Runs `scene` as participant `name` of the coupled run at `endpoint` (lattice_solver --couple): the
/// faces of its `interface` key are coupled (README "Participant mode").
void runParticipant(Scene& scene, const std::string& endpoint, const std::string& name,
                    const std::filesystem::path& outDir, common::Summary& summary);
}  // namespace lattice
