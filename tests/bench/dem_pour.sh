#!/usr/bin/env bash
# Runs dem_solver on the pour benchmark (the geometry of tests/bench/peers/: N monodisperse spheres,
# R = 0.01 m, on a cubic lattice of spacing 0.021 m with each site jittered by up to ±0.025 R,
# Hertz–Mindlin e = 0.5 μ = 0.5, dt = 2.42e-4 s up to 25 layers, no output) and prints one line like the peers:
#   RESULT cosim N=<N> threads=<T> steps=<S> seconds=<loop s> particle_steps_per_s=<x> peak_rss_kb=<kb>
#          contacts_per_sphere=<sphere–sphere contacts per sphere at the end, walls not counted>
# Usage: dem_pour.sh BUILD_DIR N threads [steps]
# The lattice is NX × NY × NZ sites if those are set (any shape, at least N sites), else the known sizes'
# shape; above 25 layers the step shrinks with the height, the same for the peers (pour_shape.sh), or is DT.
# With RANKS=P it runs on P MPI ranks of `threads` threads each (mpirun) and prints `cosim-ranks` with
# threads=P×threads (the cores it uses), its peak_rss_kb the ranks' peaks summed (as peers/run_peers.sh
# sums LIGGGHTS' ranks).
# With KEEP_SUMMARY=FILE the run's summary.yaml is copied there (phase timers, memory by structure).
# With INITIAL_OUT=PREFIX in the environment it writes the initial state for the peers instead
# (PREFIX.data for LIGGGHTS, PREFIX.txt for YADE; peers/initial_state.py) and prints nothing.
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
root=$(cd "$here/../.." && pwd)
build=${1:?build dir}; N=${2:?N}; threads=${3:?threads}; steps=${4:-${STEPS:-20000}}
. "$here/pour_shape.sh"  # nx, ny, nz, dt
# The peers' step, which resolves the fastest contact with about 9 steps, not the 20 dem_solver asks for by
# default (steps_per_contact). Its safety check is told to warn, not refuse: the peers take the step as
# given (the run still stops with exit 3 if it goes wrong); the warning is repeated on stderr.
s=0.021
calc() { awk "BEGIN { printf \"%.10g\", $1 }"; }
lx=$(calc "$nx * $s"); ly=$(calc "$ny * $s")
gx=$(calc "($nx + 0.5) * $s"); gy=$(calc "($ny + 0.5) * $s"); gz=$(calc "($nz + 0.5) * $s")  # generation box
end=$(awk "BEGIN { printf \"%.17g\", $steps * $dt }")  # whole steps of any DT
output="{interval: 0, series_interval: $end}"
[ -n "${INITIAL_OUT:-}" ] && { end=$dt; output="{interval: 1, series_interval: 1}"; }  # a step-0 snapshot
out=$(mktemp -d); trap 'rm -rf "$out"' EXIT
ranks=${RANKS:-1}; launch=(); code=cosim
if [ "$ranks" -gt 1 ]; then
  launch=(mpirun -np "$ranks"); code=cosim-ranks
  export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_btl_vader_single_copy_mechanism=none
fi
/usr/bin/time -v -o "$out/time" "${launch[@]}" "$root/$build/bin/dem_solver" "$root/configs/dem/pour.yaml" --quiet --out "$out" \
  --threads "$threads" \
  --set "generate[0]={material: glass, count: $N, radius: [0.01, 0.01], box: {min: [0, 0, 0], max: [$gx, $gy, $gz]}, seed: 1}" \
  --set "walls[2].point=[$lx, 0, 0]" --set "walls[4].point=[0, $ly, 0]" \
  --set "dt=$dt" --set "dt_fraction=null" --set "end_time=$end" --set "output=$output" \
  --set "steps_per_contact=9" --set "dt_check=warn" \
  --set "probe=null" > "$out/log" 2>&1 || { cat "$out/log" >&2; exit 1; }
grep -h 'above the safe step' "$out/log" >&2 || true
if [ -n "${INITIAL_OUT:-}" ]; then
  /usr/bin/python3 "$here/peers/initial_state.py" "$out/dem.h5" "$nx" "$ny" "$nz" "$INITIAL_OUT"
  exit 0
fi
seconds=$(sed -n 's/^ *loop_wall_time_s: //p' "$out/summary.yaml")
rate=$(sed -n 's/^ *particle_steps_per_s: //p' "$out/summary.yaml")
rss=$(sed -n 's/.*Maximum resident set size (kbytes): //p' "$out/time")
[ "$ranks" -gt 1 ] && rss=$(awk '/peak_memory_all_ranks_mb/ {printf "%d", $2 * 1024}' "$out/summary.yaml")
pairs=$(sed -n 's/^ *sphere_contacts_final: //p' "$out/summary.yaml")
cps=$(awk -v p="$pairs" -v n="$N" 'BEGIN {printf "%.4g", 2 * p / n}')
[ -n "${KEEP_SUMMARY:-}" ] && cp "$out/summary.yaml" "$KEEP_SUMMARY"
echo "RESULT $code N=$N threads=$((ranks * threads)) steps=$steps seconds=$seconds particle_steps_per_s=$rate peak_rss_kb=$rss contacts_per_sphere=$cps"
