#!/usr/bin/env bash
# dem_solver's thread scaling on the pour of dem_pour.sh (N spheres on a jittered cubic lattice falling
# into a box of planes, Hertz–Mindlin with history, no output), one run per thread count in the order
# given, then a table: loop time, particle-steps/s, speed-up and efficiency against the first count, peak
# resident memory and the heap by structure per sphere (summary `cost: memory_*`). From the first two
# counts' phase timers (summary `cost: phase_seconds`), Amdahl's serial fraction of a step, f = (p/S − 1)/(p − 1)
# for speed-up S on p times the threads, in all and per phase. The phases sum to the loop: the last,
# rest_of_loop, is what the step's timers leave out (the stability monitor's samples, output).
# Usage: dem_scaling.sh BUILD_DIR "1 2 4 8 16" N [steps]   (e.g. N = 100000 at 3000 steps, 1000000 at 300)
# REPS=R runs the counts in turn R times (1 2 4 1 2 4 …) and reports each count's run of median loop time: on a
# shared machine one run per count can put the serial fraction anywhere. It also gives the fraction from each
# count's fastest loop, the run least slowed by the machine's other work.
# The lattice is n × n × 20 sites, n = ⌈√(N / 20)⌉, filled to N: a bed as high as dem_pour.sh's 10⁴ and
# 2·10⁴ ones, so that its fixed dt (the peers') stays below the safe step at any N.
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
build=${1:?usage: dem_scaling.sh BUILD_DIR \"1 2 4\" N [steps]}
threads=${2:?thread counts}
N=${3:?N}
steps=${4:-1000}
m=20
n=$(awk -v N="$N" -v m=$m 'BEGIN { n = int(sqrt(N / m)); while (n * n * m < N) n++; print n }')
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
reps=${REPS:-1}
for r in $(seq "$reps"); do
  for t in $threads; do
    NX=$n NY=$n NZ=$m KEEP_SUMMARY="$work/summary_${t}_$r.yaml" "$here/dem_pour.sh" "$build" "$N" "$t" "$steps" |
      tee -a "$work/results"
  done
done
/usr/bin/python3 - "$work" "$reps" $threads <<'PY'
import statistics, sys, yaml
work, reps, counts = sys.argv[1], int(sys.argv[2]), [int(t) for t in sys.argv[3:]]
runs = {}
for line in open(f"{work}/results"):
    f = dict(kv.split("=", 1) for kv in line.split()[2:])
    runs.setdefault(int(f["threads"]), []).append(f)
# Per thread count, the run of median loop time stands for it (its phases, memory and summary).
rows, summ = {}, {}
for t in counts:
    order = sorted(range(reps), key=lambda r: float(runs[t][r]["seconds"]))
    r = order[(reps - 1) // 2]
    rows[t] = runs[t][r]
    summ[t] = yaml.safe_load(open(f"{work}/summary_{t}_{r + 1}.yaml"))
    if reps > 1:
        secs = [float(x["seconds"]) for x in runs[t]]
        print(f"threads {t}: loop {min(secs):.2f} / {statistics.median(secs):.2f} / {max(secs):.2f} s (min / median / max of {reps})")
t0 = counts[0]
print(f"\n{'threads':>7} {'loop s':>8} {'particle-steps/s':>17} {'speed-up':>8} {'efficiency':>10} {'peak RSS MB':>11} {'heap B/sphere':>13}")
for t in counts:
    r, c = rows[t], summ[t]["cost"]
    s = float(r["seconds"])
    speedup = float(rows[t0]["seconds"]) / s
    print(f"{t:>7} {s:>8.2f} {float(r['particle_steps_per_s']):>17.4g} {speedup:>8.2f} {speedup * t0 / t:>10.0%} "
          f"{int(r['peak_rss_kb']) / 1024:>11.1f} {c['memory_bytes_per_sphere']:>13.0f}")
c0 = summ[t0]["cost"]
print("\nheap by structure, bytes per sphere (" + str(t0) + " thread" + ("s" if t0 > 1 else "") + "):")
candidates = summ[t0]["results"]["sphere_pair_candidates_final"]
for name, mb in zip(c0["memory_names"].split(", "), c0["memory_mb"]):
    per = f"   ({mb * 2**20 / candidates:.0f} per candidate, {candidates / int(rows[t0]['N']):.2f} candidates per sphere)" \
        if name == "sphere_contacts" and candidates else ""
    print(f"  {name:16s} {mb * 2**20 / int(rows[t0]['N']):8.0f}{per}")
if len(counts) > 1:
    t1 = counts[1]
    p = t1 / t0
    def serial(a, b):  # Amdahl: b = a (f + (1 - f) / p)
        return (p * b / a - 1) / (p - 1) if a > 0 else float("nan")
    names = summ[t0]["cost"]["phase_names"].split(", ")
    ph0, ph1 = summ[t0]["cost"]["phase_seconds"], summ[t1]["cost"]["phase_seconds"]
    total0, total1 = sum(ph0), sum(ph1)
    print(f"\nserial fraction of a step from {t0} and {t1} threads (Amdahl): {serial(total0, total1):.1%}")
    if reps > 1:  # the fastest repetitions: the least disturbed by the rest of a shared machine
        fast0, fast1 = (min(float(x["seconds"]) for x in runs[t]) for t in (t0, t1))
        print(f"  from the fastest of the {reps} loops per count: {serial(fast0, fast1):.1%}")
    print(f"{'phase':>16} {'share of step':>13} {'s at ' + str(t0):>9} {'s at ' + str(t1):>9} {'serial part':>11}")
    for name, a, b in zip(names, ph0, ph1):
        print(f"{name:>16} {a / total0:>13.1%} {a:>9.3f} {b:>9.3f} {serial(a, b):>11.1%}")
PY
