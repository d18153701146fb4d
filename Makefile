# Two entry points for a fresh machine with Python >= 3.11 and pip (see README.md):
#   make demo   installs into .venv, normalises and packs the seed head, validates assets (demo-out/
#               validate.html), drives the Boe-Bot around the box and writes demo-out/demo.gif
#   make test   installs into .venv and runs lint, type checks and the test suite
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
PEERS  := .bench-peers

.PHONY: install demo test lint bench bench-hulls corpus fuzz clean mutants

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[test]"
	touch $(STAMP)

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
		--commands fixtures/scenes/square.commands.toml --video demo-out/demo.gif --fps 10

lint: $(STAMP)
	$(BIN)/ruff check meshtool simrun tests bench scripts
	$(BIN)/ruff format --check meshtool simrun tests bench scripts
	$(BIN)/mypy

test: $(STAMP) lint
	bash scripts/install_gl.sh
	sh scripts/install_test_tools.sh
	MUJOCO_GL=$${MUJOCO_GL:-egl} $(BIN)/python -m pytest -q

bench: $(STAMP) $(PEERS)/.installed
	$(BIN)/python bench/startup.py .
	$(BIN)/python bench/parse.py ../shared/corpus --peer-python=$(PEERS)/bin/python
	$(BIN)/python bench/load.py ../shared/corpus
	$(BIN)/python bench/world.py ../shared/corpus
	$(BIN)/python bench/decompose_fixed.py .
	$(BIN)/python bench/drive.py .
	$(BIN)/python bench/validate.py ../shared/corpus

# The benchmarks' peers (obj2mjcf, the C++ tinyobjloader binding) live in their own environment inside the
# checkout (ignored by git), never in the project's .venv.
$(PEERS)/.installed:
	@if [ -L $(PEERS) ]; then echo "$(PEERS) is a symlink (left by an old checkout): remove it"; exit 1; fi
	$(PYTHON) -m venv $(PEERS)
	$(PEERS)/bin/python -m pip install --quiet obj2mjcf "tinyobjloader==2.0.0rc13"
	touch $@

bench-hulls: $(STAMP) $(PEERS)/.installed
	$(BIN)/python bench/hulls.py ../shared/corpus --obj2mjcf=$(PEERS)/bin/obj2mjcf

corpus: $(STAMP)
	$(BIN)/python bench/corpus_check.py ../shared/corpus

# Fuzz the readers (obj mtl mbin scene simlog stl ply gltf glb collada urdf commands) for FUZZ_SECONDS in all,
# or FUZZ_SECONDS_PER_TARGET each; FUZZ_TARGETS=stl,ply picks targets (not part of make test).
# Crashes land in out/fuzz/crashes/, counts in out/fuzz/summary.json (see docs/testing.md)
FUZZ_SECONDS ?= 600
fuzz: $(STAMP)
	MUJOCO_GL=$${MUJOCO_GL:-egl} FUZZ_SECONDS=$(FUZZ_SECONDS) $(BIN)/python tests/fuzz/run.py

clean:
	rm -rf out build dist *.egg-info .pytest_cache .mypy_cache .ruff_cache

# Mutation testing of the robot modules (docs/testing.md, "Mutation testing"); slow, not part of make test.
# One module at a time, each against its tests (pyproject [tool.mutmut]); LP_NUM_THREADS=0 keeps Mesa's
# renderer single-threaded so mutmut's forked test runs cannot deadlock. MUTATE=simrun.arm.* for one module.
MUTATE ?= simrun.drive.* simrun.drive_service.* simrun.arm.* simrun.arm_joints.* simrun.sensors.* simrun.cameras.* \
	simrun.world.xǁWorldǁstep__* simrun.world.xǁWorldǁreschedule__*
mutants: $(STAMP)
	$(BIN)/python -m pip install --quiet -e ".[test,mutation]"
	bash scripts/install_gl.sh
	for m in $(MUTATE); do \
		LP_NUM_THREADS=0 MUJOCO_GL=$${MUJOCO_GL:-egl} $(BIN)/mutmut run --max-children $${JOBS:-2} "$$m" || exit 1; \
	done
	$(BIN)/python scripts/mutation_summary.py

