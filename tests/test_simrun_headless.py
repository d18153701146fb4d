"""Headless by default (issue 14 item 1): MUJOCO_GL chosen before MuJoCo loads, no traceback for any value.

MuJoCo picks its OpenGL backend when it is imported, so every case runs in its own process.
"""

import io
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from simrun.run.headless import HEADLESS, available, choose

ROOT = Path(__file__).resolve().parent.parent
SCENE = ROOT / "fixtures" / "scenes" / "basic.toml"
CLEAN = ROOT / "fixtures" / "validate" / "clean"
HERE = {backend: available(backend) for backend in HEADLESS}


def _loads(*present: str):
    return lambda name: name in present


EGL_LIBS, OSMESA_LIBS = ("EGL", "GL"), ("OSMesa",)


@pytest.mark.parametrize(
    ("environ", "present", "backend", "problem"),
    [
        ({}, EGL_LIBS + OSMESA_LIBS, "egl", None),
        ({}, OSMESA_LIBS, "osmesa", None),
        ({}, ("EGL",), None, "libegl1 libegl-mesa0 libgl1-mesa-dri"),  # EGL without libGL: OSMesa absent too
        ({}, (), None, "libosmesa6"),
        ({"PYOPENGL_PLATFORM": "osmesa"}, EGL_LIBS + OSMESA_LIBS, "osmesa", None),
        ({"MUJOCO_GL": "osmesa"}, EGL_LIBS, None, "apt-get install libosmesa6"),
        ({"MUJOCO_GL": "EGL"}, EGL_LIBS, "egl", None),
        ({"MUJOCO_GL": "egl"}, OSMESA_LIBS, None, "apt-get install libegl1"),
        ({"MUJOCO_GL": "glfw"}, EGL_LIBS, "glfw", "needs a display"),
        ({"MUJOCO_GL": "glfw", "DISPLAY": ":0"}, (), "glfw", None),
        ({"DISPLAY": ":0"}, EGL_LIBS, "glfw", None),
        ({"WAYLAND_DISPLAY": "wayland-0"}, EGL_LIBS, "glfw", None),
        ({"MUJOCO_GL": "foo"}, EGL_LIBS, None, "not an OpenGL backend"),
        ({"MUJOCO_GL": "off"}, EGL_LIBS, None, "rendering is off"),
    ],
)
def test_choice(environ, present, backend, problem):
    choice = choose(environ, _loads(*present), "linux")
    assert choice.backend == backend
    if problem is None:
        assert choice.problem is None
    else:
        assert problem in choice.problem and "\n" not in choice.problem


def test_macos_keeps_mujocos_default():
    assert choose({}, _loads(), "darwin").problem is None


def _env(value: str | None) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY", "PYOPENGL_PLATFORM")}
    env.pop("MUJOCO_GL", None)
    if value is not None:
        env["MUJOCO_GL"] = value
    return env


def _run(args: list[str], value: str | None, prelude: str = "") -> subprocess.CompletedProcess[str]:
    """A console script in a fresh process (``prelude`` runs before anything is imported)."""
    module, func = {"simrun": ("simrun.cli.main", "main"), "meshtool": ("meshtool.cli.main", "main")}[args[0]]
    code = f"{prelude}\nimport sys\nsys.argv = {args!r}\nfrom {module} import {func}\n{func}()"
    return subprocess.run(
        [sys.executable, "-c", code], env=_env(value), capture_output=True, text=True, timeout=300, check=False
    )


#: MUJOCO_GL values a user may have: unset, the two headless ones, a window system without a display, typos.
VALUES = [None, "egl", "osmesa", "glfw", "foo", "disable"]


def _renders_here(value: str | None) -> bool:
    if value is None:
        return any(HERE.values())
    return HERE.get(value, False)


@pytest.mark.parametrize("value", VALUES, ids=str)
def test_no_traceback_under_any_mujoco_gl(value, tmp_path):
    for args in (["simrun", "--help"], ["simrun", "check", str(SCENE)]):
        result = _run(args, value)
        assert result.returncode == 0, (args, result.stderr)
        assert "Traceback" not in result.stderr + result.stdout
    out = tmp_path / "shot.png"
    result = _run(["simrun", "snapshot", str(SCENE), "-o", str(out), "--size", "64x48"], value)
    assert "Traceback" not in result.stderr
    if _renders_here(value):
        assert result.returncode == 0, result.stderr
        pixels = np.asarray(Image.open(out).convert("RGB"), dtype=float)
        assert pixels.std() > 5  # a picture, not a blank frame
    else:
        assert result.returncode == 1
        lines = result.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("error: cannot render: "), result.stderr
        assert not out.exists()


@pytest.mark.parametrize("value", [None, "osmesa", "glfw", "foo"], ids=str)
def test_meshtool_validate_without_cache_is_not_an_internal_error(value, tmp_path):
    """Issue 14: under MUJOCO_GL=osmesa, validate --no-cache reported every asset as an internal error (exit 3)."""
    report = tmp_path / "report.json"
    result = _run(["meshtool", "validate", "--no-cache", str(CLEAN), "--format", "json", "-o", str(report)], value)
    assert result.returncode == 0, result.stderr
    assert "Traceback" not in result.stderr and report.exists()


def test_missing_osmesa_library_is_one_line_naming_the_package(tmp_path):
    """MUJOCO_GL=osmesa without libOSMesa: MuJoCo's import would die (AttributeError ... glGetError)."""
    hide = "import ctypes.util as u\n_f = u.find_library\nu.find_library = lambda n: None if n == 'OSMesa' else _f(n)"
    for args in (["simrun", "--help"], ["simrun", "snapshot", str(SCENE), "-o", str(tmp_path / "x.png")]):
        result = _run(args, "osmesa", prelude=hide)
        assert "Traceback" not in result.stderr
        if args[1] == "--help":
            assert result.returncode == 0
        else:
            assert result.returncode == 1
            assert result.stderr.strip().splitlines() == [
                "error: cannot render: MUJOCO_GL=osmesa but its libraries are not installed: apt-get install "
                "libosmesa6 (scripts/install_gl.sh), or unset MUJOCO_GL to let simrun choose"
            ]


def test_doctor_says_which_backend_is_used():
    result = _run(["simrun", "doctor"], None)
    used = [line for line in result.stdout.splitlines() if line.startswith("rendering uses ")]
    assert len(used) == 1
    if HERE["egl"]:
        assert used[0].startswith("rendering uses MUJOCO_GL=egl (chosen: no display")
    elif HERE["osmesa"]:
        assert used[0].startswith("rendering uses MUJOCO_GL=osmesa (chosen: no display")


@pytest.mark.parametrize("backend", HEADLESS)
def test_every_render_path_here_draws_the_same_scene(backend, tmp_path):
    """Each headless backend whose libraries are installed renders; EGL and OSMesa (both Mesa) agree."""
    if not HERE[backend]:
        pytest.skip(f"{backend} libraries not installed here (scripts/install_gl.sh installs them)")
    images = {}
    for value in (backend, "egl" if backend == "osmesa" and HERE["egl"] else backend):
        out = tmp_path / f"{value}.png"
        result = _run(["simrun", "snapshot", str(SCENE), "-o", str(out), "--size", "96x72"], value)
        assert result.returncode == 0, result.stderr
        images[value] = np.asarray(Image.open(io.BytesIO(out.read_bytes())).convert("RGB"), dtype=float)
    first = images[backend]
    assert first.std() > 5
    for other in images.values():
        assert np.abs(other - first).mean() < 8.0  # the same scene, the same camera, light and size


def test_mujoco_imported_before_simrun_is_judged_by_what_it_read():
    """MuJoCo decides at its own import: imported first without MUJOCO_GL (headless), it took GLFW; say so."""
    code = (
        "import mujoco, simrun\n"
        "from simrun.errors import SimrunError\n"
        "from simrun.run.render import open_renderer\n"
        "try:\n"
        "    open_renderer(mujoco.MjModel.from_xml_string('<mujoco/>'), 8, 8).close()\n"
        "    print('rendered')\n"
        "except SimrunError as exc:\n"
        "    print(exc)\n"
    )
    for value, expected in ((None, "import simrun first"), ("egl", "rendered")):
        if value == "egl" and not HERE["egl"]:
            continue
        result = subprocess.run(
            [sys.executable, "-c", code], env=_env(value), capture_output=True, text=True, timeout=300, check=False
        )
        assert result.returncode == 0 and "Traceback" not in result.stderr, result.stderr
        assert expected in result.stdout, result.stdout
