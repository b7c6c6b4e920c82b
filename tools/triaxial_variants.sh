#!/bin/sh
# The triaxial variants of docs/validation/triaxial.md, beside the scene's own runs at 100/200/300 kPa:
# the Mohr–Coulomb envelope without bonds, at contact friction 0.3 and with 1 MPa bonds (each at 100, 200
# and 300 kPa), dense against loose samples without bonds at 100 kPa, and the bonded rockfall block on
# the net (configs/rockfall/c_bonded.yaml). Two runs at a time, one thread each (4,000 spheres: about
# 30 min in all on 2 cores).
#
#   tools/triaxial_variants.sh BUILD_DIR OUT
#
# Prints, per variant, the peaks and the envelope (tools/triaxial_plot.py), the dense/loose table and the
# bonded block's broken bonds and pieces; writes OUT/<variant>/<kPa>/ and the plots in OUT/. EXTRA: --set
# values added to every triaxial run (EXTRA="specimen.count=300 triaxial.axial_strain_end=0.01" for a quick
# look; the figures of the docs are from the defaults).
set -euf  # -f: the [0] of the --set keys is not a glob
BUILD=$1
OUT=$2
PYTHON=${PYTHON:-/usr/bin/python3}
DEM="$BUILD/bin/dem_solver"
mkdir -p "$OUT"
export OMP_NUM_THREADS=1

run() {  # folder, then --set values
  folder=$1
  shift
  args=""
  for s in "$@" ${EXTRA:-}; do args="$args --set $s"; done
  # shellcheck disable=SC2086
  "$DEM" configs/dem/triaxial.yaml --quiet --out "$folder" $args
}

NO_BONDS="interactions[0].tensile_strength=0 interactions[0].cohesion=0"
for variant in no_bonds mu_0.3 bonds_1MPa; do
  case $variant in
    no_bonds) sets=$NO_BONDS ;;
    mu_0.3) sets="interactions[0].friction=0.3" ;;
    bonds_1MPa) sets="interactions[0].tensile_strength=1e6 interactions[0].cohesion=1e6" ;;
  esac
  # shellcheck disable=SC2086
  run "$OUT/$variant/100" $sets triaxial.confining_pressure=1e5 &
  # shellcheck disable=SC2086
  run "$OUT/$variant/200" $sets triaxial.confining_pressure=2e5
  wait
  # shellcheck disable=SC2086
  run "$OUT/$variant/300" $sets triaxial.confining_pressure=3e5
  echo "== $variant"
  for kPa in 100 200 300; do
    "$PYTHON" -c "import sys, yaml; r = yaml.safe_load(open(sys.argv[1]))['results']; print(f'{sys.argv[2]} kPa: q_peak {r[\"peak_deviatoric_stress\"] / 1e3:.1f} kPa')" \
      "$OUT/$variant/$kPa/summary.yaml" "$kPa"
  done
  "$PYTHON" tools/triaxial_plot.py "$OUT/$variant/100" "$OUT/$variant/200" "$OUT/$variant/300" \
    --out "$OUT/triaxial_$variant.png"
done

# Dense (the scene's frictionless growth) against loose (grown with friction to a higher porosity).
# shellcheck disable=SC2086
run "$OUT/loose" $NO_BONDS specimen.compaction_friction=0.5 specimen.porosity=0.42 &
# shellcheck disable=SC2086
run "$OUT/looser" $NO_BONDS specimen.compaction_friction=1.0 specimen.porosity=0.45
wait
echo "== dense against loose (100 kPa, no bonds)"
"$PYTHON" tools/triaxial_plot.py "$OUT/no_bonds/100" "$OUT/loose" "$OUT/looser" --labels dense,loose,looser \
  --out "$OUT/triaxial_dense_loose.png"
for s in no_bonds/100 loose looser; do
  "$PYTHON" - "$OUT/$s/summary.yaml" "$s" <<'PY'
import sys, yaml
r = yaml.safe_load(open(sys.argv[1]))["results"]
print(f"{sys.argv[2]}: porosity {r['porosity_consolidated']:.4f}, q_peak {r['peak_deviatoric_stress'] / 1e3:.1f} kPa "
      f"at {100 * r['axial_strain_at_peak']:.1f} %, most compaction {100 * r['max_compaction_volumetric_strain']:+.2f} %, "
      f"ε_v at the end {100 * r['final_volumetric_strain']:+.2f} %")
PY
done

echo "== the bonded block on the net (configs/rockfall/c_bonded.yaml)"
"$BUILD/bin/cosim" run configs/rockfall/c_bonded.yaml --out "$OUT/c_bonded" --quiet
grep -E "bonds_created|broken_bonds|bond_fracture_energy|fragments|largest_fragment" "$OUT/c_bonded/dem/summary.yaml"
