#!/usr/bin/env python3
"""A ball's impact on a clamped acrylic plate (configs/verification/slab_impact*.yaml, gmsh tetrahedra),
the plate in fem_solver's tet4 and in FEniCSx (adapters/fenicsx/elastic_solid.py --mesh), the ball in
dem_solver, through adapters/fenicsx/compare_slab.py:

- the two plates are the same linear tetrahedra on the same mesh at the same step (fem_solver's total
  Lagrangian against FEniCSx's linear strain, at strains of 1e-4): the displacement under the impact
  agrees over the whole run to 1e-3 of its peak, the peak contact force and the rebound to 1e-4;
- the ball on the plate held rigid (dem_solver alone) meets Hertz's peak force to 0.5 % and his contact
  duration to 1 % (the series samples it every 10 µs);
- the plate gives way: the coupled peak force lies below the rigid plate's, by less than 10 %;
- the coupling transfers work without loss: the interface energy error below 1e-5.

Use: test_fenicsx_slab_impact.py BUILD_DIR OUT
"""
import pathlib
import sys

build, out = (pathlib.Path(a) for a in sys.argv[1:3])
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[3] / "adapters" / "fenicsx"))
import compare_slab  # noqa: E402

failures = []


def check(name, ok, detail=""):
    print(f"{'ok  ' if ok else 'FAIL'} {name} {detail}", flush=True)
    if not ok:
        failures.append(name)


codes = {name: compare_slab.run(build / "bin", out, name) for name in compare_slab.RUNS}
codes["rigid"] = compare_slab.run_rigid(build / "bin", out)
check("every run ends with exit 0", not any(codes.values()), f"({codes})")
if not any(codes.values()):
    fig = compare_slab.compare(out)
    print(compare_slab.table(fig))
    a, b, rigid, hertz = fig["fem_solver"], fig["fenicsx"], fig["rigid"], fig["hertz"]
    check("the same instants in both plates' series", fig["same_instants"])
    d = fig["displacement_history_difference"]
    check("displacement under the impact: FEniCSx as fem_solver over the run", d < 1e-3, f"({d:.1e} of its peak)")
    rel = b["peak_contact_force"] / a["peak_contact_force"] - 1
    check("peak contact force: FEniCSx as fem_solver", abs(rel) < 1e-4, f"({rel:+.1e})")
    rel = b["rebound_velocity"] / a["rebound_velocity"] - 1
    check("rebound speed: FEniCSx as fem_solver", abs(rel) < 1e-4, f"({rel:+.1e})")
    rel = rigid["peak_contact_force"] / hertz["peak_contact_force"] - 1
    check("rigid plate: Hertz's peak force", abs(rel) < 5e-3, f"({rel:+.1e})")
    rel = rigid["contact_duration"] / hertz["contact_duration"] - 1
    check("rigid plate: Hertz's contact duration", abs(rel) < 1e-2, f"({rel:+.1e})")
    ratio = a["peak_contact_force"] / rigid["peak_contact_force"]
    check("the plate gives way: a lower peak force than on the rigid plate", 0.9 < ratio < 1.0, f"(× {ratio:.4f})")
    for name in compare_slab.RUNS:
        e = fig[name]["interface_energy_error"]
        check(f"{name}: the interface energy error", e < 1e-5, f"({e:.1e})")
print("FAIL" if failures else "all passed")
sys.exit(1 if failures else 0)
