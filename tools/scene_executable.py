"""Which executable reads a scene file, from what the file holds: a `#! run:` line (stability scenes),
`participants:` (a coupled scene, cosim), `interactions:` or configs/dem (dem_solver, a triaxial test's
`specimen:` included), `specimen:` (lattice_solver), else fem_solver. Shared by tools/cost_table.py and the key-documentation test."""
import re
from pathlib import Path


def scene_executable(scene: Path) -> str:
    text = scene.read_text()
    if "#! run:" in text:
        return re.search(r"#! run: (\S+)", text).group(1)
    if re.search(r"^participants:", text, re.M):
        return "cosim"
    # A DEM triaxial test has a `specimen:` too, and `interactions:` or lives in configs/dem.
    if re.search(r"^interactions:", text, re.M) or scene.parent.name == "dem":
        return "dem_solver"
    if re.search(r"^specimen:", text, re.M) or scene.parent.name == "lattice":
        return "lattice_solver"
    return "fem_solver"
