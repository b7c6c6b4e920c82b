#pragma once
#include <string>

#include "fem/scene.hpp"

namespace fem {
/// Runs `scene` as participant `name` of the coupled run at `endpoint` (fem_solver --couple).
void runParticipant(Scene& scene, const std::string& endpoint, const std::string& name,
                    const std::filesystem::path& outDir, common::Summary& summary,
                    const std::filesystem::path& restart = {});
}  // namespace fem
