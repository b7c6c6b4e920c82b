#!/usr/bin/env bash
# Runs one peer code on the "pour" benchmark and prints one line:
#   RESULT <code> N=<N> threads=<T> seconds=<loop s> particle_steps_per_s=<x> peak_rss_kb=<kb>
#          contacts_per_sphere=<sphere–sphere contacts per sphere at the end>
# Both codes start from dem_solver's generated sites (INITIAL, below): the same packing forms in all.
#
# Usage: run_peers.sh liggghts|yade N threads [steps]
#   N       10000 (25x20x20), 20000 (40x25x20), 50000 (50x40x25), 80 (5x4x4, smoke test); NX, NY, NZ in
#           the environment give any shape at any N (NX*NY*NZ must equal N). The step is ../pour_shape.sh's
#           (2.42e-4 s up to 25 layers, shorter for a taller fall; DT overrides it), dem_pour.sh's too.
#   threads 1 or 2. LIGGGHTS (Debian build is MPI-only, no OpenMP): threads = MPI ranks
#           (mpirun -np T, domain split in x/y only). YADE: OpenMP threads (yade -jT).
#   steps   default 20000 (or env STEPS).
# Env: LOGDIR (default /tmp/peers_logs) keeps the full log of each run.
#      INITIAL=PREFIX: the initial state, PREFIX.data and PREFIX.txt (../dem_pour.sh with INITIAL_OUT);
#      without it this script writes it to $LOGDIR/initial_N<N> with the dem_solver of BUILD
#      (default build-bench, relative to the repository).
#      SKIN (LIGGGHTS neighbour skin, default 0.002 m), VERLET (YADE verletDist, default YADE's).
#
# seconds = stepping loop only: LIGGGHTS' "Loop time of X on P procs" (setup excluded);
#           YADE: wall-clock of O.run(steps, True) (scene construction excluded).
# peak_rss_kb = /usr/bin/time -v "Maximum resident set size": for LIGGGHTS with 2 MPI ranks the sum
#           of the ranks' peaks (each rank runs under its own GNU time).
# Never run two of these at once on the 2-core machine.
set -euo pipefail

here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
code=${1:?usage: run_peers.sh liggghts|yade N threads [steps]}
N=${2:?N missing}
threads=${3:?threads missing}
steps=${4:-${STEPS:-20000}}

. "$here/../pour_shape.sh"  # nx, ny, nz, dt: the lattice and step of dem_pour.sh
if [ $((nx * ny * nz)) -ne "$N" ]; then
  echo "run_peers: nx*ny*nz = $((nx * ny * nz)) != N = $N" >&2; exit 2
fi
case "$threads" in 1|2) ;; *) echo "run_peers: threads must be 1 or 2" >&2; exit 2 ;; esac

timebin=/usr/bin/time
[ -x "$timebin" ] || { echo "run_peers: $timebin missing (apt-get install time)" >&2; exit 2; }

logdir=${LOGDIR:-/tmp/peers_logs}
mkdir -p "$logdir"
tag="${code}_N${N}_t${threads}_s${steps}"
initial=${INITIAL:-}
if [ -z "$initial" ]; then
  initial="$logdir/initial_N$N"
  (cd "$here/../../.." && INITIAL_OUT="$initial" "$here/../dem_pour.sh" "${BUILD:-build-bench}" "$N" 1)
fi
[ -f "$initial.data" ] && [ -f "$initial.txt" ] || { echo "run_peers: no $initial.data / .txt" >&2; exit 2; }
initial=$(cd "$(dirname "$initial")" && pwd)/$(basename "$initial")  # absolute: the codes run elsewhere
log="$logdir/$tag.log"
tlog="$logdir/$tag.time"
work=$(mktemp -d)               # both codes may drop files in the cwd; keep the repo clean
trap 'rm -rf "$work"' EXIT
cd "$work"

case "$code" in
  liggghts)
    cmd=(liggghts -in "$here/pour.liggghts" -var nx "$nx" -var ny "$ny" -var nz "$nz"
         -var steps "$steps" -var dt "$dt" -var skin "${SKIN:-0.002}" -var data "$initial.data" -log none -nocite)
    if [ "$threads" -gt 1 ]; then
      # Each rank under its own GNU time: the run's memory is the sum of the ranks' peaks.
      mpi=(mpirun -np "$threads")
      [ "$(id -u)" -eq 0 ] && mpi+=(--allow-run-as-root)
      rm -f "$tlog".rank*
      cmd=("${mpi[@]}" bash -c 'exec "$0" -v -o "$1.rank$OMPI_COMM_WORLD_RANK" "${@:2}"' "$timebin" "$tlog" "${cmd[@]}")
    fi
    OMP_NUM_THREADS=1 "$timebin" -v -o "$tlog" "${cmd[@]}" >"$log" 2>&1 || {
      echo "run_peers: liggghts failed, see $log" >&2; tail -20 "$log" >&2; exit 1; }
    if [ "$threads" -gt 1 ]; then
      awk -F': ' '/Maximum resident set size/ {s += $2} END {print "\tMaximum resident set size (kbytes): " s}' \
        "$tlog".rank* > "$tlog"
    fi
    loopline=$(grep -E "^Loop time of .* for $steps steps" "$log" | tail -1)
    [ -n "$loopline" ] || { echo "run_peers: no 'Loop time' line for $steps steps in $log" >&2; exit 1; }
    seconds=$(awk '{print $4}' <<<"$loopline")
    procs=$(awk '{print $6}' <<<"$loopline")
    atoms=$(sed -E 's/.* with ([0-9]+) atoms.*/\1/' <<<"$loopline")
    if [ "$atoms" -ne "$N" ] || [ "$procs" -ne "$threads" ]; then
      echo "run_peers: loop ran with $atoms atoms on $procs procs (expected $N on $threads)" >&2; exit 1
    fi
    # The thermo line of the last step: step atoms ke rke zmin zmax contacts-per-sphere
    cps=$(awk -v s="$steps" '$1 == s && NF == 7 {c = $7} END {print c}' "$log")
    ;;
  yade)
    cmd=(yade -n -x -j"$threads" "$here/pour_yade.py")
    nx=$nx ny=$ny nz=$nz steps=$steps dt=$dt INITIAL="$initial.txt" OMP_NUM_THREADS=$threads \
      "$timebin" -v -o "$tlog" "${cmd[@]}" >"$log" 2>&1 || {
      echo "run_peers: yade failed, see $log" >&2; tail -20 "$log" >&2; exit 1; }
    res=$(grep -E "^RESULT yade N=$N steps=$steps " "$log" | tail -1)
    [ -n "$res" ] || { echo "run_peers: no RESULT line in $log" >&2; exit 1; }
    seconds=$(sed -E 's/.* seconds=([^ ]+).*/\1/' <<<"$res")
    cps=$(sed -E 's/.* contacts_per_sphere=([^ ]+).*/\1/' <<<"$res")
    ;;
  *) echo "run_peers: unknown code '$code' (liggghts|yade)" >&2; exit 2 ;;
esac

rss=$(awk -F': ' '/Maximum resident set size/ {print $2}' "$tlog")
pps=$(awk -v n="$N" -v s="$steps" -v t="$seconds" 'BEGIN {printf "%.6g", n * s / t}')
echo "RESULT $code N=$N threads=$threads steps=$steps seconds=$seconds particle_steps_per_s=$pps peak_rss_kb=$rss contacts_per_sphere=$cps"
