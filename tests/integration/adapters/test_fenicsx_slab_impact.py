#!/usr/bin/env python3
"""A ball's impact on a clamped acrylic plate (configs/verification/slab_impact*.yaml, gmsh tetrahedra),
the plate in fem_solver's tet4 and in FEniCSx (adapters/fenicsx/elastic_solid.py --mesh), the ball in
dem_solver, through adapters/fenicsx/compare_slab.py:

- the two plates are the same linear tetrahedra on the same mesh at the same step (fem_solver's total
  Lagrangian against FEniCSx's linear strain, at strains of 1e-4): the displacement under the impact
  agrees over the whole run to 1e-3 of its peak, the peak contact force and the rebound to 1e-4;
- what the ball loses is the FEniCSx plate's kinetic and strain energy at the end, to 1e-3 (its kinetic
  energy from the last half-step velocity), and the interface energy error is below 1e-5.
The fem_solver plate against Hertz and its own energy: test_plate_impact.py.

Use: test_fenicsx_slab_impact.py BUILD_DIR OUT
"""
import pathlib
import sys

build, out = (pathlib.Path(a) for a in sys.argv[1:3])
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[3] / "adapters" / "fenicsx"))
import compare_slab  # noqa: E402

from checklist import check, finish  # noqa: E402 (this folder: the script's own)



codes = {name: compare_slab.run(build / "bin", out, name) for name in compare_slab.RUNS}
codes["rigid"] = compare_slab.run_rigid(build / "bin", out)
check("every run ends with exit 0", not any(codes.values()), f"({codes})")
if not any(codes.values()):
    fig = compare_slab.compare(out)
    print(compare_slab.table(fig))
    a, b = fig["fem_solver"], fig["fenicsx"]
    check("the same instants in both plates' series", fig["same_instants"])
    d = fig["displacement_history_difference"]
    check("displacement under the impact: FEniCSx as fem_solver over the run", d < 1e-3, f"({d:.1e} of its peak)")
    rel = b["peak_contact_force"] / a["peak_contact_force"] - 1
    check("peak contact force: FEniCSx as fem_solver", abs(rel) < 1e-4, f"({rel:+.1e})")
    rel = b["rebound_velocity"] / a["rebound_velocity"] - 1
    check("rebound speed: FEniCSx as fem_solver", abs(rel) < 1e-4, f"({rel:+.1e})")
    rel = b["plate_energy"] / b["ball_energy_lost"] - 1
    check("FEniCSx: the ball's lost energy is the plate's", abs(rel) < 1e-3, f"({rel:+.1e})")
    for name in compare_slab.RUNS:
        e = fig[name]["interface_energy_error"]
        check(f"{name}: the interface energy error", e < 1e-5, f"({e:.1e})")
finish()
