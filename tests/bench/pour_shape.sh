# The pour benchmark's lattice and step, for dem_pour.sh and peers/run_peers.sh alike (sourced; needs N).
# Sets nx, ny, nz: NX × NY × NZ sites if those are set (any shape; the first N sites are filled, and the
# peers need the product to be N), else the shape of a known size. Sets dt: DT if set, else 2.42e-4 s
# (0.2 × Rayleigh) up to 25 layers, the lattices of the known sizes, which it resolves with about 9 steps a
# contact at the fastest approach; a taller lattice falls faster, and the Hertz contact time
# t_c = 2.9432 δ_max/v with δ_max ∝ v^(4/5) (Johnson 1985 §11.4) goes as v^(-1/5), v² as the height, so
# above 25 layers the step is 2.42e-4 s × (25.5 / (nz + 0.5))^(1/10). Every code of a comparison takes it.
if [ -n "${NX:-}${NY:-}${NZ:-}" ]; then
  nx=${NX:?NX, NY and NZ together}; ny=${NY:?NX, NY and NZ together}; nz=${NZ:?NX, NY and NZ together}
else
  case "$N" in
    10000) nx=25; ny=20; nz=20 ;;
    20000) nx=40; ny=25; nz=20 ;;
    50000) nx=50; ny=40; nz=25 ;;
    80)    nx=5;  ny=4;  nz=4 ;;
    *)     echo "pour: N=$N has no default shape: set NX, NY and NZ" >&2; exit 2 ;;
  esac
fi
if [ $((nx * ny * nz)) -lt "$N" ]; then
  echo "pour: NX*NY*NZ = $((nx * ny * nz)) sites for N = $N spheres" >&2; exit 2
fi
dt=${DT:-$(awk -v z="$nz" 'BEGIN { f = z <= 25 ? 1 : (25.5 / (z + 0.5)) ^ 0.1; printf "%.4g", 2.42e-4 * f }')}
