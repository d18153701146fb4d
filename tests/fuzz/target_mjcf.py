"""The ``mjcf`` fuzz target: mutated MJCF models through ``MjcfRobot`` (issue 42, item 5).

Seeds (``FUZZ_MJCF_SOURCES``, comma-separated, default ``fixtures,dm_control``):

- ``fixtures``: every ``<mujoco>`` XML under ``fixtures/`` (``fixtures/mjcf``, ``fixtures/vendor``,
  ``fixtures/realworld``...), each with every file the project's reader (:func:`simrun.robots.mjcf_read.read_mjcf`)
  reads for it (includes, meshes, textures), at the same places relative to each other;
- ``dm_control``: the same for every ``<mujoco>`` model dm_control ships, read at fuzz time from the bench
  environment ``.bench-mjcf/`` (``make bench-mjcf`` makes it; dm_control is no dependency of the project).
  Without that environment the source is skipped with a note on stderr. Models whose files pass
  :data:`MAX_MODEL_BYTES` together are left out (fuzzing wants many fast inputs).

An input is a seed with its model file mutated (:func:`mutate_mjcf.mutated_mjcf`) and, 1 in 8, ``free`` or
``root_slides`` set on the robot (the entry :data:`OPTIONS`, JSON). :func:`run_mjcf` writes it into a fresh
folder (``@OUTSIDE@`` replaced by a folder outside it holding ``secret.obj``; beside the model a FIFO ``pipe``
and ``link.obj``, a symbolic link to the outside file), builds a ``World`` with the folder as its root and the
model as an ``MjcfRobot``, compiles it and steps it 10 times. A clean refusal is a
:class:`simrun.errors.SimrunError` whose message is one line; a message of several lines
(:class:`MultiLineError`), any open of a file outside the folder, a device, ``/proc`` or ``/etc``, or an open
of the FIFO that could wait for a writer (neither ``O_NONBLOCK`` nor ``O_DIRECTORY``), seen by an audit hook
(Python's opens, hence the reader's; :class:`OpenedOutside`), is a crash like any other exception.
"""

from __future__ import annotations

import json
import os
import sys
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

from hypothesis import strategies as st
from mutate_mjcf import mutated_mjcf

REPO = Path(__file__).resolve().parents[2]
FIXTURES = REPO / "fixtures"
BENCH_ENV = REPO / ".bench-mjcf"
SOURCES_ENV = "FUZZ_MJCF_SOURCES"
#: Largest seed model, bytes (the model and every file it reads, together).
MAX_MODEL_BYTES = 1 << 20
#: The input entry holding the robot's options (JSON), not a file of the model.
OPTIONS = "@robot.json"
Files = dict[str, bytes]


class MultiLineError(Exception):
    """A refusal whose message is not one line."""


class OpenedOutside(Exception):
    """A file outside the model's folder, a device or a ``/proc`` file was opened, or the FIFO could block."""


def _is_model(path: Path) -> bool:
    try:
        return ET.parse(path).getroot().tag == "mujoco"
    except (ET.ParseError, OSError):
        return False


def _seed(path: Path, roots: list[Path]) -> Files | None:
    """The model with every file the reader reads for it, relative to their common folder (``None``: too big)."""
    from simrun.robots.mjcf_read import read_mjcf

    try:
        read = [(f.path, f.real) for f in read_mjcf(path, roots).read]
    except Exception:  # a model the reader refuses as it is: mutated alone
        read = [(path, path)]
    base = Path(os.path.commonpath([str(p.parent) for p, _ in read]))
    files: Files = {}
    for shown, real in read:
        files.setdefault(os.path.relpath(shown, base), real.read_bytes())
    return files if sum(map(len, files.values())) <= MAX_MODEL_BYTES else None


def _site_packages() -> Path | None:
    found = sorted(BENCH_ENV.glob("lib/python*/site-packages/dm_control"))
    return found[-1].parent if found else None


def mjcf_seeds(_scratch: Path) -> list[Files]:
    """The fixture models and dm_control's (see the module), each once."""
    sources = [s.strip() for s in os.environ.get(SOURCES_ENV, "fixtures,dm_control").split(",") if s.strip()]
    paths: list[tuple[Path, list[Path]]] = []
    if "fixtures" in sources:
        paths += [(p, [FIXTURES]) for p in sorted(FIXTURES.rglob("*.xml")) if "fuzz" not in p.parts]
    if "dm_control" in sources:
        site = _site_packages()
        if site is None:
            note = f"mjcf: {BENCH_ENV} has no dm_control (make bench-mjcf makes it): its models skipped"
            print(note, file=sys.stderr)
        else:
            paths += [(p, [site / "dm_control"]) for p in sorted((site / "dm_control").rglob("*.xml"))]
    seeds, seen = [], set()
    for path, roots in paths:
        if not _is_model(path):
            continue
        files = _seed(path, roots)
        key = None if files is None else tuple(sorted(files.items()))
        if files is not None and key not in seen:
            seen.add(key)
            seeds.append(files)
    return seeds


def mjcf_strategy(seeds: list[Files]) -> Any:
    """A seed with its model mutated and, sometimes, the robot's ``free`` or ``root_slides`` set."""

    @st.composite
    def inputs(draw: Any) -> Files:
        files = dict(draw(st.sampled_from(seeds)))
        first = next(iter(files))
        files[first] = draw(mutated_mjcf(files[first], Path(first).name))
        if draw(st.integers(0, 7)) == 0:
            options = draw(st.sampled_from([{"free": True}, {"root_slides": True}]))
            files[OPTIONS] = json.dumps(options).encode()
        return files

    return inputs()


_OPENED: list[tuple[str, int]] = []
_RECORD = [False]
#: An open with one of these flags never waits on a FIFO (the reader's: ``meshtool/files/safeopen.py``).
_NO_WAIT = os.O_NONBLOCK | getattr(os, "O_DIRECTORY", 0)


def _hook(event: str, args: tuple[Any, ...]) -> None:
    if _RECORD[0] and event == "open" and args and isinstance(args[0], (str, bytes, os.PathLike)):
        flags = args[2] if len(args) > 2 and isinstance(args[2], int) else 0
        _OPENED.append((os.fsdecode(args[0]), flags))


def _outside(folder: Path) -> Path:
    """The folder outside every input (``@OUTSIDE@``), made once, with ``secret.obj``."""
    outside = folder.parent / "outside"
    if not (outside / "secret.obj").is_file():
        outside.mkdir(exist_ok=True)
        (outside / "secret.obj").write_bytes(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 2 3 4\n")
    return outside


def run_mjcf(files: Files, folder: Path) -> None:
    """Write the input, build its ``MjcfRobot`` in a world rooted at ``folder``, compile and step it."""
    from targets import write_input

    from simrun.errors import SimrunError
    from simrun.robots.mjcf_robot import MjcfRobot
    from simrun.world.world import World

    if not getattr(run_mjcf, "hooked", False):
        sys.addaudithook(_hook)
        run_mjcf.hooked = True  # type: ignore[attr-defined]
    outside = _outside(folder)
    options = json.loads(files.get(OPTIONS, b"{}"))
    model = {k: v.replace(b"@OUTSIDE@", os.fsencode(outside)) for k, v in files.items() if k != OPTIONS}
    first = write_input(model, folder)
    if hasattr(os, "mkfifo") and not (first.parent / "pipe").exists():
        os.mkfifo(first.parent / "pipe")
    if not (first.parent / "link.obj").exists():
        (first.parent / "link.obj").symlink_to(outside / "secret.obj")
    _OPENED.clear()
    _RECORD[0] = True
    try:
        world = World(base_dir=folder)
        world.insert(MjcfRobot(name="robot", file=first.relative_to(folder).as_posix(), **options))
        world.compile()
        world.step(10)
    except SimrunError as exc:
        text = str(exc)
        if not text.strip() or "\n" in text.strip():
            raise MultiLineError(f"{type(exc).__name__} of {len(text.splitlines())} lines: {text[:2000]!r}") from exc
        raise
    finally:
        _RECORD[0] = False
        forbidden = [
            p
            for p, flags in _OPENED
            if (os.path.basename(p) == "pipe" and not flags & _NO_WAIT)
            or p.startswith(("/dev/", "/proc/", "/etc/"))
            or Path(os.path.abspath(p)).is_relative_to(outside)
        ]
        if forbidden:
            raise OpenedOutside(f"opened {forbidden[:5]}")
