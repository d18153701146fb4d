"""Headless OpenGL by default: choose ``MUJOCO_GL`` before MuJoCo is imported, and never crash on it.

MuJoCo reads ``MUJOCO_GL`` once, when ``mujoco`` is imported. ``import simrun`` does not import MuJoCo (a
``simrun --help`` stays cheap): it arms a ``sys.meta_path`` hook (:func:`arm`) that decides the moment
anything first imports ``mujoco``, the same choice :func:`import_mujoco` makes:

- ``MUJOCO_GL`` unset (or empty) and no display (``DISPLAY`` / ``WAYLAND_DISPLAY`` on Linux): EGL when its
  libraries load, else OSMesa, else none (rendering then fails with one line naming the packages);
- set by the user: kept. When its libraries are missing (``osmesa`` without ``libOSMesa``), or the value is
  not a backend (``MUJOCO_GL=foo``), MuJoCo would die on import with a traceback; it is imported with
  rendering disabled instead and the problem is kept for the first render to report;
- ``glfw`` (or unset with a display): MuJoCo's default, a window system context.

Only libraries are loaded here (``ctypes``), never a context: a context is made in a child process by
``simrun doctor``. Nothing here imports ``mujoco`` except :func:`import_mujoco` (the hook only finds its
spec and hands the import back).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import importlib
import importlib.abc
import importlib.machinery
import importlib.util
import os
import sys
from collections.abc import Callable, Mapping, MutableMapping, Sequence
from dataclasses import dataclass
from types import ModuleType

#: Headless backends in the order they are tried.
HEADLESS = ("egl", "osmesa")
#: Debian/Ubuntu packages that provide each backend (scripts/install_gl.sh installs both).
PACKAGES = {"egl": ("libegl1", "libegl-mesa0", "libgl1-mesa-dri"), "osmesa": ("libosmesa6",)}
#: Shared libraries each backend loads (PyOpenGL's names); every group must have one that loads.
LIBRARIES = {"egl": (("EGL",), ("OpenGL", "GL")), "osmesa": (("OSMesa",),)}
#: ``MUJOCO_GL`` values MuJoCo accepts on Linux; the ``off`` group disables rendering.
VALID = ("egl", "osmesa", "glfw", "glx", "enable", "enabled", "on", "true", "1")
OFF = ("disable", "disabled", "off", "false", "0")
INSTALL_HINT = (
    "install EGL (apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri) or OSMesa (apt-get install libosmesa6), "
    "e.g. sudo scripts/install_gl.sh"
)


@dataclass(frozen=True, slots=True)
class GLChoice:
    """The OpenGL backend in effect.

    Attributes:
        backend: The ``MUJOCO_GL`` value MuJoCo uses (``egl``, ``osmesa``, ``glfw``...), ``None`` when none.
        reason: How it was chosen, for ``simrun doctor`` (``chosen: no display, EGL loads``).
        problem: Why rendering cannot work, as one line with the fix; ``None`` when it may.
    """

    backend: str | None
    reason: str
    problem: str | None = None


def _loads(name: str) -> bool:
    """Whether a shared library (PyOpenGL's short name) is found and loads, without running it."""
    found = ctypes.util.find_library(name)
    if not found:
        return False
    try:
        ctypes.CDLL(found)
    except OSError:
        return False
    return True


def available(backend: str, loads: Callable[[str], bool] = _loads) -> bool:
    """Whether the libraries of a headless backend (:data:`HEADLESS`) load here."""
    return all(any(loads(name) for name in group) for group in LIBRARIES[backend])


def has_display(environ: Mapping[str, str] = os.environ, platform: str = sys.platform) -> bool:
    """Whether a window system is there (always on macOS and Windows)."""
    if not platform.startswith("linux"):
        return True
    return bool(environ.get("DISPLAY") or environ.get("WAYLAND_DISPLAY"))


def choose(
    environ: Mapping[str, str] = os.environ, loads: Callable[[str], bool] = _loads, platform: str = sys.platform
) -> GLChoice:
    """Decide the backend as the module says (pure: reads ``environ``, changes nothing)."""
    value = environ.get("MUJOCO_GL", "").strip().lower()
    display = has_display(environ, platform)
    if value in HEADLESS:
        if available(value, loads):
            return GLChoice(value, "set by the user")
        packages = " ".join(PACKAGES[value])
        return GLChoice(
            None,
            "set by the user",
            f"MUJOCO_GL={value} but its libraries are not installed: apt-get install {packages} "
            "(scripts/install_gl.sh), or unset MUJOCO_GL to let simrun choose",
        )
    if value in OFF:
        return GLChoice(None, "set by the user", f"rendering is off (MUJOCO_GL={value})")
    if value and value not in VALID:
        return GLChoice(
            None,
            "set by the user",
            f"MUJOCO_GL={value!r} is not an OpenGL backend: use egl, osmesa or glfw, or unset it",
        )
    if value or display:
        backend = value or "glfw"
        if not display and platform.startswith("linux"):
            return GLChoice(
                backend,
                f"MUJOCO_GL={backend}",
                f"MUJOCO_GL={backend} needs a display and there is none (DISPLAY is unset): unset MUJOCO_GL to "
                "render headless with EGL or OSMesa",
            )
        return GLChoice(backend, "a display is present" if not value else "set by the user")
    preferred = environ.get("PYOPENGL_PLATFORM", "").strip().lower()
    order = sorted(HEADLESS, key=lambda b: b != preferred)  # a PyOpenGL platform already set goes first
    for backend in order:
        if available(backend, loads):
            return GLChoice(backend, f"chosen: no display, {backend.upper()} libraries load")
    return GLChoice(None, "no display", f"no headless OpenGL here: {INSTALL_HINT}")


_CHOICE: GLChoice | None = None


def import_mujoco(environ: MutableMapping[str, str] = os.environ) -> ModuleType:
    """Choose the backend (:func:`choose`), set ``MUJOCO_GL`` / ``PYOPENGL_PLATFORM`` and import ``mujoco``.

    A choice made here is written to ``environ`` (child processes inherit it). A user's value that would
    crash the import is replaced by ``disable`` for the import only and then put back.

    Returns:
        The ``mujoco`` module.
    """
    global _CHOICE
    disarm()
    if "mujoco" in sys.modules:  # imported before simrun: MuJoCo already decided
        if _CHOICE is None:
            _CHOICE = _as_imported(environ)
        return sys.modules["mujoco"]
    restore = _decide(environ)
    try:
        return importlib.import_module("mujoco")
    finally:
        if restore is not None:
            environ["MUJOCO_GL"] = restore


class _DecideFirst(importlib.abc.MetaPathFinder):
    """A ``sys.meta_path`` finder that decides ``MUJOCO_GL`` the moment something first imports ``mujoco``.

    It finds nothing itself: on the first ``import mujoco`` it removes itself, makes the choice of
    :func:`import_mujoco` (written to ``os.environ``) and hands the import back to the other finders, with
    the loader wrapped when a user's value must be replaced by ``disable`` for the import only.
    """

    def find_spec(
        self, fullname: str, path: Sequence[str] | None, target: ModuleType | None = None
    ) -> importlib.machinery.ModuleSpec | None:
        """``None`` for every module but ``mujoco``, whose real spec comes back after the choice is made."""
        if fullname != "mujoco":
            return None
        disarm()
        restore = _decide(os.environ)
        spec = importlib.util.find_spec("mujoco")
        if spec is None or restore is None or spec.loader is None:
            if restore is not None:
                os.environ["MUJOCO_GL"] = restore
            return spec
        spec.loader = _Restoring(spec.loader, restore)
        return spec


class _Restoring(importlib.abc.Loader):
    """A loader that runs ``mujoco``'s own and then puts the user's ``MUJOCO_GL`` back."""

    def __init__(self, loader: importlib.abc.Loader, value: str) -> None:
        self.loader, self.value = loader, value

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType | None:
        """The wrapped loader's module."""
        return self.loader.create_module(spec)

    def exec_module(self, module: ModuleType) -> None:
        """Run the wrapped loader, then restore ``MUJOCO_GL``."""
        try:
            self.loader.exec_module(module)
        finally:
            os.environ["MUJOCO_GL"] = self.value


_HOOK = _DecideFirst()


def arm() -> None:
    """Decide ``MUJOCO_GL`` when ``mujoco`` is first imported (run by ``import simrun``; imports nothing).

    ``import simrun`` stays cheap (``simrun --help`` never loads MuJoCo) while every later ``import mujoco``
    of this process, simrun's or anyone's, still sees the backend chosen first. Nothing happens when
    ``mujoco`` is already imported: :func:`gl_choice` then judges what MuJoCo read.
    """
    if "mujoco" not in sys.modules and _HOOK not in sys.meta_path:
        sys.meta_path.insert(0, _HOOK)


def disarm() -> None:
    """Remove the hook of :func:`arm` (the choice is then made by :func:`import_mujoco` or never)."""
    while _HOOK in sys.meta_path:
        sys.meta_path.remove(_HOOK)


def _decide(environ: MutableMapping[str, str]) -> str | None:
    """Make the choice and write it to ``environ``; the user's value to put back after the import, or ``None``."""
    global _CHOICE
    choice = choose(environ)
    _CHOICE = choice
    user = environ.get("MUJOCO_GL")
    if choice.backend in HEADLESS and not user:
        environ["MUJOCO_GL"] = choice.backend
        environ.setdefault("PYOPENGL_PLATFORM", choice.backend)
    if choice.backend is None and user:
        environ["MUJOCO_GL"] = "disable"
        return user
    return None


def _as_imported(environ: Mapping[str, str]) -> GLChoice:
    """The choice when ``mujoco`` was imported before simrun: what MuJoCo read then, judged as :func:`choose` would."""
    module = sys.modules.get("mujoco.rendering.classic.gl_context")
    read = getattr(module, "_MUJOCO_GL", None)
    if read is None:  # unknown MuJoCo layout: judge the environment as it is now
        return choose(environ)
    choice = choose({**environ, "MUJOCO_GL": read} if read else {k: v for k, v in environ.items() if k != "MUJOCO_GL"})
    if not read and choice.backend in HEADLESS:  # MuJoCo took its default (GLFW) before simrun could choose
        return GLChoice(
            "glfw",
            "mujoco was imported before simrun, without MUJOCO_GL",
            "mujoco was imported before simrun without MUJOCO_GL and there is no display: import simrun first, "
            f"or set MUJOCO_GL={choice.backend}",
        )
    return choice


def gl_choice() -> GLChoice:
    """The backend in effect for this process (chosen on first call when ``import simrun`` did not)."""
    global _CHOICE
    if _CHOICE is None:
        _CHOICE = _as_imported(os.environ) if "mujoco" in sys.modules else choose()
    return _CHOICE


def gl_problem() -> str | None:
    """Why rendering cannot work in this process (one line with the fix), or ``None``."""
    return gl_choice().problem
