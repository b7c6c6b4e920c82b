#!/usr/bin/env bash
# `make bench`: the scene benchmarks (docs/performance.md records their figures with the command, the
# machine and the date). Not part of `make test`. Env variables of each script select sizes and steps.
set -euo pipefail
build=${1:-build-bench}
echo "bench: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $(date -u +%F)"
echo "== DEM pour (issue 3): dem_solver vs LIGGGHTS vs YADE"
tests/bench/dem_pour_compare.sh "$build"
echo "== DEM triaxial (issue 27): dem_solver vs YADE, same sample and loading, compression timed"
tests/bench/triaxial_vs_yade.sh "$build"
echo "== FEM (issue 4): explicit membrane throughput, static net solve"
tests/bench/fem_bench.sh "$build"
echo "== Coupling (issue 5): one exchange of a 1,000-node field against raw ZeroMQ request-reply"
"$build/bin/exchange_bench" --nodes 1000 --exchanges 2000 --rounds 7
echo "== Lattice (issue 7): K x on the 1M-rod cube, the 5 cm cube's full curve"
tests/bench/lattice_bench.sh "$build"
