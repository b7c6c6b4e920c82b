# The README's commands. Everything a fresh Debian machine needs is installed by `make deps`.
#   make demo    run the most complete scene that exists (at the end: the rockfall scene)
#   make test    install what is missing, build, run the test suite (ctest)
#   make build   build every executable into build/bin/
#   make bench   build with benchmarks in build-bench/ and run them (not part of make test)
#   make stability  the whole stability suite, long cases included (build/stability/stability.csv)
#   make faults     the whole fault-injection matrix (build/faults/faults.csv, table in docs/reliability.md)

BUILD_DIR ?= build
BENCH_DIR ?= build-bench
JOBS      ?= 2
PYTHON    ?= /usr/bin/python3
CMAKE_FLAGS ?=

DEB_PACKAGES := cmake g++ make pkg-config \
  libeigen3-dev libzmq3-dev cppzmq-dev libhdf5-dev libgmsh-dev gmsh python3-gmsh libyaml-cpp-dev libcli11-dev \
  libspdlog-dev libfmt-dev libgtest-dev libgmock-dev libbenchmark-dev \
  python3 python3-h5py python3-matplotlib python3-numpy python3-zmq python3-yaml

# Only `make bench` needs these: the peer codes it compares against and GNU time for peak memory.
BENCH_PACKAGES := time liggghts yade openmpi-bin

.PHONY: deps bench-deps build test demo bench stability faults clean

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
	$(PYTHON) tools/stability_suite.py $(BUILD_DIR) $(BUILD_DIR)/stability

faults: build
	$(PYTHON) tests/integration/faults/fault_suite.py $(BUILD_DIR) $(BUILD_DIR)/faults --markdown $(BUILD_DIR)/faults/table.md

demo: build
	@./tools/demo.sh $(BUILD_DIR)

bench: deps bench-deps
	cmake -S . -B $(BENCH_DIR) -DCMAKE_BUILD_TYPE=Release -DCOSIM_BUILD_BENCH=ON -DCOSIM_BUILD_TESTS=OFF $(CMAKE_FLAGS)
	cmake --build $(BENCH_DIR) -j$(JOBS)
	@./tools/bench.sh $(BENCH_DIR)

clean:
	rm -rf $(BUILD_DIR) $(BENCH_DIR)
