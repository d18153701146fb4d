"""Start-up work of the command lines (issue 28): ``--help`` of every command imports no heavy library.

Counted in a child process (``sys.modules`` after the command ran), never timed: numpy, Pillow, trimesh,
scipy, MuJoCo, CoACD and the GLB exporter are imported only by the commands that use them.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

HEAVY = ("numpy", "PIL", "trimesh", "scipy", "mujoco", "coacd", "pxr", "dask", "simrun.export.glb")
MESHTOOL = ("export", "hulls", "info", "mjcf", "normalize", "unpack", "urdf", "validate")
SIMRUN = ("check", "doctor", "export", "play", "replay", "resim", "snapshot", "test", "view")
CASES = (
    [("meshtool.cli.main", "main", ["meshtool", "--help"]), ("meshtool.cli.main", "obj2bin", ["obj2bin", "--help"])]
    + [("meshtool.cli.main", "main", ["meshtool", name, "--help"]) for name in MESHTOOL]
    + [("simrun.cli.main", "main", ["simrun", "--help"])]
    + [("simrun.cli.main", "main", ["simrun", name, "--help"]) for name in SIMRUN]
)


def _imported(module: str, function: str, argv: list[str]) -> tuple[int, list[str], str]:
    """(exit code, heavy modules imported, stdout) of a console script's ``main`` run in a fresh interpreter."""
    code = (
        f"import sys, json\nsys.argv = {argv!r}\nfrom {module} import {function}\n"
        f"try:\n    {function}()\nexcept SystemExit as exc:\n    status = exc.code or 0\n"
        f"heavy = sorted(h for h in {HEAVY!r} if any(m == h or m.startswith(h + '.') for m in sys.modules))\n"
        "print(json.dumps([status, heavy]), file=sys.stderr)"
    )
    env = {k: v for k, v in os.environ.items() if k != "MUJOCO_GL"}
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=False, env=env
    )
    status, heavy = json.loads(result.stderr.strip().splitlines()[-1])
    return status, heavy, result.stdout


@pytest.mark.parametrize(("module", "function", "argv"), CASES, ids=[" ".join(c[2]) for c in CASES])
def test_help_imports_no_heavy_library(module: str, function: str, argv: list[str]) -> None:
    status, heavy, out = _imported(module, function, argv)
    assert status == 0
    assert "Usage:" in out
    assert heavy == [], f"{' '.join(argv)} imported {heavy}"


def test_import_simrun_does_not_load_mujoco_but_the_first_import_of_it_is_headless() -> None:
    """``import simrun`` arms the GL choice; the first ``import mujoco`` (anyone's) still sees it decided."""
    code = (
        "import os, sys\nimport simrun\nbefore = 'mujoco' in sys.modules\nimport mujoco\n"
        "from simrun.run.headless import gl_choice\n"
        "print(before, os.environ.get('MUJOCO_GL'), gl_choice().backend)"
    )
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "DISPLAY", "WAYLAND_DISPLAY")}
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env)
    before, variable, backend = result.stdout.split()
    assert before == "False"
    assert variable == backend  # MuJoCo read the backend simrun chose (egl, osmesa, or none: "None")


def test_the_light_copies_of_option_choices_agree_with_the_library() -> None:
    """The command lines keep the choices they show in ``--help`` without importing the library that owns them."""
    from meshtool.cli import command_support as cli_support
    from meshtool.cli import validate as cli_validate
    from meshtool.frame.units import UNIT_FACTORS
    from meshtool.validate.reports import FORMATS
    from simrun.cli import types as cli
    from simrun.run.render import MODES
    from simrun.run.session import DEFAULT_SIZE

    assert tuple(UNIT_FACTORS) == cli_support.UNITS
    assert cli_validate.FORMATS == FORMATS
    assert cli.MODES == MODES
    assert cli.DEFAULT_SIZE == DEFAULT_SIZE


@pytest.mark.parametrize("module", ["meshtool.cli.main", "simrun.cli.main"])
def test_the_command_lines_run_numpy_without_spinning_blas_threads(module: str) -> None:
    """OpenBLAS starts a spinning thread per CPU when numpy loads; the command lines ask for none (counted)."""
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    code = f"import os\nimport {module}\nimport numpy\nprint(len(os.listdir('/proc/self/task')))"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env)
    assert int(result.stdout) == 1
    kept = {**env, "OPENBLAS_NUM_THREADS": "2"}  # a user's own setting is kept
    code = f"import os\nimport {module}\nprint(os.environ['OPENBLAS_NUM_THREADS'])"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=kept)
    assert result.stdout.strip() == "2"
