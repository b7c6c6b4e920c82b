"""Every registered name is a complete unit: for each registry (contact laws, element types, rod laws,
lattice solvers, mappings, accelerations, coupling schemes), each name the executables accept has its file
(FOLDER/NAME.cpp, the name a scene gives being the file's), its line in its part's CMakeLists.txt, its row
named in its README, a test that names it, and the README's "Adding …" list names the CMake step. The names come
from the executables themselves: given an unknown name, each lists the registered ones ("expected one
of: …"), so this test pins no list and a new unit needs no change here.
Run: python3 test_registries.py SOURCE_DIR BIN_DIR"""
import re
import subprocess
import sys
from pathlib import Path

source, bin_dir = Path(sys.argv[1]), Path(sys.argv[2])
VERIFY = "configs/verification/split_bar_static.yaml"
# What the scene key chooses, the command that reads it, the unit's folder, its part's CMakeLists.txt and
# README, and the README's heading of the list of what adding one takes.
REGISTRIES = [
    ("contact law", ["dem_solver", "configs/dem/pour.yaml", "--check"], "interactions[0].law",
     "dem_solver/src/contact", "dem_solver/CMakeLists.txt", "dem_solver/README.md", "## Adding a contact law"),
    ("element type", ["fem_solver", "configs/fem/bar_wave.yaml", "--check"], "elements[0].type",
     "fem_solver/src/elements", "fem_solver/CMakeLists.txt", "fem_solver/README.md", "## Adding an element type"),
    ("rod law", ["lattice_solver", "configs/lattice/tension_5cm.yaml", "--check"], "rod.law",
     "lattice_solver/src/rod_laws", "lattice_solver/CMakeLists.txt", "lattice_solver/README.md",
     "### Adding a rod law or a solver"),
    ("lattice solver", ["lattice_solver", "configs/lattice/tension_5cm.yaml", "--check"], "solver.type",
     "lattice_solver/src/solvers", "lattice_solver/CMakeLists.txt", "lattice_solver/README.md",
     "### Adding a rod law or a solver"),
    ("mapping", ["cosim", "check", VERIFY], "exchanges[0].mapping", "coupler/mapping/src",
     "coupler/CMakeLists.txt", "coupler/README.md", "### Adding a mapping or an acceleration"),
    ("acceleration", ["cosim", "check", VERIFY], "coupling.acceleration.type", "coupler/acceleration/src",
     "coupler/CMakeLists.txt", "coupler/README.md", "### Adding a mapping or an acceleration"),
    ("coupling scheme", ["cosim", "check", VERIFY], "coupling.scheme", "coupler/cosim/schemes",
     "coupler/CMakeLists.txt", "coupler/README.md", "Adding a scheme:"),
]
tests = {p: p.read_text(errors="replace") for p in (source / "tests").rglob("*")
         if p.is_file() and p.suffix in (".cpp", ".py", ".yaml", ".txt")}
failures = []
for label, command, key, folder, cmake, readme, adding in REGISTRIES:
    program, *args = command
    r = subprocess.run([str(bin_dir / program), *args, "--set", f"{key}=no_such_name"], cwd=source,
                       capture_output=True, text=True, timeout=120)
    listed = re.search(r"expected one of: ([a-z0-9_, ]+)", r.stdout + r.stderr)
    if r.returncode != 2 or not listed:
        failures.append(f"{label}: `{' '.join(command)} --set {key}=no_such_name` does not list the registered names "
                        f"(exit {r.returncode}): {(r.stdout + r.stderr)[-300:]}")
        continue
    names = [n.strip() for n in listed.group(1).split(",")]
    readme_text = (source / readme).read_text()
    cmake_text = (source / cmake).read_text()
    # The list of what adding one takes, up to the next heading: it must name the CMake step.
    steps = readme_text[readme_text.index(adding):] if adding in readme_text else ""
    steps = steps[:steps.find("\n#", 1)] if "\n#" in steps[1:] else steps
    if "CMakeLists.txt" not in steps:
        failures.append(f"{label}: {readme} \"{adding}\" does not name the CMakeLists.txt step")
    for name in names:
        unit = source / folder / f"{name}.cpp"
        if not unit.is_file():
            failures.append(f"{label} {name}: no file {folder}/{name}.cpp (the scene's name is the file's)")
        if not re.search(rf"(?<![\w.]){re.escape(name)}\.cpp\b", cmake_text):
            failures.append(f"{label} {name}: {cmake} does not list {name}.cpp")
        if not re.search(rf"\b{re.escape(name)}\b", readme_text):
            failures.append(f"{label} {name}: {readme} does not name it")
        if not any(re.search(rf"\b{re.escape(name)}\b", text) for text in tests.values()):
            failures.append(f"{label} {name}: no test under tests/ names it")
    print(f"{label}: {', '.join(names)}")
if failures:
    print("\n".join(failures))
    sys.exit(1)
print("ok: every registered name has its file, CMake line, README row and test")
