# Two entry points for a fresh machine with Python >= 3.11 and pip (see README.md):
#   make demo   installs the project (no test tools) into .venv, normalises and packs the seed head, validates
#               assets (demo-out/validate.html), drives the Boe-Bot around the box and writes demo-out/demo.gif
#   make test   also installs the test extras, then runs lint, type checks and the test suite (in parallel)
# Both run scripts/install_gl.sh (apt-get: Mesa EGL/OSMesa) and make test scripts/install_test_tools.sh (npm into
# tools/, apt-get: chromium); SYSTEM=0 (or MESHTOOL_NO_SYSTEM=1) skips every system install and says what it skipped.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
TEST_STAMP := $(VENV)/.installed-test
PEERS  := .bench-peers
SYSTEM ?= 1
ifeq ($(SYSTEM),0)
export MESHTOOL_NO_SYSTEM := 1
endif
# pytest workers: one per core (pytest-xdist); TEST_JOBS=0 runs the suite in one process
TEST_JOBS ?= auto

.PHONY: install demo test lint bench bench-batch bench-hulls bench-usd bench-mjcf corpus fuzz clean mutants

# setuptools says "Editable installation ... be careful with folders in your working directory" on every
# editable install (a note, not a problem here): hidden, every other warning still shows.
PIP := PYTHONWARNINGS="ignore:Editable installation" $(BIN)/python -m pip

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PIP) install --quiet --upgrade pip
	$(PIP) install --quiet -e .
	touch $(STAMP)

$(TEST_STAMP): $(STAMP)
	$(PIP) install --quiet -e ".[test]"
	touch $(TEST_STAMP)

install: $(STAMP)

demo: $(STAMP)
	bash scripts/install_gl.sh
	rm -rf out/demo demo-out
	$(BIN)/meshtool normalize "fixtures/head/Head 1.obj" -o out/demo --units cm
	$(BIN)/python scripts/show_asset.py out/demo/head_1
	$(BIN)/obj2bin "fixtures/head/Head 1.obj" --units cm -o out/demo/head_1.mbin
	$(BIN)/meshtool info out/demo/head_1.mbin
	$(BIN)/meshtool validate fixtures/head fixtures/validate/clean out/demo/head_1.mbin \
		--format html -o demo-out/validate.html
	$(BIN)/meshtool urdf fixtures/urdf/tiny_arm_description/urdf/tiny_arm.urdf -o out/demo/tiny_arm --actuators
	$(BIN)/simrun check fixtures/scenes/urdf_arm.toml
	$(BIN)/simrun export fixtures/scenes/urdf_arm.toml --usd demo-out/urdf_arm.usda --glb demo-out/urdf_arm.glb
	$(BIN)/simrun check fixtures/scenes/boebot.toml
	$(BIN)/simrun doctor
	$(BIN)/simrun play fixtures/scenes/boebot.toml --duration 40 \
		--commands fixtures/scenes/square.commands.toml --video demo-out/demo.gif --fps 10 --camera follow:boebot
	@echo "next: $(BIN)/simrun serve fixtures/scenes/boebot_sensors.toml, then open http://127.0.0.1:8765/ (docs/serve.md)"

lint: $(TEST_STAMP)
	$(BIN)/ruff check meshtool simrun tests bench scripts
	$(BIN)/ruff format --check meshtool simrun tests bench scripts
	$(BIN)/mypy

test: $(TEST_STAMP) lint
	bash scripts/install_gl.sh
	sh scripts/install_test_tools.sh
	MUJOCO_GL=$${MUJOCO_GL:-egl} $(BIN)/python -m pytest -q -n $(TEST_JOBS) --dist loadfile

bench: $(TEST_STAMP) $(PEERS)/.installed
	bash scripts/install_gl.sh
	sh scripts/install_test_tools.sh
	$(BIN)/python bench/startup.py . --obj2mjcf=$(PEERS)/bin/obj2mjcf
	$(BIN)/python bench/parse.py ../shared/corpus --peer-python=$(PEERS)/bin/python
	$(BIN)/python bench/load.py ../shared/corpus
	$(BIN)/python bench/world.py ../shared/corpus
	$(BIN)/python bench/decompose_fixed.py .
	$(BIN)/python bench/mjcf_robots.py --install
	$(BIN)/python bench/drive.py .
	$(BIN)/python bench/validate.py ../shared/corpus
	$(BIN)/python bench/hulls.py ../shared/corpus --obj2mjcf=$(PEERS)/bin/obj2mjcf
	$(BIN)/python bench/hull_agreement.py ../shared/corpus
	$(BIN)/python bench/formats_check.py ../shared/robots --corpus ../shared/corpus --derived 10 --docs
	MUJOCO_GL=$${MUJOCO_GL:-egl} $(BIN)/python bench/recordings.py --repeat 3
	MUJOCO_GL=$${MUJOCO_GL:-egl} $(BIN)/python bench/scenetest.py --seeds 50 --rounds 2
	$(BIN)/python bench/serve.py . --repeat 3
	$(BIN)/python bench/serve_load.py . --repeat 3
	$(BIN)/python bench/batch_throughput.py ../shared/corpus --docs

# The benchmarks' peers (obj2mjcf, the C++ tinyobjloader binding) live in their own environment inside the
# checkout (ignored by git), never in the project's .venv.
$(PEERS)/.installed:
	@if [ -L $(PEERS) ]; then echo "$(PEERS) is a symlink (left by an old checkout): remove it"; exit 1; fi
	$(PYTHON) -m venv $(PEERS)
	$(PEERS)/bin/python -m pip install --quiet obj2mjcf "tinyobjloader==2.0.0rc13"
	touch $@

# The MJCF models dm-control and gymnasium ship, as simrun entities (issue 29): their packages go into their own
# environment .bench-mjcf/ (pip --no-deps: only their XML and meshes are read, by the project's MuJoCo), never .venv;
# writes the "MJCF robots" section of docs/robots.md.
bench-mjcf: $(STAMP)
	$(BIN)/python bench/mjcf_robots.py --docs

# Assets/s of obj2bin DIR and meshtool validate DIR over 1, 100 and 1,000 corpus assets with -j 1, -j 2 and a Dask
# LocalCluster of 2 workers (issue 38; dask comes with the test extras): the "Batch throughput" section of
# docs/benchmarks.md. The packs and reports must be byte-identical across the executors.
bench-batch: $(TEST_STAMP)
	$(BIN)/python bench/batch_throughput.py ../shared/corpus --sizes 1,100,1000 --docs

bench-hulls: $(STAMP) $(PEERS)/.installed
	$(BIN)/python bench/hulls.py ../shared/corpus --obj2mjcf=$(PEERS)/bin/obj2mjcf

# mujoco-usd-converter pins mujoco 3.16: its own ignored environment, never the project's .venv
.bench-usd/.installed:
	$(PYTHON) -m venv .bench-usd
	.bench-usd/bin/python -m pip install --quiet "mujoco-usd-converter==0.8.0"
	touch $@

bench-usd: $(STAMP) .bench-usd/.installed
	$(BIN)/python bench/usd_compare.py

corpus: $(STAMP)
	$(BIN)/python bench/corpus_check.py ../shared/corpus

# Fuzz the readers (obj mtl mbin scene simlog stl ply gltf glb collada urdf commands) for FUZZ_SECONDS in all,
# or FUZZ_SECONDS_PER_TARGET each; FUZZ_TARGETS=stl,ply picks targets (not part of make test).
# Crashes land in out/fuzz/crashes/, counts in out/fuzz/summary.json (see docs/testing.md)
FUZZ_SECONDS ?= 600
fuzz: $(TEST_STAMP)
	MUJOCO_GL=$${MUJOCO_GL:-egl} FUZZ_SECONDS=$(FUZZ_SECONDS) $(BIN)/python tests/fuzz/run.py

clean:
	rm -rf out build dist *.egg-info .pytest_cache .mypy_cache .ruff_cache

# Mutation testing of the robot modules (docs/testing.md, "Mutation testing"); slow, not part of make test.
# One module at a time, each against its tests (pyproject [tool.mutmut]); LP_NUM_THREADS=0 keeps Mesa's
# renderer single-threaded so mutmut's forked test runs cannot deadlock. MUTATE=simrun.robots.arm.* for one module.
MUTATE ?= simrun.robots.diff_drive.* simrun.services.drive_service.* simrun.robots.arm.* simrun.robots.arm_service.* simrun.robots.arm_joints.* simrun.sensors.base.* simrun.sensors.range_cone.* simrun.services.joint_service.* \
	simrun.world.world.xǁWorldǁstep__* simrun.world.world.xǁWorldǁreschedule__*
mutants: $(TEST_STAMP)
	$(PIP) install --quiet -e ".[test,mutation]"
	bash scripts/install_gl.sh
	for m in $(MUTATE); do \
		LP_NUM_THREADS=0 MUJOCO_GL=$${MUJOCO_GL:-egl} $(BIN)/mutmut run --max-children $${JOBS:-2} "$$m" || exit 1; \
	done
	$(BIN)/python scripts/mutation_summary.py

