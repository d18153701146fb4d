"""simrun's file outputs: atomic (temporary file, then a rename) and never over what simrun did not write.

Every simrun writer goes through :func:`write_bytes`, which applies meshtool's rules
(:func:`meshtool.files.outdir.check_output`): an output path that is one of the run's inputs is always refused;
an existing file is replaced only when it is a meshtool/simrun output of the kind its suffix names, or
when forced. The CLI sets the policy for a command with :func:`output_policy` (``--force`` and the
command's inputs); library callers may pass ``force``/``inputs`` to :func:`check_output` directly.

A run's inputs are the files it names (scene, recording, commands) and every file its worlds read
(:func:`world_inputs`: textures, meshes, imported models and what MuJoCo read for them). A command registers
each world it loads with :func:`reading` (or passes ``world=``), and checks all its outputs with
:func:`refuse_inputs` once the world is built, before the first byte of any output is written. The rule is
meshtool's (:func:`meshtool.files.outdir.refuse_inputs`: the same path, a symbolic link, a hard link, a case
alias); the refusal is one line naming the output, the input and which of these it is (exit 1).

Kinds are recognised by suffix through the formats registry (:data:`meshtool.formats.OUTPUTS`, its table
in ``docs/formats.md``): by the generator recorded inside where the format has room (``.mbin``, GLB,
glTF, USD, HTML), by magic number or root element where it has none (PNG, GIF, MP4, MJCF XML, ``.mjz``,
``.simlog``: a file of the same kind is replaced, documented in README "Outputs").

Anything else that exists is replaced only when its bytes are already those to be written.
"""

from __future__ import annotations

import contextlib
import contextvars
import dataclasses
import os
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from meshtool import __version__
from meshtool.errors import OutputError
from meshtool.files.outdir import check_output as meshtool_check_output
from meshtool.files.outdir import refuse_inputs as meshtool_refuse_inputs
from meshtool.files.outdir import write_file
from simrun.errors import SimrunError

GENERATOR = f"simrun (meshtool {__version__})"


@dataclass
class _Policy:
    """One command's output policy: ``--force``, the files it names and the worlds it loaded."""

    force: bool = False
    inputs: list[Path] = field(default_factory=list)
    worlds: list[Any] = field(default_factory=list)

    def every_input(self) -> list[Path]:
        """The named inputs and every file the worlds read, evaluated now (a world read more as it built)."""
        return [*self.inputs, *(path for world in self.worlds for path in world_inputs(world))]


_POLICY: contextvars.ContextVar[_Policy | None] = contextvars.ContextVar("simrun_output_policy", default=None)


@contextlib.contextmanager
def output_policy(force: bool = False, inputs: Iterable[Path | str | None] = ()) -> Iterator[None]:
    """Within the block, :func:`write_bytes` refuses ``inputs`` always and other files unless ``force``.

    Worlds registered with :func:`reading` inside the block add every file they read to ``inputs``.

    Args:
        force: Replace existing files that simrun did not write (``--force``); never an input.
        inputs: Files the command reads (scene, recording, commands); ``None`` entries are skipped.
    """
    token = _POLICY.set(_Policy(force, [Path(p) for p in inputs if p is not None]))
    try:
        yield
    finally:
        _POLICY.reset(token)


def reading(world: Any, *paths: Path | str | None, scene: Path | None = None) -> Any:
    """Count every file ``world`` reads, ``paths`` and ``scene``'s files as inputs of the current command.

    Within :func:`output_policy`; outside one it does nothing (pass ``world=`` to the checks instead).

    Args:
        world: A world the command loaded.
        paths: More files the command reads (a commands file); ``None`` entries are skipped.
        scene: The scene file the world came from (:func:`scene_files`).

    Returns:
        ``world``.
    """
    policy = _POLICY.get()
    if policy is not None:
        policy.worlds.append(world)
        policy.inputs.extend(Path(p) for p in (*paths, *(scene_files(scene) if scene is not None else ())) if p)
    return world


def scene_files(scene: Path) -> list[Path]:
    """The scene file and the file its ``[test]`` table names (``commands``: TOML or ``.py``), neither to be replaced.

    What the world loaded from the scene reads is :func:`world_inputs`'; a scene that cannot be read gives
    only itself (loading it names the problem).
    """
    from simrun.scene.tomlpos import read_toml

    found = [Path(scene)]
    try:
        table = read_toml(Path(scene), "scene")[0].get("test")
    except SimrunError:
        return found
    name = table.get("commands") if isinstance(table, dict) else None
    if isinstance(name, str) and name:
        found.append(Path(scene).parent / name)
    return found


def world_inputs(world: Any) -> list[Path]:
    """Every file ``world`` read or names, real paths: nothing an output may replace.

    ``World.files_read()`` (its builds: ``.mbin`` and mesh assets, images, URDF and MJCF models with every
    include, mesh, texture, height field and skin the MJCF reader read for MuJoCo), and every existing file
    its asset table and its entities' text fields name, relative to its base folder: these cover a world
    whose model came from the compiled-model cache, whose build read nothing. Before the first build only
    the named files are known: check outputs after ``world.compile()`` (or ``world.model``).
    """
    found: list[Path] = [Path(p) for p in world.files_read()]
    base = Path(world.base_dir)
    names = {str(v) for v in getattr(world, "assets", {}).values()}
    for _, entity in world:
        if dataclasses.is_dataclass(entity):
            for item in dataclasses.fields(entity):
                value = getattr(entity, item.name, None)
                if item.name not in ("name", "parent") and isinstance(value, str | Path) and str(value):
                    names.add(str(value))
    for name in sorted(names):
        try:
            candidate = base / name
            if os.path.isfile(candidate):
                found.append(Path(os.path.realpath(candidate)))
        except (OSError, ValueError):
            continue
    return list(dict.fromkeys(found))


def _inputs(inputs: Iterable[Path | str | None], world: Any) -> list[Path]:
    policy = _POLICY.get()
    every = policy.every_input() if policy is not None else []
    every.extend(Path(p) for p in inputs if p is not None)
    if world is not None:
        every.extend(world_inputs(world))
    return every


def refuse_inputs(outputs: Iterable[Path | None], *, inputs: Iterable[Path] = (), world: Any = None) -> None:
    """Refuse every output that is an input, before any is written (meshtool's rule; ``--force`` or not).

    Args:
        outputs: The files the command will write; ``None`` entries are skipped.
        inputs: Files the run reads, added to those of :func:`output_policy` and its :func:`reading` worlds.
        world: A world whose files (:func:`world_inputs`) are inputs too.

    Raises:
        SimrunError: One line: the output, the input it would replace and how (same path, symbolic link,
            hard link, case alias).
    """
    every = _inputs(inputs, world)
    for path in outputs:
        if path is None:
            continue
        try:
            meshtool_refuse_inputs(Path(path), every)
        except OutputError as exc:
            raise SimrunError(exc.one_line()) from None


def check_output(
    path: Path,
    *,
    force: bool | None = None,
    inputs: Iterable[Path] = (),
    data: bytes | None = None,
    world: Any = None,
) -> None:
    """Refuse to write ``path`` when it is an input, or an existing file simrun/meshtool did not write.

    Args:
        path: The file about to be written.
        force: Replace a file of another kind (never an input); ``None`` uses :func:`output_policy`.
        inputs: Files the run reads, added to those of :func:`output_policy` and its :func:`reading` worlds.
        data: The bytes about to be written (an existing file with exactly these bytes may be replaced).
        world: A world whose files (:func:`world_inputs`) are inputs too.

    Raises:
        SimrunError: One line naming the file and how to proceed.
    """
    policy = _POLICY.get()
    force = (policy.force if policy is not None else False) if force is None else force
    every_input = _inputs(inputs, world)
    try:
        meshtool_check_output(path, None, force=force, inputs=every_input, data=data, any_of_kind=True)
    except OutputError as exc:
        raise SimrunError(exc.one_line()) from None
    except OSError as exc:
        raise SimrunError(f"{path}: cannot check the existing output: {exc.strerror}") from None


def write_bytes(path: Path, data: bytes, *, world: Any = None) -> None:
    """Write ``data`` to ``path`` atomically, after :func:`check_output` (``world``: its files are inputs too).

    Raises:
        SimrunError: The output is refused, or the folder cannot be written.
    """
    check_output(path, data=data, world=world)
    try:
        write_file(path, data)
    except OutputError as exc:
        raise SimrunError(exc.one_line()) from None


def write_text(path: Path, text: str, *, world: Any = None) -> None:
    """Write UTF-8 text atomically (see :func:`write_bytes`)."""
    write_bytes(path, text.encode("utf-8"), world=world)


def stamp_glb(tree: dict[str, Any]) -> None:
    """Record simrun as a GLB's ``asset.generator`` (a ``tree_postprocessor`` for trimesh's export)."""
    tree.setdefault("asset", {"version": "2.0"})["generator"] = GENERATOR
