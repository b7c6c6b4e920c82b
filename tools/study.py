#!/usr/bin/env python3
"""Error against run time: run a scene over parameter ladders and report what each setting buys.

Usage:  cosim study STUDY.yaml [--out DIR] [-j N] [--quiet]
        (or python3 tools/study.py STUDY.yaml --bin BUILD/bin [--out DIR] [-j N] [--quiet])

A study file (configs/studies/*.yaml; its header states each ladder's expected order and why):

    study:
      run: dem_solver                  # an executable of the build's bin/ (cosim for coupled scenes)
      scene: ../dem/hertz_bounce.yaml  # relative to the study file
      set: [output.interval=0]         # overrides for every run (coupled: NAME:KEY=VALUE reaches a participant)
      time: loop_wall_time_s           # the run time plotted: wall_time_s (default) or a summary result
      post: [python3, tools/rockfall_report.py]   # run on each run's folder before its results are read
    ladders:
      dt:                              # a ladder: one scene key, or several changed together
        key: dt                        # or keys: [dt, end_time] with values: [[…, …], …]
        values: [8.0e-7, 4.0e-7, 2.0e-7]
        parameter: dt                  # the ladder parameter the order is fitted against (default: the first
                                       # key's value; `1/KEY` for a count such as elements per side), or
                                       # parameters: [..] stated per rung
        expected_order: 2
        fit_rungs: 3                   # the finest rungs in the asymptotic range (default: all)
    metrics:
      contact_duration:                # a summary.yaml result of the run …
        result: contact_duration
        reference: {result: contact_duration_analytic}   # … against a result the scene computes itself,
      overlap: {result: max_overlap, reference: {value: 2.386e-5}}  # a published number,
      sag: {result: center_sag, reference: finest}     # or the finest rung (Richardson error estimate);
      iterations: {result: mean_coupling_iterations, reference: none}   # tabulated, no error
      tip: {summary: left, result: tip_ux, reference: finest}   # a participant's summary (coupled runs)
      force:                           # or an HDF5 time series of the run:
        series: {file: dem.h5, dataset: /timeseries/body_0/fz, norm: max}   # max | at: t | l2 (vs the finest rung)
        reference: finest

Each run's folder is DIR/runs/<hash of the binary, the scene files and the overrides>: a run already
done is reused, not rerun (the progress line says so), so adding a rung or re-plotting is cheap.
Writes DIR/table.csv, DIR/table.md, DIR/error_vs_runtime.png and DIR/summary.yaml
(results.ladders.<ladder>.observed_order / expected_order / orders per metric). Exit 0 when every run
ended 0; 2 for a study file error (with its file:line); 3 when a run failed (the table says which).
"""
import argparse
import concurrent.futures
import csv
import difflib
import hashlib
import math
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parent.parent


class StudyError(Exception):
    """A mistake in the study file: the message names the file, line and key."""


def located(node, path, message):
    mark = getattr(node, "start_mark", None)
    where = f"{path}:{mark.line + 1}:{mark.column + 1}" if mark else str(path)
    return StudyError(f"{where}: {message}")


def compose(path):
    """The study file as plain data plus its YAML node tree (for line numbers)."""
    text = path.read_text()
    try:
        node = yaml.compose(text)
        data = yaml.safe_load(text)
    except yaml.YAMLError as e:
        raise StudyError(f"{path}: not valid YAML: {e}")
    if not isinstance(data, dict):
        raise StudyError(f"{path}: a study file is a map with study:, ladders: and metrics:.")
    return data, node


def child(node, key):
    if isinstance(node, yaml.MappingNode):
        for k, v in node.value:
            if k.value == key:
                return v
    return node


def number(x):
    """YAML 1.1 reads 1e-5 (no dot) as a string: numbers are taken as floats wherever they stand."""
    if isinstance(x, bool):
        raise ValueError("a boolean is not a number")
    return float(x)


def check_keys(data, node, allowed, path, where):
    for key in data:
        if key not in allowed:
            close = difflib.get_close_matches(str(key), sorted(allowed), n=1)
            hint = f" Did you mean \"{close[0]}\"?" if close else ""
            raise located(child(node, key), path, f"unknown key \"{where}{key}\"; expected one of: "
                                                  f"{', '.join(sorted(allowed))}.{hint}")


def parse(path):
    data, node = compose(path)
    check_keys(data, node, {"study", "ladders", "metrics"}, path, "")
    for key in ("study", "ladders", "metrics"):
        if key not in data or not data[key]:
            raise located(node, path, f"missing or empty \"{key}\".")
    study, snode = data["study"], child(node, "study")
    check_keys(study, snode, {"run", "scene", "set", "time", "post"}, path, "study.")
    for key in ("run", "scene"):
        if key not in study:
            raise located(snode, path, f"study.{key} is required.")
    scene = (path.parent / study["scene"]).resolve()
    if not scene.is_file():
        raise located(child(snode, "scene"), path, f"study.scene = {study['scene']}: no such file ({scene}).")
    ladders = {}
    for name, ladder in data["ladders"].items():
        lnode = child(child(node, "ladders"), name)
        if not isinstance(ladder, dict):
            raise located(lnode, path, f"ladders.{name}: expected a map with key (or keys), values, expected_order.")
        check_keys(ladder, lnode, {"key", "keys", "values", "parameter", "parameters", "expected_order", "fit_rungs",
                                   "set", "why"}, path, f"ladders.{name}.")
        keys = ladder.get("keys") or ([ladder["key"]] if "key" in ladder else None)
        if not keys:
            raise located(lnode, path, f"ladders.{name}: give key: (one scene key) or keys: [..].")
        values = ladder.get("values")
        if not values:
            raise located(child(lnode, "values") if "values" in ladder else lnode, path,
                          f"ladders.{name}.values: the ladder is empty; give at least two rungs.")
        if len(values) < 2:
            raise located(child(lnode, "values"), path, f"ladders.{name}.values: one rung fits no order; give at least two.")
        rungs = [v if isinstance(v, list) else [v] for v in values]
        for r in rungs:
            if len(r) != len(keys):
                raise located(child(lnode, "values"), path,
                              f"ladders.{name}.values: rung {r} has {len(r)} values for {len(keys)} keys.")
        if "expected_order" not in ladder:
            raise located(lnode, path, f"ladders.{name}.expected_order is required (state the order and why in the "
                                       "file's header).")
        parameter = ladder.get("parameter", keys[0])
        try:
            if "parameters" in ladder:  # stated per rung (a cluster level's sphere radius, say)
                params = [number(p) for p in ladder["parameters"]]
                if len(params) != len(rungs):
                    raise ValueError(f"{len(params)} parameters for {len(rungs)} rungs")
            else:
                params = [parameter_value(parameter, keys, r) for r in rungs]
        except (KeyError, ValueError, ZeroDivisionError, TypeError) as e:
            raise located(child(lnode, "parameters" if "parameters" in ladder else "parameter"), path,
                          f"ladders.{name}: the ladder parameter cannot be evaluated: {e}")
        ladders[name] = {"keys": keys, "rungs": rungs, "params": params, "expected": number(ladder["expected_order"]),
                         "fit_rungs": int(ladder.get("fit_rungs", len(rungs))), "set": ladder.get("set", [])}
    metrics = {}
    for name, m in data["metrics"].items():
        mnode = child(child(node, "metrics"), name)
        if not isinstance(m, dict):
            raise located(mnode, path, f"metrics.{name}: expected a map with result: or series:, and reference:.")
        check_keys(m, mnode, {"result", "series", "reference", "summary"}, path, f"metrics.{name}.")
        if ("result" in m) == ("series" in m):
            raise located(mnode, path, f"metrics.{name}: give exactly one of result: (a summary key) or series:.")
        if "series" in m:
            s = m["series"]
            check_keys(s, child(mnode, "series"), {"file", "dataset", "norm", "at"}, path, f"metrics.{name}.series.")
            if s.get("norm", "max") not in ("max", "at", "l2"):
                raise located(child(mnode, "series"), path, f"metrics.{name}.series.norm: max, at or l2.")
            if s.get("norm") == "at" and "at" not in s:
                raise located(child(mnode, "series"), path, f"metrics.{name}.series: norm at needs at: TIME.")
        ref = m.get("reference")
        rnode = child(mnode, "reference")
        if ref in ("finest", "none"):
            pass
        elif isinstance(ref, dict) and len(ref) == 1 and ("result" in ref or "value" in ref):
            if "value" in ref:
                try:
                    number(ref["value"])
                except (TypeError, ValueError):
                    raise located(rnode, path, f"metrics.{name}.reference.value = {ref['value']!r} cannot be "
                                               "evaluated as a number.")
        else:
            raise located(rnode if ref is not None else mnode, path,
                          f"metrics.{name}.reference: {{result: KEY}} (a result the run computes), {{value: X}} (a "
                          "published number), finest (the finest rung) or none (a value to tabulate, such as "
                          "iterations); got " + repr(ref))
        if m.get("series", {}).get("norm") == "l2" and ref != "finest":
            raise located(rnode, path, f"metrics.{name}: an l2 norm over time is taken against the finest rung's "
                                       "series: reference: finest.")
        metrics[name] = m
    return {"path": path, "run": study["run"], "scene": scene, "set": study.get("set", []), "ladders": ladders,
            "metrics": metrics, "time": study.get("time", "wall_time_s"), "post": study.get("post")}


def parameter_value(parameter, keys, rung):
    if parameter.startswith("1/"):
        return 1.0 / number(rung[keys.index(parameter[2:])])
    return number(rung[keys.index(parameter)])


def scene_files(scene, seen=None):
    """The scene and every file it includes (what the cache key must cover)."""
    seen = seen or []
    if scene in seen or not scene.is_file():
        return seen
    seen.append(scene)
    try:
        data = yaml.safe_load(scene.read_text())
    except yaml.YAMLError:
        return seen

    def walk(d, base):
        if isinstance(d, dict):
            for k, v in d.items():
                if k == "include":
                    for f in v if isinstance(v, list) else [v]:
                        scene_files((base / f).resolve(), seen)
                else:
                    walk(v, base)
        elif isinstance(d, list):
            for v in d:
                walk(v, base)

    walk(data, scene.parent)
    return seen


def referenced_files(scene, overrides):
    """Every file a run can read: the scene, what it includes, the files its values name (a coupled
    scene's participant scenes, meshes, cluster files) and the files override values name — each with
    its own includes. Paths resolve against the file that names them, or the scene's folder."""
    found = []

    def visit(path):
        if path in found or not path.is_file():
            return
        found.append(path)
        if path.suffix not in (".yaml", ".yml"):
            return
        try:
            data = yaml.safe_load(path.read_text())
        except yaml.YAMLError:
            return

        def walk(d):
            if isinstance(d, dict):
                for v in d.values():
                    walk(v)
            elif isinstance(d, list):
                for v in d:
                    walk(v)
            elif isinstance(d, str):
                for word in d.replace("=", " ").split():
                    if word.endswith((".yaml", ".yml", ".msh", ".geo")):
                        visit((path.parent / word).resolve())

        walk(data)

    visit(scene)
    for o in overrides:
        value = o.split("=", 1)[-1]
        if value.endswith((".yaml", ".yml", ".msh", ".geo")):
            visit((scene.parent / value).resolve())
            for f in list(found):  # participant scenes resolve their own override paths from their folder
                visit((f.parent / value).resolve())
    return found


def run_key(bin_dir, scene, overrides, post):
    """What a run's result depends on: every executable it can start (a coupled run starts the solvers),
    every file it can read, its overrides and its post-processing script."""
    h = hashlib.sha256()
    for exe in sorted(p for p in bin_dir.iterdir() if p.is_file() and os.access(p, os.X_OK)):
        h.update(exe.name.encode())
        h.update(exe.read_bytes())
    for f in referenced_files(scene, overrides):
        h.update(str(f).encode())
        h.update(f.read_bytes())
    for o in overrides + (post or []):
        h.update(b"\0" + o.encode())
    for word in post or []:
        if word.startswith("tools/"):
            h.update((ROOT / word).read_bytes())
    return h.hexdigest()[:16]


def execute(exe, scene, overrides, folder, concurrent, post=None):
    """Runs one rung into `folder` unless a finished run is there (a summary with exit 0, 2 or 3: a
    coupling failure, exit 4, or a run that left no summary is run again). Returns (summary, cached,
    how it ran: {concurrent, threads})."""
    summary_file = folder / "summary.yaml"
    if summary_file.exists():
        summary = yaml.safe_load(summary_file.read_text())
        if summary and summary.get("exit_code") in (0, 2, 3):
            how = yaml.safe_load((folder / "run.yaml").read_text()) if (folder / "run.yaml").exists() else {}
            return summary, True, how
    tmp = folder.with_suffix(".running")
    subprocess.run(["rm", "-rf", str(tmp)], check=True)
    tmp.mkdir(parents=True)
    cmd = [exe, str(scene), "--out", str(tmp), "--quiet"]
    for o in overrides:
        cmd += ["--set", o]
    env = dict(os.environ, OMP_WAIT_POLICY="passive")
    if concurrent:
        env.setdefault("OMP_NUM_THREADS", "1")
    how = {"concurrent": bool(concurrent), "threads": env.get("OMP_NUM_THREADS", "default")}
    with open(tmp / "console.txt", "w") as console:
        subprocess.run(cmd, stdout=console, stderr=subprocess.STDOUT, env=env)
    if post and (tmp / "summary.yaml").exists():  # e.g. tools/rockfall_report.py adding its results
        words = [str(ROOT / w) if w.startswith("tools/") else w for w in post] + [str(tmp)]
        words = [sys.executable if w == "python3" else w for w in words]
        with open(tmp / "post.txt", "w") as log:
            subprocess.run(words, stdout=log, stderr=subprocess.STDOUT)
    summary = yaml.safe_load((tmp / "summary.yaml").read_text()) if (tmp / "summary.yaml").exists() else None
    (tmp / "command.txt").write_text(" ".join(cmd) + "\n")
    (tmp / "run.yaml").write_text(yaml.safe_dump(how))
    subprocess.run(["rm", "-rf", str(folder)], check=True)  # a failed earlier attempt
    tmp.rename(folder)
    return summary, False, how


def series_value(folder, spec, finest_folder=None):
    import h5py
    path = folder / spec["file"]
    with h5py.File(path, "r") as f:
        dataset = spec["dataset"]
        group = dataset.rsplit("/", 1)[0]
        values = np.asarray(f[dataset][()], dtype=float)
        times = np.asarray(f[group + "/time"][()], dtype=float) if group + "/time" in f else None
    norm = spec.get("norm", "max")
    if norm == "max":
        return float(np.max(np.abs(values)))
    if norm == "at":
        return float(np.interp(number(spec["at"]), times, values))
    # l2 over time of this run's series against the finest rung's, on the finest rung's times
    with h5py.File(finest_folder / spec["file"], "r") as f:
        ref = np.asarray(f[spec["dataset"]][()], dtype=float)
        tref = np.asarray(f[spec["dataset"].rsplit("/", 1)[0] + "/time"][()], dtype=float)
    diff = np.interp(tref, times, values) - ref
    return float(np.sqrt(np.trapz(diff * diff, tref) / np.trapz(ref * ref, tref)))


def result(summary, key):
    """A summary result; KEY[i] takes a component of a vector result (interface_displacement[0])."""
    if key.endswith("]") and "[" in key:
        name, index = key[:-1].split("[")
        return number(summary["results"][name][int(index)])
    return number(summary["results"][key])


def run_time(summary, study):
    """The run time the plot uses: the process's wall_time_s, or a result key such as loop_wall_time_s
    (study.time) when startup would drown a short run."""
    if not summary:
        return None
    if study["time"] == "wall_time_s":
        return summary.get("wall_time_s")
    return (summary.get("results") or {}).get(study["time"])


def fit_order(params, errors, rungs=None):
    """Least-squares slope of log error against log parameter over the finest `rungs` usable rungs (errors
    at round-off, below 1e-14, are left out)."""
    pairs = sorted(((p, e) for p, e in zip(params, errors) if e is not None and e > 1e-14 and p > 0),
                   key=lambda pe: pe[0])
    if rungs:
        pairs = pairs[:rungs]
    if len(pairs) < 2:
        return None
    x = np.log([p for p, _ in pairs])
    y = np.log([e for _, e in pairs])
    return float(np.polyfit(x, y, 1)[0])


def asymptotic_warnings(params, signed, expected):
    """Why an observed order may not mean what it says, from the signed errors over the rungs (coarse to
    fine): a sign change (the error crosses zero: not yet asymptotic, or two error sources cancelling) and
    errors that level off at the fine end (a floor: the model and the reference differ by about it)."""
    pts = sorted(((h, e) for h, e in zip(params, signed) if e is not None and h > 0), key=lambda he: -he[0])
    notes = []
    for (h1, e1), (h2, e2) in zip(pts, pts[1:]):
        if e1 * e2 < 0:
            notes.append(f"the error changes sign between the rungs at {h1:g} ({e1:+.3g}) and {h2:g} ({e2:+.3g}): "
                         "not yet in the asymptotic range, or two errors cancel; the fitted order does not measure "
                         "the convergence")
    if len(pts) >= 3 and expected:
        (h1, e1), (h2, e2) = pts[-2], pts[-1]
        if abs(e2) > 1e-14 and abs(e1) > 0:
            local = math.log(abs(e1) / abs(e2)) / math.log(h1 / h2)
            if local < 0.5 * expected:
                notes.append(f"the error levels off at the finest rungs: order {local:.2f} between {h1:g} and {h2:g} "
                             f"against {expected:g} expected, a floor of about {abs(e2):.3g} (the model and the "
                             "reference differ by that much, or the reference is known no better)")
    return notes


def fit_extrapolated(params, values):
    """Order p and limit v∞ of v(h) = v∞ + C h^p through every rung (least squares over p on a grid, the
    linear v∞, C for each): with the finest rung as the reference, errors |v − v_finest| = C |h^p − h_f^p|
    bend the log-log slope when the rungs are close, this does not. Needs three rungs."""
    pairs = [(h, v) for h, v in zip(params, values) if v is not None and h > 0]
    if len(pairs) < 3:
        return None, None
    h = np.array([p for p, _ in pairs])
    v = np.array([x for _, x in pairs])
    best = (math.inf, None, None)
    for p in np.arange(0.2, 6.0001, 0.005):
        A = np.vstack([np.ones_like(h), h ** p]).T
        coef, *_ = np.linalg.lstsq(A, v, rcond=None)
        sse = float(np.sum((A @ coef - v) ** 2))
        if sse < best[0]:
            best = (sse, float(p), float(coef[0]))
    if best[1] is None or best[1] <= 0.2 + 1e-9 or best[1] >= 6.0 - 1e-9:
        return None, None  # at the search's edge: no power law fits these rungs
    return best[1], best[2]


def pareto(points):
    """Indices of the points no other point beats in both time and error."""
    front = []
    for i, (t, e) in enumerate(points):
        if not any((t2 <= t and e2 <= e) and (t2 < t or e2 < e) for j, (t2, e2) in enumerate(points) if j != i):
            front.append(i)
    return front


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("study", type=Path)
    ap.add_argument("--bin", type=Path, default=ROOT / "build" / "bin", help="folder of the executables")
    ap.add_argument("--out", type=Path, default=None, help="results folder (default results/studies/<study>)")
    ap.add_argument("-j", type=int, default=1, help="runs at once (timings are then flagged as concurrent)")
    ap.add_argument("--quiet", action="store_true")
    a = ap.parse_args(argv)
    try:
        study = parse(a.study.resolve())
    except StudyError as e:
        print(f"[cosim] error: {e}", file=sys.stderr)
        return 2
    out = (a.out or Path("results") / "studies" / a.study.stem).resolve()
    (out / "runs").mkdir(parents=True, exist_ok=True)
    exe = a.bin.resolve() / study["run"]
    if not exe.is_file():
        print(f"[cosim] error: {a.study}: study.run = {study['run']}: no executable {exe}.", file=sys.stderr)
        return 2
    say = (lambda *x: None) if a.quiet else (lambda *x: print(*x, flush=True))

    jobs = []  # (ladder, rung index, overrides)
    for name, ladder in study["ladders"].items():
        for i, rung in enumerate(ladder["rungs"]):
            overrides = list(study["set"]) + list(ladder["set"]) + [f"{k}={v}" for k, v in zip(ladder["keys"], rung)]
            jobs.append((name, i, overrides))
    parallel = a.j > 1
    results = {}
    start = time.monotonic()
    done_seconds = []

    def work(job):
        name, i, overrides = job
        folder = out / "runs" / keys[tuple(overrides)]
        summary, cached, how = execute(str(exe), study["scene"], overrides, folder, parallel, study["post"])
        return job, folder, summary, cached, how

    # The keys first, on one thread: they read every executable and file once per distinct run.
    keys = {tuple(o): run_key(exe.parent, study["scene"], o, study["post"]) for _, _, o in jobs}
    with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, a.j)) as pool:
        futures = [pool.submit(work, j) for j in jobs]
        for n, fut in enumerate(concurrent.futures.as_completed(futures), 1):
            (name, i, overrides), folder, summary, cached, how = fut.result()
            results[(name, i)] = (folder, summary, cached, overrides, how)
            wall = (summary or {}).get("wall_time_s")
            if not cached and wall:
                done_seconds.append(wall)
            left = len(jobs) - n
            eta = left * (sum(done_seconds) / len(done_seconds)) / max(1, a.j) if done_seconds else 0.0
            what = "reused (same binary, scene and overrides)" if cached else (
                f"exit {summary.get('exit_code') if summary else '?'} in {wall:.3g} s" if wall else "no summary")
            say(f"[{n}/{len(jobs)}] {name} rung {i} ({', '.join(overrides[-len(study['ladders'][name]['keys']):])}): "
                f"{what}; ETA {eta:.0f} s")

    rows, failed = [], []
    orders = {}
    for name, ladder in study["ladders"].items():
        finest = min(range(len(ladder["rungs"])), key=lambda i: ladder["params"][i])
        finest_folder, finest_summary = results[(name, finest)][0], results[(name, finest)][1] or {}
        orders[name] = {"expected_order": ladder["expected"], "metrics": {}}
        for metric, m in study["metrics"].items():
            values, errors, signs = [], [], []
            for i in range(len(ladder["rungs"])):
                folder, summary, cached, overrides, how = results[(name, i)]
                value = ref = error = signed = None
                code = summary.get("exit_code") if summary else None
                if code != 0:
                    message = f"{name} rung {i}: exit {code} ({(summary or {}).get('status', 'no summary')})"
                    if message not in failed:
                        failed.append(message)
                else:
                    try:
                        source = summary
                        if m.get("summary"):  # a participant's own summary in a coupled run
                            source = yaml.safe_load((folder / m["summary"] / "summary.yaml").read_text())
                        if "result" in m:
                            value = result(source, m["result"])
                        else:
                            value = series_value(folder / (m.get("summary") or ""), m["series"],
                                                 finest_folder / (m.get("summary") or ""))
                        r = m["reference"]
                        if r == "none":
                            ref = None
                        elif r == "finest":
                            if "series" in m and m["series"].get("norm") == "l2":
                                ref = 0.0
                            else:
                                fs = finest_summary
                                if m.get("summary"):
                                    fs = yaml.safe_load((finest_folder / m["summary"] / "summary.yaml").read_text())
                                ref = (result(fs, m["result"]) if "result" in m
                                       else series_value(finest_folder / (m.get("summary") or ""), m["series"],
                                                         finest_folder / (m.get("summary") or "")))
                        elif "value" in r:
                            ref = number(r["value"])
                        else:
                            ref = result(summary, r["result"])
                        if ref is not None:
                            scale = abs(ref) if ref else 1.0
                            signed = (value - ref) / scale if not (r == "finest" and i == finest) else None
                            error = abs(signed) if signed is not None else None
                    except (KeyError, TypeError, OSError) as e:
                        failed.append(f"{name} rung {i}: metric {metric} cannot be evaluated ({e!r})")
                values.append(value)
                errors.append(error)
                signs.append(signed)
                rows.append({"ladder": name, "rung": i, "parameter": ladder["params"][i],
                             "overrides": " ".join(overrides[-len(ladder["keys"]):]), "metric": metric,
                             "value": value, "reference": ref, "error": error, "signed_error": signed,
                             "wall_time_s": (summary or {}).get("wall_time_s"), "time_s": run_time(summary, study),
                             "exit_code": code,
                             "cached": cached, "concurrent": bool((how or {}).get("concurrent", parallel)),
                             "run": folder.name})
            observed = fit_order(ladder["params"], errors, ladder["fit_rungs"])
            entry = {"observed_order": observed}
            notes = asymptotic_warnings(ladder["params"], signs, ladder["expected"]) if m["reference"] != "finest" else []
            for note in notes:
                print(f"[cosim] warning: {name}/{metric}: {note}", file=sys.stderr)
            if notes:
                entry["warnings"] = notes
            if m["reference"] == "finest":
                # Against the finest rung: v = v∞ + C h^p through the rungs (Richardson), which also
                # estimates the finest rung's own error, |v_finest − v∞| / |v∞|.
                order, limit = (fit_extrapolated(ladder["params"], values) if values[finest] is not None
                                else (None, None))
                entry = {"observed_order": order, "slope_against_finest": observed}
                if order is not None:
                    entry.update({"extrapolated": limit,
                                  "finest_error_estimate": abs(values[finest] - limit) / (abs(limit) or 1.0)})
                else:
                    entry["note"] = "no power law v = v∞ + C h^p fits these rungs (not in the asymptotic range)"
            if m["reference"] == "none":
                entry = {"observed_order": None, "tabulated": True}
            orders[name]["metrics"][metric] = entry
        first = next(m for m in study["metrics"] if study["metrics"][m]["reference"] != "none")
        orders[name]["observed_order"] = orders[name]["metrics"][first]["observed_order"]
        orders[name]["metric"] = first

    columns = ["ladder", "rung", "parameter", "overrides", "metric", "value", "reference", "error", "signed_error", "wall_time_s",
               "time_s", "exit_code", "cached", "concurrent", "run"]
    with open(out / "table.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=columns)
        w.writeheader()
        w.writerows(rows)
    fmt = lambda v: "—" if v is None else (f"{v:.4g}" if isinstance(v, float) else str(v))
    with open(out / "table.md", "w") as f:
        f.write(f"Study `{a.study}`: {study['run']} on `{study['scene'].name}`"
                + (" (timings concurrent)" if parallel else "") + "\n\n")
        # Values to 8 digits and signed errors to 3: a converging ladder shows in the digits that change.
        f.write("| ladder | rung | setting | metric | value | reference | error (value − reference) / |reference| | wall [s] |\n")
        f.write("| --- | --- | --- | --- | --- | --- | --- | --- |\n")
        digits = lambda v, n: "—" if v is None else (f"{v:.{n}g}" if isinstance(v, float) else str(v))
        for r in rows:
            f.write(f"| {r['ladder']} | {r['rung']} | {r['overrides']} | {r['metric']} | {digits(r['value'], 8)} | "
                    f"{digits(r['reference'], 8)} | {digits(r['signed_error'], 3)} | {fmt(r['wall_time_s'])} |\n")
        f.write("\n| ladder | metric | observed order | expected order |\n| --- | --- | --- | --- |\n")
        for name, o in orders.items():
            for metric, e in o["metrics"].items():
                f.write(f"| {name} | {metric} | {fmt(e['observed_order'])} | {fmt(o['expected_order'])} |\n")
        for name, o in orders.items():
            for metric, e in o["metrics"].items():
                for note in e.get("warnings", []):
                    f.write(f"\n**Warning** ({name}, {metric}): {note}\n")
    plot(out, rows, study)
    summary = {"study": str(a.study), "status": "ok" if not failed else "; ".join(failed[:5]),
               "exit_code": 0 if not failed else 3, "wall_time_s": time.monotonic() - start,
               "runs": len(jobs), "reused": sum(1 for v in results.values() if v[2]), "concurrent": parallel,
               "results": {"ladders": orders}}
    with open(out / "summary.yaml", "w") as f:
        yaml.safe_dump(summary, f, sort_keys=False)
    say(f"wrote {out}/table.csv, table.md, error_vs_runtime.png, summary.yaml")
    for name, o in orders.items():
        say(f"  {name}: observed order {fmt(o['observed_order'])} ({o['metric']}), expected {fmt(o['expected_order'])}")
    for line in failed:
        print(f"[cosim] error: {line}", file=sys.stderr)
    return 0 if not failed else 3


def plot(out, rows, study):
    """Error against run time, one curve per ladder and metric in ladder order (coarse to fine), each
    curve's Pareto-optimal rungs ringed (no other rung of it is both faster and more accurate)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7, 5))
    ringed = False
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    styles = ["o-", "s--", "^:", "d-.", "v-", "P--"]
    for li, name in enumerate(study["ladders"]):
        for mi, metric in enumerate(study["metrics"]):
            pts = [(r["time_s"], r["error"], r["parameter"]) for r in rows
                   if r["ladder"] == name and r["metric"] == metric and r["error"] and r["time_s"]]
            if not pts:
                continue
            pts.sort(key=lambda p: -p[2])
            # Colour per ladder, line style per metric: the curves stay apart however many there are.
            ax.loglog([p[0] for p in pts], [p[1] for p in pts], styles[mi % len(styles)],
                      color=colours[li % len(colours)], label=f"{name}: {metric}")
            front = pareto([(p[0], p[1]) for p in pts])
            ax.loglog([pts[i][0] for i in front], [pts[i][1] for i in front], "o", ms=11, mfc="none",
                      mec="k", label=None if ringed else "Pareto-optimal rung")
            ringed = True
    ax.set_xlabel(f"{study['time']} [s]")
    ax.set_ylabel("relative error")
    ax.set_title(f"{study['path'].stem}: error against run time")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "error_vs_runtime.png", dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    sys.exit(main())
