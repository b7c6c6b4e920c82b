# The README's commands. Everything a fresh Debian machine needs is installed by `make deps`.
#   make demo    run the most complete scene that exists (at the end: the rockfall scene)
#   make test    install what is missing, build, run the test suite (ctest)
#   make build   build every executable into build/bin/
#   make bench   build with benchmarks in build-bench/ and run them (not part of make test)
#   make stability  the whole stability suite, long cases included (build/stability/stability.csv)
#   make faults     the whole fault-injection matrix (build/faults/faults.csv, table in docs/reliability.md)
#   make fuzz       libFuzzer targets (clang) in build-fuzz/, FUZZ_SECONDS each (findings: build-fuzz/findings/)
#   make test-sanitize  the test suite built with AddressSanitizer + UndefinedBehaviorSanitizer (but SANITIZE_SKIP)
#   make adapters   install YADE and FEniCSx, run their adapters' tests, rockfall c1 with both DEM codes and the
#                   plate impact with both FEM codes (adapters/)

BUILD_DIR ?= build
BENCH_DIR ?= build-bench
FUZZ_DIR  ?= build-fuzz
SAN_DIR   ?= build-sanitize
FUZZ_SECONDS ?= 60
JOBS      ?= 2
PYTHON    ?= /usr/bin/python3
CMAKE_FLAGS ?=
STABILITY_ARGS ?=

DEB_PACKAGES := cmake g++ make pkg-config \
  libeigen3-dev libzmq3-dev cppzmq-dev libhdf5-dev libgmsh-dev gmsh python3-gmsh libyaml-cpp-dev libcli11-dev \
  libspdlog-dev libfmt-dev libgtest-dev libgmock-dev libbenchmark-dev libopenmpi-dev openmpi-bin \
  python3 python3-h5py python3-matplotlib python3-numpy python3-zmq python3-yaml

# Only `make fuzz` needs these (libFuzzer comes with clang).
FUZZ_PACKAGES := clang

# Only `make bench` needs these: the peer codes it compares against and GNU time for peak memory.
BENCH_PACKAGES := time liggghts yade openmpi-bin

# Only `make adapters` needs these: the external codes that replace a solver.
ADAPTER_PACKAGES := yade python3-dolfinx python3-scipy
ADAPTERS_DIR ?= results/adapters

.PHONY: deps bench-deps build test demo bench stability faults triaxial bridging fuzz test-sanitize adapters clean

deps:
	@missing=""; \
	for p in $(DEB_PACKAGES); do \
	  dpkg-query -W -f='$${Status}' $$p 2>/dev/null | grep -q "install ok installed" || missing="$$missing $$p"; \
	done; \
	if [ -z "$$missing" ]; then echo "deps: all Debian packages present"; exit 0; fi; \
	if [ "$$(id -u)" = 0 ]; then \
	  echo "deps: installing$$missing"; \
	  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $$missing; \
	else \
	  echo "deps: missing Debian packages. Run as root:"; \
	  echo "  sudo apt-get install -y$$missing"; \
	  exit 1; \
	fi

bench-deps:
	@$(MAKE) --no-print-directory deps DEB_PACKAGES="$(BENCH_PACKAGES)"

$(BUILD_DIR)/CMakeCache.txt:
	cmake -S . -B $(BUILD_DIR) -DCMAKE_BUILD_TYPE=Release -DCOSIM_ENABLE_ASSERTS=ON $(CMAKE_FLAGS)

build: deps $(BUILD_DIR)/CMakeCache.txt
	cmake --build $(BUILD_DIR) -j$(JOBS)

test: build
	cd $(BUILD_DIR) && ctest --output-on-failure --no-label-summary -j$(JOBS)

stability: build
	$(PYTHON) tools/stability_suite.py $(BUILD_DIR) $(BUILD_DIR)/stability $(STABILITY_ARGS)

# The triaxial tests of docs/validation/triaxial.md: 100, 200, 300 kPa and 100 kPa without bonds, two at a
# time on one thread each (about 3 min on two cores), then the plots.
TRIAXIAL_DIR ?= results/triaxial
triaxial: build
	@mkdir -p $(TRIAXIAL_DIR)
	OMP_NUM_THREADS=1 $(BUILD_DIR)/bin/dem_solver configs/dem/triaxial.yaml --quiet --out $(TRIAXIAL_DIR)/100 & \
	OMP_NUM_THREADS=1 $(BUILD_DIR)/bin/dem_solver configs/dem/triaxial_200kPa.yaml --quiet --out $(TRIAXIAL_DIR)/200; \
	wait
	OMP_NUM_THREADS=1 $(BUILD_DIR)/bin/dem_solver configs/dem/triaxial_300kPa.yaml --quiet --out $(TRIAXIAL_DIR)/300 & \
	OMP_NUM_THREADS=1 $(BUILD_DIR)/bin/dem_solver configs/dem/triaxial.yaml --quiet --out $(TRIAXIAL_DIR)/100_no_bonds \
	  --set interactions[0].tensile_strength=0 --set interactions[0].cohesion=0; \
	wait
	$(PYTHON) tools/triaxial_plot.py $(TRIAXIAL_DIR)/100 $(TRIAXIAL_DIR)/200 $(TRIAXIAL_DIR)/300 \
	  --out $(TRIAXIAL_DIR)/triaxial_q_ev.png --network $(TRIAXIAL_DIR)/triaxial_network_peak.png
	PYTHON=$(PYTHON) tools/triaxial_variants.sh $(BUILD_DIR) $(TRIAXIAL_DIR)/variants

# The bridging domain's wave study of docs/validation/bridging.md: the overlap narrowed, the truss coarsened
# (seven runs of a few seconds), the slab against the slab as spheres throughout (three pairs timed in
# turn, about a minute), their tables and plots.
BRIDGING_DIR ?= results/bridging
bridging: build
	$(PYTHON) tools/bridging_study.py $(BUILD_DIR) $(BRIDGING_DIR) --pairs 3

faults: build
	$(PYTHON) tests/integration/faults/fault_suite.py $(BUILD_DIR) $(BUILD_DIR)/faults --markdown $(BUILD_DIR)/faults/table.md

fuzz: deps
	@$(MAKE) --no-print-directory deps DEB_PACKAGES="$(FUZZ_PACKAGES)"
	CC=clang CXX=clang++ cmake -S . -B $(FUZZ_DIR) -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCOSIM_FUZZ=ON \
	  -DCOSIM_SANITIZE=address,undefined -DCOSIM_BUILD_TESTS=OFF $(CMAKE_FLAGS)
	cmake --build $(FUZZ_DIR) -j$(JOBS) --target fuzz_protocol fuzz_scene_dem fuzz_msh fuzz_cluster fuzz_scene_lattice
	@mkdir -p $(FUZZ_DIR)/findings
	@for t in protocol scene_dem msh cluster scene_lattice; do \
	  mkdir -p $(FUZZ_DIR)/corpus/$$t && cp -n tests/fuzz/corpus/$$t/* $(FUZZ_DIR)/corpus/$$t/ ; \
	  echo "== fuzz_$$t for $(FUZZ_SECONDS) s"; \
	  (cd $(FUZZ_DIR)/findings && ASAN_OPTIONS=detect_leaks=0 ../bin/fuzz_$$t -max_total_time=$(FUZZ_SECONDS) \
	    -timeout=20 -rss_limit_mb=4096 -max_len=8192 ../corpus/$$t) || exit 1; \
	done

# Left out of `make test-sanitize` (make test runs them unsanitized): the runs that take 2 to 14 min each under
# the sanitizers and whose code smaller sanitized tests run too (CONTRIBUTING.md, "Tests").
# - StabilitySuite: 38 full runs; the DemStability cases stay in.
# - Restart.KilledCoupledRunRestartsBitForBit (14 min): the checkpoints of every solver and of the window loop
#   are sanitized by DemCheckpoint.*, FemCheckpoint.*, lattice.LatticeCheckpoint.*, RunLoop.* and WindowLoop.*,
#   `cosim run --restart` by Bridging.PulseCrossesTheOverlap and StateArchive.*.
# - Rockfall.WeakCouplingThatCreatesEnergyEndsWithExit3 (6 min): the same rockfall scene and the same exit 3
#   as Rockfall.LooseToleranceThatCreatesInterfaceEnergyEndsWithExit3 and SplitBar.DivergingCouplingIteration*.
# - Guide.EveryCommandRuns (4 min) and Guide.EverySceneKeyIsDocumented (2 min): they test the documentation
#   against the executables, on scenes that the scenes' own tests and the scene fuzz targets run.
# - lattice.LatticePrism.CrackLocalisesAndTheCurveSoftens (3 min): the prism of ElasticStiffnessMatches*,
#   cracking as in lattice.VolumeSpecimen.NotchedPrismCrackStartsAtTheNotch.
# Measured on 2 cores (2026-12-06): the whole suite 2,318 s sanitized; these runs 1,757 s of its 4,202 s of tests.
SANITIZE_SKIP := StabilitySuite|Restart\.KilledCoupledRunRestartsBitForBit|Rockfall\.WeakCouplingThatCreatesEnergy|$\
  Guide\.EveryCommandRuns|Guide\.EverySceneKeyIsDocumented|LatticePrism\.CrackLocalises

test-sanitize: deps
	cmake -S . -B $(SAN_DIR) -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCOSIM_SANITIZE=address,undefined \
	  -DCOSIM_ENABLE_ASSERTS=ON $(CMAKE_FLAGS)
	cmake --build $(SAN_DIR) -j$(JOBS)
	cd $(SAN_DIR) && ASAN_OPTIONS=detect_leaks=0:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1 \
	  ctest --output-on-failure --no-label-summary -j$(JOBS) -LE long -E '$(SANITIZE_SKIP)' --timeout 1800

# The external codes' adapters (adapters/): their tests (skipped, with the reason, where yade or dolfinx is
# missing), then rockfall c1 with dem_solver and with YADE, variant by variant, and the plate impact with
# fem_solver and with FEniCSx (docs/validation/external_codes.md; about 12 min).
adapters: build
	@$(MAKE) --no-print-directory deps DEB_PACKAGES="$(ADAPTER_PACKAGES)"
	cmake -S . -B $(BUILD_DIR)
	cd $(BUILD_DIR) && ctest --output-on-failure --no-label-summary -L adapters
	$(PYTHON) adapters/yade/compare.py $(BUILD_DIR) $(ADAPTERS_DIR)
	$(PYTHON) adapters/fenicsx/compare_slab.py $(BUILD_DIR) $(ADAPTERS_DIR)/slab

demo: build
	@./tools/demo.sh $(BUILD_DIR)

bench: deps bench-deps
	cmake -S . -B $(BENCH_DIR) -DCMAKE_BUILD_TYPE=Release -DCOSIM_BUILD_BENCH=ON -DCOSIM_BUILD_TESTS=OFF $(CMAKE_FLAGS)
	cmake --build $(BENCH_DIR) -j$(JOBS)
	@./tools/bench.sh $(BENCH_DIR)

clean:
	rm -rf $(BUILD_DIR) $(BENCH_DIR)
