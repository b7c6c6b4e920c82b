#include "common/results_file.hpp"

namespace common {

ResultsFile openResults(const std::filesystem::path& h5Path, const std::filesystem::path& restart,
                        const std::string& kind, const std::string& shape, const std::filesystem::path& stale) {
  ResultsFile r;
  if (restart.empty()) {
    if (!stale.empty()) {
      std::error_code ec;
      std::filesystem::remove(stale, ec);
    }
    r.h5 = std::make_unique<H5Writer>(h5Path);
    return r;
  }
  StateArchive::verify(restart);
  r.restart = StateArchive::open(restart, kind);
  if (!shape.empty()) r.restart->shape(shape);
  H5Extent extent;
  r.restart->io(kResultsExtent, extent);
  r.h5 = std::make_unique<H5Writer>(h5Path, extent);
  return r;
}

void archiveExtent(StateArchive& a, H5Writer& h5) {
  H5Extent extent = h5.checkpoint();
  a.io(kResultsExtent, extent);
}

}  // namespace common
