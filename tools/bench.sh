#!/usr/bin/env bash
# `make bench`: runs every benchmark executable (bench_*) of the benchmark build. Figures go to
# docs/performance.md with the command, the machine and the date.
set -euo pipefail
build=${1:-build-bench}
shopt -s nullglob
benches=("$build"/bin/bench_*)
if [ ${#benches[@]} -eq 0 ]; then
  echo "bench: no benchmarks built yet"
  exit 0
fi
echo "bench: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $(date -u +%F)"
for b in "${benches[@]}"; do
  echo "== $(basename "$b")"
  "$b"
done
