#!/usr/bin/env python3
"""The YADE adapter's parts that need no YADE: the split of a facet contact force to the facet's nodes
(force and moment kept), and the net's grid, node for node the mesh that dem_solver builds from the same
`grid:` keys (read from a dem_solver run's dem.h5).

Use: test_yade_adapter.py ADAPTER_DIR DEM_H5 ORIGIN_X ORIGIN_Y ORIGIN_Z LX LY NX NY PATTERN
"""
import sys

import h5py
import numpy as np

sys.path.insert(0, sys.argv[1])
sys.path.insert(0, sys.argv[1] + "/../../coupler/python")
import cosim_yade  # noqa: E402
from cosim_participant import substeps  # noqa: E402

failures = []


def check(name, ok, detail=""):
    print(f"{'ok  ' if ok else 'FAIL'} {name} {detail}")
    if not ok:
        failures.append(name)


rng = np.random.default_rng(7)
worst_f = worst_m = worst_w = 0.0
for _ in range(200):
    a, b, c = rng.normal(size=(3, 3))
    w = rng.dirichlet([1, 1, 1])
    p = w[0] * a + w[1] * b + w[2] * c  # a point of the facet
    f = rng.normal(size=3) * 1e3
    nodal = cosim_yade.split_force(a, b, c, p, f)
    moment = sum(np.cross(x, g) for x, g in zip((a, b, c), nodal))
    worst_f = max(worst_f, np.abs(nodal.sum(axis=0) - f).max() / np.abs(f).max())
    worst_m = max(worst_m, np.abs(moment - np.cross(p, f)).max() / (np.abs(f).max() * np.abs(p).max()))
    worst_w = max(worst_w, np.abs(np.array(cosim_yade.barycentric(a, b, c, p)) - w).max())
check("split: the nodal forces sum to the contact force", worst_f < 1e-13, f"(worst relative {worst_f:.1e})")
check("split: their moment about the origin is the force's at its point", worst_m < 1e-10, f"(worst relative {worst_m:.1e})")
check("split: barycentric weights recovered", worst_w < 1e-10, f"(worst {worst_w:.1e})")

# A contact point off the plane (YADE puts it halfway into the overlap) splits as its projection.
a, b, c = np.array([0.0, 0, 0]), np.array([1.0, 0, 0]), np.array([0.0, 1, 0])
nodal = cosim_yade.split_force(a, b, c, [0.25, 0.25, -0.01], [0, 0, -100.0])
check("split: a point below the facet goes by its projection", np.allclose(nodal[:, 2], [-50, -25, -25], atol=1e-12),
      f"({nodal[:, 2]})")
# On an edge: the far node gets nothing.
nodal = cosim_yade.split_force(a, b, c, [0.5, 0.5, 0], [0, 0, -100.0])
check("split: a point on an edge loads its two nodes only", np.allclose(nodal[:, 2], [0, -50, -50], atol=1e-12),
      f"({nodal[:, 2]})")

# The grid against dem_solver's own (the mesh of its dem.h5).
origin = [float(x) for x in sys.argv[3:6]]
size = [float(x) for x in sys.argv[6:8]]
divisions = [int(x) for x in sys.argv[8:10]]
nodes, triangles = cosim_yade.grid_mesh(origin, size, divisions, sys.argv[10])
with h5py.File(sys.argv[2], "r") as f:
    name = next(iter(f["meshes"]))
    ref_nodes, ref_cells = f["meshes"][name]["nodes"][()], f["meshes"][name]["cells"][()]
check("grid: dem_solver's nodes, in its order", ref_nodes.shape == nodes.shape and np.abs(ref_nodes - nodes).max() < 1e-12)
check("grid: dem_solver's triangles, in its order and orientation",
      ref_cells.shape == triangles.shape and np.array_equal(ref_cells, triangles))

mass = cosim_yade.node_masses(nodes, triangles, 0.65)
interior = divisions[0] // 2 * (divisions[0] + 1) + divisions[0] // 2  # the middle node: eight triangles (alternate)
cell = size[0] / divisions[0] * size[1] / divisions[1]
check("node masses: the sheet's whole mass", abs(mass.sum() - 0.65 * size[0] * size[1]) < 1e-12 * mass.sum(), f"({mass.sum()})")
check("node masses: a third of each triangle at a corner", abs(mass[interior] - 0.65 * 8 * cell / 2 / 3) < 1e-15,
      f"({mass[interior]})")
check("substeps: whole substeps of at most dt", [substeps(1e-4, 1e-5), substeps(1e-4 * (1 + 1e-14), 1e-5),
                                                  substeps(5e-5, 1e-5), substeps(1e-4, 3e-5)] == [10, 10, 5, 4])
sys.exit(1 if failures else 0)
