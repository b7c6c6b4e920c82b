#pragma once
#include <filesystem>
#include <string>

#include "lattice/scene.hpp"

namespace lattice {
/// Runs `scene` as participant `name` of the coupled run at `endpoint` (lattice_solver --couple): the
/// faces of its `interface` key are coupled (README "Participant mode"); with `restart`, from that
/// checkpoint (cosim run … --restart).
void runParticipant(Scene& scene, const std::string& endpoint, const std::string& name,
                    const std::filesystem::path& outDir, common::Summary& summary, const std::filesystem::path& restart);
}  // namespace lattice
