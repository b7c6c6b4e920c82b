"""The XDMF files of a short coupled rockfall run (c2 to 15 ms, snapshots every 5 ms), of a standalone
DEM bounce and of a pour's force network: every Grid has a Topology and a Geometry, every DataItem names an HDF5 dataset that exists with
the stated dimensions, the time values increase, the net carries its coupled force and the spheres a
radius; a file whose writer had no snapshot has no .xdmf at all (coupling.h5).
Run: python3 test_xdmf.py BUILD/bin SOURCE_DIR OUT"""
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import h5py
import yaml

bin_dir, source, out = Path(sys.argv[1]), Path(sys.argv[2]), Path(sys.argv[3])
failures = []
subprocess.run(["rm", "-rf", str(out)], check=True)
coupled = out / "c2"
r = subprocess.run([str(bin_dir / "cosim"), "run", str(source / "configs/rockfall/c2.yaml"), "--out", str(coupled),
                    "--quiet", "--set", "coupling.end_time=0.015"], capture_output=True, text=True)
if r.returncode != 0:
    failures.append(f"coupled run: exit {r.returncode}: {r.stderr[-400:]}")
standalone = out / "bounce"
subprocess.run([str(bin_dir / "dem_solver"), str(source / "configs/dem/hertz_bounce.yaml"), "--out", str(standalone),
                "--quiet"], check=True)


def check(xdmf, grids_expected, arrays_expected):
    root = ET.parse(xdmf).getroot()
    collections = root.findall("./Domain/Grid")
    if len(collections) != len(grids_expected):
        failures.append(f"{xdmf.name}: {len(collections)} grid collections, expected {grids_expected}")
    for c in collections:
        name = c.get("Name")
        steps = c.findall("./Grid")
        times = [float(s.find("Time").get("Value")) for s in steps]
        if len(steps) != grids_expected.get(name, -1):
            failures.append(f"{xdmf.name}/{name}: {len(steps)} time steps, expected {grids_expected.get(name)}")
        if any(b <= a for a, b in zip(times, times[1:])):
            failures.append(f"{xdmf.name}/{name}: times do not increase: {times}")
        for s in steps:
            if s.find("Topology") is None or s.find("Geometry") is None:
                failures.append(f"{xdmf.name}/{s.get('Name')}: no Topology or Geometry")
            names = {a.get("Name") for a in s.findall("Attribute")}
            for a in arrays_expected.get(name, []):
                if a not in names:
                    failures.append(f"{xdmf.name}/{s.get('Name')}: no attribute {a} (has {sorted(names)})")
            for item in s.iter("DataItem"):
                file, _, dataset = item.text.strip().partition(":")
                dims = [int(d) for d in item.get("Dimensions").split()]
                with h5py.File(xdmf.parent / file, "r") as f:
                    if dataset not in f:
                        failures.append(f"{xdmf.name}: {dataset} does not exist in {file}")
                    elif list(f[dataset].shape) != dims and [f[dataset].size] != dims:
                        failures.append(f"{xdmf.name}: {dataset} has shape {f[dataset].shape}, the XDMF says {dims}")


# 0, 5, 10, 15 ms: four snapshots of the net; the block's spheres (and the DEM's copy of the net) from
# the first window on, 5, 10, 15 ms;
# the bounce: every 1e-5 s of its 3e-4 s, 31.
check(coupled / "fem" / "fem.xdmf", {"surface": 4}, {"surface": ["displacement", "velocity", "coupled_force", "pk2_stress"]})
check(coupled / "dem" / "dem.xdmf", {"spheres": 3, "net": 3}, {"spheres": ["radius", "velocity", "body_force"], "net": ["force"]})
check(standalone / "dem.xdmf", {"spheres": 31}, {"spheres": ["radius", "velocity"]})
# The force network of a granular run: a Polyline grid per snapshot, its own lines, a normal force per
# line, positive, between centres closer than two largest radii (2 × 11 mm).
pour = out / "pour"
subprocess.run([str(bin_dir / "dem_solver"), str(source / "configs/dem/pour.yaml"), "--out", str(pour), "--quiet",
                "--set", "end_time=0.2", "--set", "output={interval: 0.1}"], check=True)
check(pour / "dem.xdmf", {"spheres": 3, "contacts": 2}, {"contacts": ["normal_force"]})
root = ET.parse(pour / "dem.xdmf").getroot()
for grid in root.iter("Grid"):
    if grid.get("Name", "").startswith("contacts_") and grid.find("Topology").get("TopologyType") != "Polyline":
        failures.append(f"{grid.get('Name')}: topology {grid.find('Topology').get('TopologyType')}, expected Polyline")
with h5py.File(pour / "dem.h5", "r") as f:
    for name, step in f["networks/contacts/steps"].items():
        p, lines, fn = step["points"][()], step["lines"][()], step["normal_force"][()]
        length = ((p[lines[:, 0]] - p[lines[:, 1]]) ** 2).sum(axis=1) ** 0.5
        # (the force is from the step's force pass, the centres from its end: a pair separating in that step
        # may be a little longer than 2 r_max; far less than a skin, 0.2 r)
        if not (fn > 0).all() or not (length < 0.022 * 1.1).all() or len(lines) < 100:
            failures.append(f"network {name}: {len(lines)} lines, force min {fn.min()}, longest {length.max()}")
# Every other solver's XDMF, standalone: the lattice's rods and cracks, the FEM's net in vibration.
lattice = out / "lattice"
subprocess.run([str(bin_dir / "lattice_solver"), str(source / "configs/lattice/elastic_cubic.yaml"), "--out", str(lattice),
                "--quiet"], check=True)
fem = out / "fem"
subprocess.run([str(bin_dir / "fem_solver"), str(source / "configs/fem/membrane_vibration.yaml"), "--out", str(fem),
                "--quiet", "--set", "explicit.end_time=0.2"], check=True)
# Snapshots from the scenes: the lattice with output.snapshot_every unset writes the final state only; the
# membrane one at t = 0 and every output.interval to the end_time set above.
lattice_scene = yaml.safe_load((source / "configs/lattice/elastic_cubic.yaml").read_text())
lattice_grids = 1 if not (lattice_scene.get("output") or {}).get("snapshot_every") else None
fem_scene = yaml.safe_load((source / "configs/fem/membrane_vibration.yaml").read_text())
fem_grids = round(0.2 / fem_scene["output"]["interval"]) + 1
if lattice_grids is None:
    failures.append("configs/lattice/elastic_cubic.yaml now sets output.snapshot_every: count its snapshots here")
else:
    check(lattice / "lattice.xdmf", {"rods": lattice_grids}, {"rods": ["displacement", "rotation", "strain"]})
check(fem / "fem.xdmf", {"surface": fem_grids}, {"surface": ["displacement", "velocity"]})
if (coupled / "coupling.xdmf").exists():
    failures.append("coupling.xdmf exists though coupling.h5 has no grid")
# The picture of the impact renders from these snapshots (make demo writes it for the whole run).
picture = subprocess.run([sys.executable, str(source / "tools/render_rockfall.py"), str(coupled), "--no-animation"],
                         capture_output=True, text=True)
png = coupled / "plots" / "rockfall_max_deflection.png"
if picture.returncode != 0 or not png.is_file() or png.stat().st_size < 20000:
    failures.append(f"render_rockfall.py: exit {picture.returncode}, {picture.stderr[-300:]}")
if failures:
    print("\n".join(failures))
    sys.exit(1)
print("ok")
