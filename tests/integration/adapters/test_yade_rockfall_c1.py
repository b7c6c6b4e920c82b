#!/usr/bin/env python3
"""Rockfall c1 as given, YADE as the DEM participant against dem_solver (adapters/yade/compare.py
--only on_node): YADE's run ends with exit 0, and its figures stay within the differences explained in
docs/validation/external_codes.md (max deflection −0.0 %, peak F_R +2.9 %, peak F_C +4.7 %, each by its
cause): max deflection within 2 %, peak reaction force within 5 %, peak contact force within 8 %, and the
energy balance of both runs within 3 %.

Use: test_yade_rockfall_c1.py BUILD_DIR OUT
"""
import pathlib
import shutil
import subprocess
import sys

import yaml

from checklist import check, finish  # noqa: E402 (this folder: the script's own)

build, out = (pathlib.Path(a) for a in sys.argv[1:3])
compare = pathlib.Path(__file__).resolve().parents[3] / "adapters" / "yade" / "compare.py"


shutil.rmtree(out, ignore_errors=True)  # a run that fails early must not leave an earlier run's summary to check
p = subprocess.run([sys.executable, str(compare), str(build), str(out), "--only", "on_node"], capture_output=True, text=True)
print(p.stdout[-3000:], p.stderr[-2000:])
check("compare.py ends with exit 0", p.returncode == 0, f"({p.returncode})")
results = {}
for side in ("dem_solver", "yade"):
    path = out / f"c1_on_node_{side}" / "summary.yaml"
    summary = yaml.safe_load(path.read_text()) if path.exists() else {}
    check(f"{side}: the run ends with exit 0", summary.get("exit_code") == 0, f"({summary.get('exit_code')})")
    results[side] = summary.get("results", {})
ours, theirs = results["dem_solver"], results["yade"]
for key, tolerance in [("max_deflection", 0.02), ("peak_reaction_force", 0.05), ("peak_contact_force", 0.08)]:
    if key in ours and key in theirs:
        rel = theirs[key] / ours[key] - 1
        check(f"{key}: YADE within {tolerance:.0%} of dem_solver", abs(rel) < tolerance, f"({rel:+.2%})")
    else:
        check(f"{key}: reported by both", False)
for side, r in results.items():
    e = r.get("energy_balance_error", float("inf"))
    check(f"{side}: the energy balance within 3 %", e < 0.03, f"({e:.2%})")
finish()
