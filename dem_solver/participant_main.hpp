#pragma once
#include <string>

#include "dem/scene.hpp"

namespace dem {
/// Runs `scene` as participant `name` of the coupled run at `endpoint` (dem_solver --couple).
void runParticipant(Scene& scene, const std::string& endpoint, const std::string& name,
                    const std::filesystem::path& outDir, common::Summary& summary,
                    const std::filesystem::path& restart = {});
}  // namespace dem
