#!/usr/bin/env python3
"""A dem_solver ball's impact on a clamped acrylic plate of fem_solver tet4 from a gmsh mesh
(configs/verification/slab_impact.yaml), the reference side of the FEniCSx plate (adapters/fenicsx/
compare_slab.py), with no external code:

- the ball on the plate held rigid (dem_solver alone) meets Hertz's peak force to 0.5 % and his contact
  duration to 1 % (Johnson 1985, eqs. 11.45–11.47; the series samples it every 10 µs);
- the plate gives way: the coupled peak force lies below the rigid plate's, by less than 10 %, and the
  contact lasts longer;
- energy: what the ball loses (½ m (v₀² − v₁²)) is the plate's kinetic and strain energy at the end, to
  1e-3 (no damping on either side), and the interface energy error is below 1e-5.

Use: test_plate_impact.py BUILD_DIR OUT
"""
import pathlib
import sys

build, out = (pathlib.Path(a) for a in sys.argv[1:3])
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[3] / "adapters" / "fenicsx"))
import compare_slab  # noqa: E402

from checklist import check, finish  # noqa: E402 (this folder: the script's own)



codes = (compare_slab.run(build / "bin", out, "fem_solver"), compare_slab.run_rigid(build / "bin", out))
check("both runs end with exit 0", codes == (0, 0), f"({codes})")
if codes == (0, 0):
    coupled = compare_slab.coupled_figures(out, "fem_solver")
    rigid = compare_slab.impact_figures(out / "rigid" / "dem.h5")
    hertz = compare_slab.hertz()
    rel = rigid["peak_contact_force"] / hertz["peak_contact_force"] - 1
    check("rigid plate: Hertz's peak force", abs(rel) < 5e-3, f"({rel:+.1e})")
    rel = rigid["contact_duration"] / hertz["contact_duration"] - 1
    check("rigid plate: Hertz's contact duration", abs(rel) < 1e-2, f"({rel:+.1e})")
    ratio = coupled["peak_contact_force"] / rigid["peak_contact_force"]
    check("the plate gives way: a lower peak force", 0.9 < ratio < 1.0, f"(× {ratio:.4f})")
    ratio = coupled["contact_duration"] / rigid["contact_duration"]
    check("the plate gives way: a longer contact", 1.0 < ratio < 1.2, f"(× {ratio:.4f})")
    lost, plate = coupled["ball_energy_lost"], coupled["plate_energy"]
    check("the ball's lost energy is the plate's", abs(plate / lost - 1) < 1e-3, f"({plate:.5f} J against {lost:.5f} J)")
    error = coupled["interface_energy_error"]
    check("the interface energy error", error < 1e-5, f"({error:.1e})")
finish()
