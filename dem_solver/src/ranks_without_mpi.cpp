// dem/ranked_run.hpp in a build without MPI: one rank; a launch on several is refused, not run P times.
#include <cstdlib>
#include <string>

#include "common/errors.hpp"
#include "dem/ranked_run.hpp"

namespace dem {

bool Ranks::available() { return false; }

Ranks startRanks(int*, char***) {
  Ranks r;
  for (const char* size : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE"})
    if (const char* v = std::getenv(size)) r.size = std::max(1, std::atoi(v));
  for (const char* rank : {"OMPI_COMM_WORLD_RANK", "PMI_RANK"})
    if (const char* v = std::getenv(rank)) r.rank = std::atoi(v);
  return r;
}

void stopRanks(int) {}

namespace {
[[noreturn]] void refuse(const Ranks& ranks) {
  throw common::ConfigError("started on " + std::to_string(ranks.size) +
                            " ranks, but this dem_solver was built without MPI: install libopenmpi-dev (make deps) "
                            "and build again, or run it without mpirun");
}
}  // namespace

void runSceneOnRanks(Scene&, const Ranks& ranks, const std::filesystem::path&, common::Summary&, bool, int,
                     const std::filesystem::path&) {
  refuse(ranks);
}

void runParticipantOnRanks(Scene&, const Ranks& ranks, const std::string&, const std::string&,
                           const std::filesystem::path&, common::Summary&, int) {
  refuse(ranks);
}

}  // namespace dem
