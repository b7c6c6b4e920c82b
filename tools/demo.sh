#!/usr/bin/env bash
# `make demo`: runs the most complete scene that exists and plots its time series.
# Order of preference: the coupled rockfall scene (DEMO_SCENE=configs/rockfall/c5.yaml for another level),
# then the standalone solver scenes.
set -euo pipefail
build=${1:-build}
bin="$build/bin"
py=/usr/bin/python3; [ -x "$py" ] || py=python3

run() {  # run EXECUTABLE SCENE [args…]
  local exe=$1 scene=$2; shift 2
  local name; name=$(basename "$scene" .yaml)
  echo "demo: $exe $scene --out results/$name $*"
  "$bin/$exe" "$scene" --out "results/$name" "$@"
  "$py" tools/plot_timeseries.py "results/$name"
  echo "demo: results in results/$name (summary.yaml, *.h5 + *.xdmf for ParaView, plots/*.png)"
  sed -n '/^results:/,$p' "results/$name/summary.yaml"
}

if [ -x "$bin/cosim" ] && [ -f configs/rockfall/c2.yaml ]; then
  scene=${DEMO_SCENE:-configs/rockfall/c2.yaml}
  name=$(basename "$scene" .yaml)
  echo "demo: $bin/cosim run $scene --out results/$name"
  "$bin/cosim" run "$scene" --out "results/$name"
  "$py" tools/rockfall_report.py "results/$name"
  "$py" tools/plot_timeseries.py "results/$name/dem" --out "results/$name/plots" > /dev/null
  "$py" tools/plot_timeseries.py "results/$name/fem" --out "results/$name/plots" > /dev/null
  "$py" tools/render_rockfall.py "results/$name"
  echo "demo: results in results/$name: summary.yaml, plots/rockfall.png, the impact at its largest deflection plots/rockfall_max_deflection.png and animated plots/rockfall_impact.gif, coupling.h5, and for ParaView fem/fem.xdmf (the net every 5 ms: displacement, velocity, PK2 stress, the block's force on its nodes) and dem/dem.xdmf (the block's spheres every 5 ms: Point Gaussian or Glyph scaled by radius)"
elif [ -x "$bin/dem_solver" ] && [ -f configs/dem/hertz_bounce.yaml ]; then
  run dem_solver configs/dem/hertz_bounce.yaml
else
  echo "demo: no solver scene exists yet (see the status table in README.md)" >&2
  exit 1
fi
