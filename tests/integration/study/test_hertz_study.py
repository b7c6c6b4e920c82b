"""`cosim study configs/studies/hertz_dt.yaml`: the four outputs, the observed order of every metric
within 0.3 of the expected 2, and the cache: a second call reuses every run and starts none.
Run: python3 test_hertz_study.py BUILD/bin/cosim SOURCE_DIR OUT"""
import csv
import subprocess
import sys
from pathlib import Path

import yaml

cosim, source, out = sys.argv[1], Path(sys.argv[2]), Path(sys.argv[3])
study = source / "configs" / "studies" / "hertz_dt.yaml"
failures = []


def run():
    r = subprocess.run([cosim, "study", str(study), "--out", str(out), "--quiet"], capture_output=True, text=True)
    if r.returncode != 0:
        failures.append(f"exit {r.returncode}: {r.stderr}")
    return yaml.safe_load((out / "summary.yaml").read_text())


subprocess.run(["rm", "-rf", str(out)], check=True)
first = run()
for name in ("table.csv", "table.md", "error_vs_runtime.png", "summary.yaml"):
    if not (out / name).is_file() or (out / name).stat().st_size == 0:
        failures.append(f"{name} missing")
ladder = first["results"]["ladders"]["dt"]
if ladder["expected_order"] != 2:
    failures.append(f"expected_order {ladder['expected_order']}")
for metric, m in ladder["metrics"].items():
    if not abs(m["observed_order"] - 2) <= 0.3:
        failures.append(f"{metric}: observed order {m['observed_order']}, expected 2 ± 0.3")
rows = list(csv.DictReader(open(out / "table.csv")))
for column in ("ladder", "rung", "value", "wall_time_s", "metric", "error"):
    if column not in rows[0]:
        failures.append(f"table.csv has no column {column}")
if first["reused"] != 0:
    failures.append(f"first call reused {first['reused']} runs")
runs_before = sorted(p.name for p in (out / "runs").iterdir())
second = run()
if second["reused"] != second["runs"] or second["runs"] != 5:
    failures.append(f"second call reused {second['reused']} of {second['runs']} runs")
if sorted(p.name for p in (out / "runs").iterdir()) != runs_before:
    failures.append("the second call made new run folders")
if any(r["cached"] != "True" for r in csv.DictReader(open(out / "table.csv"))):
    failures.append("table.csv of the second call has uncached rows")
if failures:
    print("\n".join(failures))
    sys.exit(1)
print("ok")
