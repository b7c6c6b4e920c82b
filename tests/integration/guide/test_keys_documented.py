"""Every scene key a solver reads is in its README: `--check` on every scene of configs/ (and the study
and stability scenes) with COSIM_LIST_KEYS records the key paths each executable asked for; each key's
name must appear in that executable's README (its key table), so the documentation cannot drift from the
code. Run: python3 test_keys_documented.py SOURCE_DIR BIN_DIR OUT"""
import os
import re
import subprocess
import sys
from pathlib import Path

source, bin_dir, out = Path(sys.argv[1]), Path(sys.argv[2]), Path(sys.argv[3])
sys.path.insert(0, str(source / "tools"))
from scene_executable import scene_executable  # noqa: E402
out.mkdir(parents=True, exist_ok=True)
listing = out / "keys.txt"
listing.unlink(missing_ok=True)
readmes = {"dem_solver": "dem_solver/README.md", "fem_solver": "fem_solver/README.md",
           "lattice_solver": "lattice_solver/README.md", "cosim": "coupler/README.md"}
parts = {"coupling.yaml"}  # an include of the rockfall scenes, no scene of its own


env = dict(os.environ, COSIM_LIST_KEYS=str(listing))
for folder in ("dem", "fem", "lattice", "rockfall", "verification", "stability"):
    for scene in sorted((source / "configs" / folder).glob("*.yaml")):
        if scene.name in parts:
            continue
        exe = scene_executable(scene)
        r = subprocess.run([str(bin_dir / exe), str(scene), "--check", "--quiet"], env=env, capture_output=True, text=True)
        if r.returncode != 0:  # a scene that does not check records no keys: that is a failure here
            print(f"{exe} {scene.relative_to(source)} --check: exit {r.returncode}: {r.stderr.strip()[-300:]}")
            sys.exit(1)
missing = {}
for line in listing.read_text().splitlines():
    exe, key = line.split(" ", 1)
    name = key.replace("[]", "").split(".")[-1]
    text = (source / readmes[exe]).read_text()
    if not re.search(r"(?<![A-Za-z_])" + re.escape(name) + r"(?![A-Za-z_])", text):
        missing.setdefault(exe, set()).add(key)
if missing:
    for exe, keys in sorted(missing.items()):
        print(f"{readmes[exe]} does not document: {', '.join(sorted(keys))}")
    sys.exit(1)
print(f"ok: {len(listing.read_text().splitlines())} keys read, every one documented")
