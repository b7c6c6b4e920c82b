#!/usr/bin/env bash
# FEM benchmark (issue 4): explicit membrane steps per second at ~10,000 and ~100,000 triangles, 1 and
# 2 threads; static dead-load solve time of the rockfall net at three mesh sizes. REPS runs each,
# alternating thread counts, medians printed.   Usage: fem_bench.sh BUILD_DIR   (env: REPS=3, STEPS=200)
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd); root=$(cd "$here/../.." && pwd)
build=${1:-build-bench}; reps=${REPS:-3}; steps=${STEPS:-200}
exe="$root/$build/bin/fem_solver"
out=$(mktemp -d); trap 'rm -rf "$out"' EXIT
results="$out/results"
value() { sed -n "s/^ *$1: //p" "$out/run/summary.yaml"; }
for r in $(seq "$reps"); do
  for cells in 71 224; do   # 2 n² triangles: 10,082 and 100,352
    for t in 1 2; do
      h=$(awk "BEGIN { printf \"%.10g\", 3.9 / $cells }")
      "$exe" "$root/configs/fem/membrane_vibration.yaml" --quiet --out "$out/run" --threads "$t" \
        --set "mesh.rectangle.element_size=$h" --set "explicit.end_time=null" --set "explicit.steps=$steps" \
        --set "output={interval: 0, series_interval: 1.0}"
      echo "explicit triangles=$((2 * cells * cells)) threads=$t steps_per_s=$(value steps_per_s)" | tee -a "$results"
    done
  done
  for cells in 16 32 64; do
    h=$(awk "BEGIN { printf \"%.10g\", 3.9 / $cells }")
    "$exe" "$root/configs/fem/net_deadload.yaml" --quiet --out "$out/run" --threads 2 --set "mesh.rectangle.element_size=$h"
    echo "static_net cells=${cells}x$cells seconds=$(value static_time_s) iterations=$(value static_iterations)" | tee -a "$results"
  done
done
echo "== medians"
/usr/bin/python3 - "$results" <<'PY'
import statistics, sys
groups = {}
for line in open(sys.argv[1]):
    parts = line.split()
    key = " ".join(p for p in parts if not p.startswith(("steps_per_s", "seconds", "iterations")))
    val = [p for p in parts if p.startswith(("steps_per_s", "seconds"))][0]
    name, v = val.split("=")
    groups.setdefault((key, name), []).append(float(v))
for (key, name), vals in sorted(groups.items()):
    print(f"{key:40s} {name} median {statistics.median(vals):.4g} ({len(vals)} runs)")
PY
