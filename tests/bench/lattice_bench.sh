#!/usr/bin/env bash
# Lattice benchmark (issue 7): the stiffness product K x on the 1,000,000-rod cube (1 and 2 threads,
# product_bench's median of ROUNDS rounds) and the 5 cm cube's full stress–strain curve (2 threads:
# solves, cg iterations, solve time, peak memory). REPS runs each.   Usage: lattice_bench.sh BUILD_DIR
# (env: REPS=2, ROUNDS=5). The full 1M-rod curve (≈ 15 min) is in docs/performance.md, not here.
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd); root=$(cd "$here/../.." && pwd)
build=${1:-build-bench}; reps=${REPS:-2}; rounds=${ROUNDS:-5}
out=$(mktemp -d); trap 'rm -rf "$out"' EXIT
value() { sed -n "s/^ *$1: //p" "$out/run/summary.yaml"; }
for r in $(seq "$reps"); do
  for t in 1 2; do
    echo -n "1M rods, K x, threads=$t: "
    "$root/$build/bin/product_bench" "$root/configs/lattice/tension_10cm.yaml" --set specimen.rod_length=0.00253 \
      --products 50 --rounds "$rounds" --threads "$t" 2>/dev/null | tail -1
  done
  /usr/bin/time -f "%M" -o "$out/time" "$root/$build/bin/lattice_solver" "$root/configs/lattice/tension_5cm.yaml" \
    --threads 2 --quiet --out "$out/run"
  echo "5 cm curve, threads=2: solves=$(value solves) iterations=$(value solver_iterations)" \
    "solve_s=$(value solve_time_s) peak_stress=$(value peak_stress) peak_kB=$(cat "$out/time")"
done
