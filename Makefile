# stiffcomp: the two commands a newcomer needs are `make install` and `make test`.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: install test test-fast node-deps mbpoll run walk bench bench-service lint clean demo image image-test egm-proto

install: $(STAMP)

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e ".[test]"
	$(PY) -m service.kernel.warm
	touch $(STAMP)

# BLAS one thread per process: the suite runs fits beside services on two cores, where OpenBLAS's threads
# only contend (the CPU-bound tests ran 4.8 x faster so, one loaded run each); subprocesses inherit it.
# The tests on two pytest workers (pytest-xdist), each taking whole files so a file's fixtures are built once;
# then, in one process, the HIL's (its virtual robot follows the wall clock, and its real-time passes beside
# another worker failed under load) and those marked serial (docs/contributing.md). Both halves run; either
# failing fails. WORKERS=0 runs the first half in one process too.
WORKERS ?= 2
PYTEST  := OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 $(PY) -m pytest -q
test: $(STAMP) node-deps mbpoll
	$(VENV)/bin/lint-imports
	$(PYTEST) -n $(WORKERS) --dist loadfile -m "not (hil or serial)"; first=$$?; \
	$(PYTEST) -m "hil or serial"; second=$$?; [ $$first -eq 0 ] && [ $$second -eq 0 ]

# The quick lane for everyday work: every package's unit tests, without the tests that run the service or
# the HIL in real time, compile cycles or run whole discovery loops (pytest markers, docs/contributing.md)
test-fast: $(STAMP)
	$(VENV)/bin/lint-imports
	$(PYTEST) -m "not (realtime or hil or container or slow)"

# ads-client (Node.js) for tests/plc_link/test_ads_node.py, from the committed lock file, into a
# folder git ignores. Without npm nothing is installed and that test is skipped (one line in pytest's summary).
NODE_CHECK := tests/plc_link/node
node-deps: $(NODE_CHECK)/node_modules/.package-lock.json
$(NODE_CHECK)/node_modules/.package-lock.json: $(NODE_CHECK)/package-lock.json
	@if command -v npm >/dev/null 2>&1; then npm ci --prefix $(NODE_CHECK) --no-audit --no-fund --loglevel=error; fi

# mbpoll (libmodbus) for tests/plc_link/test_modbus_security.py, the Debian package, when this runs as root
# with apt-get. Otherwise nothing is installed and that test is skipped (one line in pytest's summary).
mbpoll:
	@command -v mbpoll >/dev/null 2>&1 || { [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1 && \
		{ DEBIAN_FRONTEND=noninteractive apt-get install -y -qq mbpoll >/dev/null 2>&1 || \
		  { apt-get update -qq >/dev/null 2>&1 && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq mbpoll >/dev/null 2>&1; }; }; } || true

run: $(STAMP)
	$(VENV)/bin/stiffcomp run

# The discovery walk of the README on the shipped example campaign; reports land in out/.
WALK_DATA := examples/campaign_backlash.csv
SC := $(VENV)/bin/stiffcomp
walk: $(STAMP)
	mkdir -p out
	$(SC) fit config/models/kr125_6dof.yaml $(WALK_DATA) -o out/6dof.yaml
	$(SC) compare out/6dof.yaml $(WALK_DATA) --report out/compare_before
	$(SC) diagnose out/6dof.yaml $(WALK_DATA) --report out/diagnose
	$(SC) model add out/6dof.yaml backlash --joint 3 -o out/6dof_backlash.yaml
	$(SC) fit out/6dof_backlash.yaml $(WALK_DATA) -o out/6dof_backlash_fitted.yaml
	$(SC) compare out/6dof.yaml out/6dof_backlash_fitted.yaml $(WALK_DATA) --report out/compare

# One table: cycle work, model speed, fit and diagnose, Modbus and ADS round trips (medians, percentiles)
bench: $(STAMP)
	$(PY) benchmarks/bench_all.py

# 60 s of the service as make run starts it, 4 Modbus clients at 500 Hz and 8 pyads clients, beside a C loop
bench-service: $(STAMP)
	$(PY) benchmarks/bench_cycle.py --duration 60

# The paper's circle (Fig. 8) milled in the loop: service, virtual sensor and virtual PLC as separate
# processes, without then with compensation; prints both path errors, writes out/hil/hil_circle.png.
demo: $(STAMP)
	$(SC) hil circle --report out/hil

# The container (docs/deploy.md). BASE: any image with python3 >= 3.11 and venv, e.g. a local base
# made from Debian packages where no registry is reachable. CA_CERTS_DIR: site CA certificates (*.crt)
# the build needs to reach the package index; PIP_INDEX_URL etc. are taken from the environment.
# `make image` remembers what it was given in IMAGE_ARGS (git ignores it), so that `make image-test`,
# which builds first, builds the same image without them; a value on the command line still wins.
IMAGE_ARGS ?= deploy/.image-args.mk
-include $(IMAGE_ARGS)
IMAGE        ?= stiffcomp
BASE         ?= python:3.11-slim
CA_CERTS_DIR ?=
DOCKER_BUILD_ARGS ?=
image:
	rm -f deploy/ca-certificates/*.crt
	$(if $(CA_CERTS_DIR),cp $(CA_CERTS_DIR)/*.crt deploy/ca-certificates/)
	docker build --network=host --build-arg BASE=$(BASE) --build-arg PIP_INDEX_URL \
		--build-arg PIP_EXTRA_INDEX_URL --build-arg PIP_TRUSTED_HOST $(DOCKER_BUILD_ARGS) -t $(IMAGE) .
	printf '%s\n' 'IMAGE ?= $(IMAGE)' 'BASE ?= $(BASE)' 'CA_CERTS_DIR ?= $(CA_CERTS_DIR)' \
		'DOCKER_BUILD_ARGS ?= $(DOCKER_BUILD_ARGS)' > $(IMAGE_ARGS)

# Build (as the last `make image`), start, wait for healthy, read the cycle counter over Modbus and ADS,
# scrape the metrics, stop with SIGTERM and expect exit code 0, the compiled cycle as fast as on this
# host; one line per check.
image-test: image $(STAMP)
	$(PY) deploy/image_test.py --image $(IMAGE)

# The ABB EGM packets' Python code from robot_road/egm.proto, by grpcio-tools' protoc (test extras);
# the protobuf floor in pyproject.toml is the runtime the file demands (tests/robot_road/test_egm.py checks both)
egm-proto: $(STAMP)
	$(PY) -m grpc_tools.protoc -Irobot_road --python_out=robot_road robot_road/egm.proto

lint: $(STAMP)
	$(VENV)/bin/ruff check .

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache out $(NODE_CHECK)/node_modules
