#!/usr/bin/env python3
"""What each shipped scene pays for: run every scene of configs/ (or reuse OUT/<scene>/summary.yaml) and
print the `cost:` sections of their summary.yaml files as one markdown table (docs/performance.md).

Usage:  tools/cost_table.py BUILD_DIR OUT [--reuse] [--skip NAME ...]
"""
import argparse
import subprocess
import sys
from pathlib import Path

import yaml

from scene_executable import scene_executable

ROOT = Path(__file__).resolve().parent.parent
# Which executable runs a scene: coupled scenes name participants; the others by their folder. Scenes
# that are a participant's half of a coupled scene (no standalone meaning) are left out.
PARTS = {"block.yaml", "net.yaml", "coupling.yaml", "lattice_prism_fem_high.yaml", "lattice_prism_fem_low.yaml",
         "lattice_prism_lattice.yaml", "split_bar_left.yaml", "split_bar_right.yaml",
         "split_bar_dynamic_left.yaml", "split_bar_dynamic_right.yaml"}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("build", type=Path)
    ap.add_argument("out", type=Path)
    ap.add_argument("--reuse", action="store_true", help="read OUT/<scene>/summary.yaml where it exists")
    ap.add_argument("--skip", nargs="*", default=[], help="scene names to leave out (long runs)")
    a = ap.parse_args(argv)
    scenes = []
    for folder in ("dem", "fem", "lattice", "rockfall", "verification"):
        for s in sorted((ROOT / "configs" / folder).glob("*.yaml")):
            if s.name not in PARTS and s.stem not in a.skip:
                scenes.append(s)
    rows = []
    for s in scenes:
        out = a.out / f"{s.parent.name}_{s.stem}"
        if not (a.reuse and (out / "summary.yaml").exists()):
            exe = a.build / "bin" / scene_executable(s)
            subprocess.run([str(exe), str(s), "--out", str(out), "--quiet"], stdout=subprocess.DEVNULL,
                           stderr=subprocess.DEVNULL)
        summary = yaml.safe_load((out / "summary.yaml").read_text()) if (out / "summary.yaml").exists() else {}
        cost = summary.get("cost") or {}
        per_step = cost.get("time_per_step_s") or cost.get("time_per_window_s") or cost.get("time_per_increment_s")
        memory = cost.get("peak_memory_mb", 0) + cost.get("peak_memory_children_mb", 0)
        rows.append(f"| `{s.parent.name}/{s.name}` | {summary.get('exit_code', '—')} | {cost.get('processes', '—')} | "
                    f"{cost.get('threads', '—')} | {cost.get('physics') or cost.get('coupling') or '—'} | "
                    f"{cost.get('physics_left_out', '—') or '—'} | {memory:.0f} | {cost.get('output_bytes', 0) / 1e6:.2f} | "
                    f"{per_step:.3g} | {summary.get('wall_time_s', 0):.2f} |" if per_step else
                    f"| `{s.parent.name}/{s.name}` | {summary.get('exit_code', '—')} | {cost.get('processes', '—')} | "
                    f"{cost.get('threads', '—')} | {cost.get('physics') or cost.get('coupling') or '—'} | "
                    f"{cost.get('physics_left_out', '—') or '—'} | {memory:.0f} | {cost.get('output_bytes', 0) / 1e6:.2f} | "
                    f"— | {summary.get('wall_time_s', 0):.2f} |")
        print(rows[-1], flush=True)
    print()
    print("| scene | exit | processes | threads | physics computed | left out | peak MB | output MB | s per step | wall s |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    print("\n".join(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
