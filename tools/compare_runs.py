#!/usr/bin/env python3
"""Compares two results folders of the same scene: every summary.yaml's results and every HDF5 dataset.

Run with:   python3 tools/compare_runs.py RUN_A RUN_B [--rtol 1e-12]

What a restarted run must reproduce (issue 28): the physics. Wall-clock quantities (keys and columns
ending in _s or _time_s, time_per_*, coupling_overhead_share, phase_seconds), static_reused and the cost section differ
between any two runs and are left out. Exit 0 when everything agrees within --rtol (relative to the
larger magnitude of the two values, per dataset), 1 with the first differences listed otherwise.
"""
import argparse
import math
import pathlib
import sys

import h5py
import numpy as np
import yaml

TIMING_SUFFIXES = ("_s", "_time_s", "_seconds")
# How a run computed, not what: wall-clock shares, the idle policy, whether a static start came from the
# cache (the first of two identical runs computes it, the second reads it).
TIMING_KEYS = {"coupling_overhead_share", "phase_seconds", "idle_cpus", "wall_time_s", "time_per_step_s", "static_reused"}


def is_timing(name):
    leaf = name.rsplit("/", 1)[-1]
    return (leaf in TIMING_KEYS or leaf.endswith(TIMING_SUFFIXES) or leaf.startswith("time_per_")
            or leaf.startswith("solver_time_") or leaf.endswith("_thread_wait"))


def close(a, b, rtol):
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if a.shape != b.shape:
        return False, f"shapes {a.shape} and {b.shape}"
    if a.size == 0:
        return True, ""
    scale = max(np.max(np.abs(a)), np.max(np.abs(b)), 1e-300)
    worst = float(np.max(np.abs(a - b)))
    if not np.all(np.isfinite(a) == np.isfinite(b)) or worst > rtol * scale:
        return False, f"largest difference {worst:.3e} (scale {scale:.3e})"
    return True, ""


def compare_summaries(a, b, rtol, where, out):
    ra, rb = (yaml.safe_load(p.read_text()) or {} for p in (a, b))
    out_a, out_b = ra.get("results") or {}, rb.get("results") or {}
    for key in sorted(set(out_a) | set(out_b)):
        if is_timing(key):
            continue
        if key not in out_a or key not in out_b:
            out.append(f"{where}: results.{key} only in one run")
            continue
        va, vb = out_a[key], out_b[key]
        if isinstance(va, str) or isinstance(vb, str):
            if va != vb:
                out.append(f"{where}: results.{key}: {va!r} vs {vb!r}")
            continue
        ok, why = close(va, vb, rtol)
        if not ok:
            out.append(f"{where}: results.{key}: {va} vs {vb}: {why}")
    for key in ("status", "exit_code"):
        if ra.get(key) != rb.get(key):
            out.append(f"{where}: {key}: {ra.get(key)!r} vs {rb.get(key)!r}")


def compare_h5(a, b, rtol, where, out):
    with h5py.File(a, "r") as fa, h5py.File(b, "r") as fb:
        names_a, names_b = [], []
        fa.visititems(lambda n, o: names_a.append(n) if isinstance(o, h5py.Dataset) else None)
        fb.visititems(lambda n, o: names_b.append(n) if isinstance(o, h5py.Dataset) else None)
        for name in sorted(set(names_a) | set(names_b)):
            if is_timing(name):
                continue
            if name not in names_a or name not in names_b:
                out.append(f"{where}:/{name} only in one file")
                continue
            ok, why = close(fa[name][()], fb[name][()], rtol)
            if not ok:
                out.append(f"{where}:/{name}: {why}")
        for name in sorted(set(names_a) & set(names_b)):
            ta, tb = fa[name].parent.attrs.get("time"), fb[name].parent.attrs.get("time")
            if ta is not None and tb is not None and not math.isclose(float(ta), float(tb), rel_tol=rtol, abs_tol=0):
                out.append(f"{where}:/{name}: snapshot time {ta} vs {tb}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_a", type=pathlib.Path)
    parser.add_argument("run_b", type=pathlib.Path)
    parser.add_argument("--rtol", type=float, default=1e-12)
    args = parser.parse_args()
    differences, compared = [], 0
    for path_a in sorted(args.run_a.rglob("*")):
        rel = path_a.relative_to(args.run_a)
        if rel.parts and rel.parts[0] == "checkpoint":
            continue
        path_b = args.run_b / rel
        if path_a.name == "summary.yaml" or path_a.suffix == ".h5":
            if not path_b.exists():
                differences.append(f"{rel}: missing in {args.run_b}")
                continue
            compared += 1
            (compare_summaries if path_a.suffix == ".yaml" else compare_h5)(path_a, path_b, args.rtol, str(rel), differences)
    for d in differences[:40]:
        print(d)
    if len(differences) > 40:
        print(f"… and {len(differences) - 40} more")
    print(f"{compared} files compared, {len(differences)} differences (rtol {args.rtol:g})")
    return 1 if differences or compared == 0 else 0


if __name__ == "__main__":
    sys.exit(main())
