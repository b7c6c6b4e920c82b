"""tools/study.py: the order fit on synthetic data of known order, the Pareto front, and located errors
for bad study files. Run: python3 test_study.py PATH/TO/tools/study.py"""
import importlib.util
import sys
import tempfile
from pathlib import Path

import numpy as np

spec = importlib.util.spec_from_file_location("study", sys.argv[1])
study = importlib.util.module_from_spec(spec)
spec.loader.exec_module(study)
failures = []


def check(cond, what):
    if not cond:
        failures.append(what)


# Order fit: e = C h^p (1 + 2 % noise) over five halvings recovers p = 1, 2, 4 within 0.1; round-off
# errors (below 1e-14) are left out of the fit; fit_rungs takes the finest rungs only.
rng = np.random.default_rng(7)
h = [0.1 / 2 ** k for k in range(5)]
for p in (1, 2, 4):
    e = [3.0 * x ** p * (1 + 0.02 * rng.standard_normal()) for x in h]
    got = study.fit_order(h, e)
    check(abs(got - p) < 0.1, f"order {p}: fitted {got}")
check(abs(study.fit_order(h, [x ** 2 for x in h[:3]] + [1e-16, 0.0]) - 2) < 1e-9, "round-off rungs not left out")
mixed = [x ** 1 if x > 0.02 else x ** 2 * 10 for x in h]  # order 2 only in the two finest rungs
check(abs(study.fit_order(h, mixed, 2) - 2) < 1e-9, "fit_rungs does not take the finest rungs")
check(study.fit_order([0.1], [0.01]) is None, "one rung gave an order")

# The warnings on an order that does not measure convergence: a clean order-2 ladder gets none; errors
# that change sign get one naming both rungs; errors that level off at 2.3e-4 (a model floor, as a clamped
# membrane against Hencky's value) get one with the floor's size.
check(study.asymptotic_warnings(h, [3 * x ** 2 for x in h], 2) == [], "a clean order-2 ladder was warned about")
crossing = study.asymptotic_warnings(h, [-2e-3, 4e-4, 1e-4, 2.5e-5, 6e-6], 2)
check(len(crossing) == 1 and "changes sign" in crossing[0] and "0.1 (-0.002)" in crossing[0]
      and "0.05 (+0.0004)" in crossing[0], f"sign change: {crossing}")
floor = study.asymptotic_warnings(h, [4e-3, 1.2e-3, 4e-4, 2.4e-4, 2.3e-4], 2)
check(len(floor) == 1 and "levels off" in floor[0] and "0.00023" in floor[0], f"floor: {floor}")

# Against the finest rung: v = 1 + 0.5 h^p through four rungs (h ratio 1.33 at the fine end, where the
# slope of |v − v_finest| bends) gives p back, and the limit 1.
for p in (1, 2):
    hs = [0.004, 0.003, 0.002, 0.0015]
    order, limit = study.fit_extrapolated(hs, [1 + 0.5 * x ** p for x in hs])
    check(abs(order - p) < 0.01 and abs(limit - 1) < 1e-9, f"extrapolated order {order}, limit {limit} for p = {p}")

# Pareto front: (time, error) points no other point beats in both.
pts = [(1, 1e-2), (2, 1e-3), (3, 5e-3), (4, 1e-4), (5, 1e-4)]
check(study.pareto(pts) == [0, 1, 3], f"pareto {study.pareto(pts)}")

# Bad study files: located errors (file:line:column, key, what to do).
scene = "materials: {}\n"
cases = {
    "unknown key": ("study: {run: dem_solver, scene: s.yaml}\nladders: {dt: {key: dt, values: [1, 2], expected_order: 2, "
                    "expectd: 1}}\nmetrics: {m: {result: x, reference: finest}}\n", ["unknown key \"ladders.dt.expectd\"",
                                                                                      ":2:"]),
    "empty ladder": ("study: {run: dem_solver, scene: s.yaml}\nladders:\n  dt: {key: dt, values: [], expected_order: 2}\n"
                     "metrics: {m: {result: x, reference: finest}}\n", ["ladders.dt.values: the ladder is empty", ":3:"]),
    "bad reference": ("study: {run: dem_solver, scene: s.yaml}\nladders: {dt: {key: dt, values: [1, 2], expected_order: 2}}\n"
                      "metrics:\n  m: {result: x, reference: {value: abc}}\n", ["reference.value = 'abc' cannot be evaluated",
                                                                              ":4:"]),
    "no order": ("study: {run: dem_solver, scene: s.yaml}\nladders: {dt: {key: dt, values: [1, 2]}}\n"
                 "metrics: {m: {result: x, reference: finest}}\n", ["ladders.dt.expected_order is required"]),
    "missing scene": ("study: {run: dem_solver, scene: nowhere.yaml}\nladders: {dt: {key: dt, values: [1, 2], "
                      "expected_order: 2}}\nmetrics: {m: {result: x, reference: finest}}\n", ["no such file"]),
}
with tempfile.TemporaryDirectory() as d:
    (Path(d) / "s.yaml").write_text(scene)
    for name, (text, needles) in cases.items():
        f = Path(d) / f"{name.replace(' ', '_')}.yaml"
        f.write_text(text)
        try:
            study.parse(f)
            failures.append(f"{name}: no error")
        except study.StudyError as e:
            for n in needles:
                check(n in str(e), f"{name}: {n!r} not in {e}")
        code = study.main([str(f), "--bin", d, "--out", str(Path(d) / "out"), "--quiet"])
        check(code == 2, f"{name}: exit {code}, expected 2")

if failures:
    print("\n".join(failures))
    sys.exit(1)
print("ok")
