#!/usr/bin/python3
"""The pour benchmark's initial state for the peer codes, from dem_solver's step-0 snapshot.

Our generator puts the spheres on a cubic lattice of spacing 2.1 r with each site jittered by up to
±0.025 r per axis (dem_solver/src/scene.cpp). On the exact lattice the peers used before (until
2026-11-24) the columns fall straight down without touching each other: LIGGGHTS ends with 1.9 contacts
per sphere and no rotation, the friction never loaded, where our pour builds a random packing of 5. From
the same jittered sites all three codes build the same packing, so the peers start from these positions,
to all digits.

Usage: initial_state.py DEM_H5 NX NY NZ PREFIX
  writes PREFIX.data (LIGGGHTS read_data, atom_style granular) and PREFIX.txt (x y z r per line, YADE)
  for the box [0, NX s] x [0, NY s] x [0, NZ s + 0.1 m], s = 0.021 m.
"""
import sys

import h5py

S = 0.021
DENSITY = 2500.0


def num(v):
    return repr(float(v))  # shortest text that reads back to the same double


def main():
    if len(sys.argv) != 6:
        sys.exit(__doc__)
    h5, nx, ny, nz, prefix = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4]), sys.argv[5]
    with h5py.File(h5, "r") as f:
        step = f["particles/spheres/steps/000000"]
        x = step["position"][:]
        r = step["radius"][:]
    if len(r) != nx * ny * nz:
        sys.exit(f"initial_state: {h5} holds {len(r)} spheres, expected {nx * ny * nz}")
    hi = (nx * S, ny * S, nz * S + 0.1)
    for axis in range(3):
        lo_ok = (x[:, axis] - r > 0).all()
        hi_ok = (x[:, axis] + r < hi[axis]).all()
        if not (lo_ok and hi_ok):
            sys.exit(f"initial_state: a sphere crosses the box along axis {axis}")
    with open(prefix + ".data", "w") as out:
        out.write("LIGGGHTS data file: pour benchmark initial state (tests/bench/peers/initial_state.py)\n\n")
        out.write(f"{len(r)} atoms\n1 atom types\n\n")
        out.write(f"0 {num(hi[0])} xlo xhi\n0 {num(hi[1])} ylo yhi\n0 {num(hi[2])} zlo zhi\n\nAtoms\n\n")
        for i, (p, ri) in enumerate(zip(x, r)):
            out.write(f"{i + 1} 1 {num(2 * ri)} {num(DENSITY)} {num(p[0])} {num(p[1])} {num(p[2])}\n")
    with open(prefix + ".txt", "w") as out:
        for p, ri in zip(x, r):
            out.write(f"{num(p[0])} {num(p[1])} {num(p[2])} {num(ri)}\n")


if __name__ == "__main__":
    main()
