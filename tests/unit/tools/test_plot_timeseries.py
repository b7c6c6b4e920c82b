"""Runs tools/plot_timeseries.py on the sample run written by common::H5Writer (test_common) and checks
the PNGs: one per series, real images with drawn curves, and a clear error on an empty folder."""
import pathlib
import subprocess
import sys
import tempfile

import matplotlib.image as mpimg
import numpy as np

tool, sample = pathlib.Path(sys.argv[1]), pathlib.Path(sys.argv[2])
failures = 0


def check(cond, what):
    global failures
    print(("ok   " if cond else "FAIL ") + what)
    failures += 0 if cond else 1


with tempfile.TemporaryDirectory() as tmp:
    out = pathlib.Path(tmp) / "plots"
    r = subprocess.run([sys.executable, str(tool), str(sample.parent), "--out", str(out)], capture_output=True, text=True)
    check(r.returncode == 0, f"tool exits 0 (stderr: {r.stderr.strip()})")
    for series, panels in (("energy", 2), ("block", 2)):
        png = out / f"{sample.stem}_{series}.png"
        check(png.exists(), f"{png.name} written")
        if not png.exists():
            continue
        img = mpimg.imread(png)
        h, w = img.shape[:2]
        check(w >= 600 and h >= 300, f"{png.name} is {w}x{h} px")
        # Curves are drawn in the default blue (#1f77b4): count pixels of that colour.
        rgb = img[..., :3]
        blue = np.all(np.abs(rgb - np.array([0x1F, 0x77, 0xB4]) / 255.0) < 0.08, axis=-1).sum()
        check(blue > 200 * panels, f"{png.name} has {blue} curve pixels")
    r = subprocess.run([sys.executable, str(tool), tmp + "/nothing"], capture_output=True, text=True)
    check(r.returncode == 2 and "does not exist" in r.stderr, "missing folder: exit 2 with a message")
    empty = pathlib.Path(tmp) / "empty"
    empty.mkdir()
    r = subprocess.run([sys.executable, str(tool), str(empty)], capture_output=True, text=True)
    check(r.returncode == 2 and "no .h5 files" in r.stderr, "empty folder: exit 2 with a message")

sys.exit(1 if failures else 0)
