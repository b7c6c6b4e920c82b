#!/usr/bin/env bash
# The DEM pour benchmark of issue 3, side by side: dem_solver (cosim), LIGGGHTS and YADE on the same
# scene (tests/bench/peers/README in the scripts' headers), alternating A B C A B C … so that the
# shared machine's drift hits all codes alike; prints every RESULT line and the median per code.
# Usage: dem_pour_compare.sh BUILD_DIR   (env: SIZES="10000 50000", THREADS="1 2", STEPS=20000, REPS=3,
#                                          CODES="cosim liggghts yade")
# CODES may name cosim-ranks: dem_solver on THREADS MPI ranks of one thread each (LIGGGHTS' threads are
# ranks too). NX, NY, NZ in the environment set the lattice of every size in SIZES (pour_shape.sh): give
# one size whose count is their product.
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
build=${1:-build-bench}
sizes=${SIZES:-10000}; threads=${THREADS:-1 2}; steps=${STEPS:-2000}; reps=${REPS:-3}
codes=${CODES:-cosim liggghts yade}
results=$(mktemp)
initial=$(mktemp -d)
trap 'rm -rf "$results" "$initial"' EXIT
for n in $sizes; do
  # The peers start from our generator's sites (peers/initial_state.py), so all build the same packing.
  INITIAL_OUT="$initial/N$n" "$here/dem_pour.sh" "$build" "$n" 1
  for t in $threads; do
    for r in $(seq "$reps"); do
      for c in $codes; do
        if [ "$c" = cosim ]; then line=$("$here/dem_pour.sh" "$build" "$n" "$t" "$steps")
        elif [ "$c" = cosim-ranks ]; then
          [ "$t" -gt 1 ] || continue  # one rank is `cosim`
          line=$(RANKS=$t "$here/dem_pour.sh" "$build" "$n" 1 "$steps")
        elif command -v "$c" >/dev/null; then line=$(INITIAL="$initial/N$n" "$here/peers/run_peers.sh" "$c" "$n" "$t" "$steps")
        else echo "bench: $c not installed, skipped" >&2; continue; fi
        echo "$line" | tee -a "$results"
      done
    done
  done
done
echo "== medians (particle-steps/s)"
/usr/bin/python3 - "$results" <<'PY'
import statistics, sys
rates, rss, contacts = {}, {}, {}
for line in open(sys.argv[1]):
    f = dict(kv.split("=", 1) for kv in line.split()[2:])
    key = f"{line.split()[1]:9s} N={f['N']} threads={f['threads']}"
    rates.setdefault(key, []).append(float(f["particle_steps_per_s"]))
    contacts.setdefault(key, []).append(float(f["contacts_per_sphere"]))
    rss[key] = f["peak_rss_kb"]
for key in sorted(rates):
    print(f"{key}  median {statistics.median(rates[key]):.3g}  ({len(rates[key])} runs, peak RSS {rss[key]} kB, "
          f"contacts per sphere at the end {statistics.median(contacts[key]):.3g})")
PY
