#pragma once
// The initial static state of an explicit run, solved once per structure and load and reused by every
// later run of the same model (a scene pays only for what it uses: the rockfall net's dead-load solve is
// the same for every cluster level and every study rung).
//
// Key: a fingerprint of the finalized model — node coordinates, each block's kind and connectivity, its
// internal forces and strain energy at a fixed probe displacement (which carry every material and
// section parameter, the prestress included), the lumped masses, the dead load, the supports and their
// prescribed values — and of the static settings and the executable (its size and time: a rebuilt
// solver solves again). Files: COSIM_CACHE_DIR, else $XDG_CACHE_HOME/cosim,
// else ~/.cache/cosim; `static/<key>.bin`, written through a temporary file and a rename. A file that does
// not read back whole (size, header, checksum) is ignored and replaced.

#include <cstdint>

#include "fem/model.hpp"

namespace fem {

struct CachedStatic {
  StaticReport report;  ///< of the solve; zero iterations when reused
  bool reused = false;
};

/// Sets the model's displacement to its static state under `settings`, from the cache or by
/// Model::solveStatic (then stored). Throws what solveStatic throws.
CachedStatic solveStaticCached(Model& model, const StaticSettings& settings);

/// The fingerprint used as the key (exposed for tests).
std::uint64_t staticFingerprint(const Model& model, const StaticSettings& settings);

}  // namespace fem
