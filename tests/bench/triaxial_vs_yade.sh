#!/usr/bin/env bash
# The triaxial test against YADE: the same sample (dem_solver's consolidated spheres and its bonds), laws
# and loading (tests/bench/peers/triaxial_yade.py), both with rigid platens of the same contact stiffness
# 2 E r (ours through the platen pair's modulus at E/2: our rigid planes otherwise take 4 E r, YADE's rigid
# boxes 2 E r), to the same engineering strain; the axial compression timed in each, one thread each,
# runs interleaved ours, YADE, ours, YADE, … and the medians compared. Prints one line per run and
#   TRIAXIAL N=<N> strain=<ε_end> ours_median_s=<s> yade_median_s=<s> speedup=<x> peak_ratio=<ours/yade>
# and draws both codes' curves on one figure (OUT/triaxial_vs_yade.png).
#
# Usage: triaxial_vs_yade.sh BUILD [N] [STRAIN_END] [RUNS]   (defaults: build-bench 800 0.06 3)
# Env: OUT (default /tmp/triaxial_vs_yade), SIGMA3 (default 1e5), E (the grains' modulus of
# configs/dem/triaxial.yaml, 1e8). Never run two benchmarks at once.
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
root=$(cd "$here/../.." && pwd)
build=$(cd "${1:-build-bench}" && pwd)
n=${2:-800}
strain=${3:-0.06}
runs=${4:-3}
out=${OUT:-/tmp/triaxial_vs_yade}
sigma3=${SIGMA3:-1e5}
command -v yade > /dev/null || { echo "triaxial_vs_yade: yade missing (make bench-deps installs it)" >&2; exit 2; }
mkdir -p "$out"
young=${E:-1e8}
platen=$(/usr/bin/python3 -c "import sys; print(float(sys.argv[1]) / 2)" "$young")
sets=(--set "specimen.count=$n" --set "triaxial.axial_strain_end=$strain" --set "triaxial.confining_pressure=$sigma3"
      --set "materials.sand.young_modulus=$young" --set "interactions[1].young_modulus=$platen")
ours=() yade_s=()
for i in $(seq 1 "$runs"); do
  OMP_NUM_THREADS=1 "$build/bin/dem_solver" "$root/configs/dem/triaxial.yaml" --quiet --out "$out/ours_$i" "${sets[@]}"
  s=$(/usr/bin/python3 -c "import yaml,sys; print(yaml.safe_load(open(sys.argv[1]))['results']['compression_wall_time_s'])" "$out/ours_$i/summary.yaml")
  echo "ours run $i: compression $s s"
  ours+=("$s")
  dt=$(/usr/bin/python3 -c "import yaml,sys; print(yaml.safe_load(open(sys.argv[1]))['results']['dt'])" "$out/ours_1/summary.yaml")
  log=$(cd "$out" && H5="$out/ours_1/dem.h5" SIGMA3="$sigma3" STRAIN_END="$strain" DT="$dt" OUT="$out/yade.csv" \
        yade -n -x -j1 "$here/peers/triaxial_yade.py" 2>&1)
  grep '^BONDS' <<< "$log"
  line=$(grep '^RESULT' <<< "$log")
  echo "yade run $i: $line"
  yade_s+=("$(sed -E 's/.*seconds=([0-9.]+).*/\1/' <<< "$line")")
done
/usr/bin/python3 - "$out" "$n" "$strain" "${ours[*]}" "${yade_s[*]}" <<'EOF'
import statistics, sys, yaml
import numpy as np
out, n, strain, ours, yade = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4].split(), sys.argv[5].split()
a, b = statistics.median(map(float, ours)), statistics.median(map(float, yade))
peak = yaml.safe_load(open(f"{out}/ours_1/summary.yaml"))["results"]["peak_deviatoric_stress"]
peer = np.genfromtxt(f"{out}/yade.csv", delimiter=",", names=True)["deviatoric_stress"].max()
print(f"TRIAXIAL N={n} strain={strain} ours_median_s={a:.3f} yade_median_s={b:.3f} speedup={b / a:.2f} "
      f"peak_ratio={peak / peer:.3f}")
EOF
/usr/bin/python3 "$root/tools/triaxial_plot.py" "$out/ours_1" --peer "$out/yade.csv:YADE 2023.02a" --out "$out/triaxial_vs_yade.png"
