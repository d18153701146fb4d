"""Fuzz targets: each reader as a user reaches it, its seeds from ``fixtures/``, and the errors it may raise.

A target takes one input (a dict of file name -> bytes; the first entry is the file handed to the reader),
writes it into a fresh folder and runs the reader the way the CLI does. Raising the package's documented
error base class (:class:`meshtool.errors.MeshtoolError`, :class:`simrun.errors.SimrunError`) is a clean
refusal; any other exception is a crash.

Targets:
    obj: ``meshtool.normalise.prepare`` on a mutated OBJ beside its fixture MTLs and textures.
    mtl: the same with the OBJ kept and one of its MTLs mutated.
    mbin: ``packfile.parse(verify=True)`` then what ``info``, ``unpack`` and ``export`` do with the pack.
    scene: ``simrun.scene.load_scene`` then ``World.compile`` (what ``simrun check`` does), beside copies of
        the fixture scenes' assets.
    simlog: ``simrun.simlog.Simlog`` and every reading method, on recordings made from the fixture scenes.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hypothesis import strategies as st
from mutate import (
    MTL_TOKENS,
    OBJ_TOKENS,
    SIMLOG_TOKENS,
    TOML_TOKENS,
    mutated_bytes,
    mutated_json,
    mutated_pack,
    mutated_toml,
)

REPO = Path(__file__).resolve().parents[2]
FIXTURES = REPO / "fixtures"
Files = dict[str, bytes]
#: Seed files larger than this are left out (fuzzing wants many fast inputs).
MAX_SEED_BYTES = 256 * 1024


@dataclass
class Target:
    """A reader under fuzz.

    Attributes:
        name: Target name (also the folder under ``fixtures/fuzz/``).
        seeds: Called once with a scratch folder; returns the seed inputs.
        strategy: Builds the hypothesis strategy of inputs from the seeds.
        run: Feeds one input (written under a fresh folder) to the reader.
        allowed: Returns the exception classes that are clean refusals (imported when the target runs).
    """

    name: str
    seeds: Callable[[Path], list[Files]]
    strategy: Callable[[list[Files]], Any]
    run: Callable[[Files, Path], None]
    allowed: Callable[[], tuple[type[BaseException], ...]]


def write_input(files: Files, folder: Path) -> Path:
    """Write an input's files under ``folder``; returns the first (the file handed to the reader)."""
    first = None
    for name, data in files.items():
        path = folder / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)
        first = first or path
    assert first is not None
    return first


# -- OBJ / MTL ---------------------------------------------------------------------------------------------


def _obj_seeds(_scratch: Path) -> list[Files]:
    seeds = []
    for obj in sorted(FIXTURES.rglob("*.obj")):
        if "fuzz" in obj.relative_to(FIXTURES).parts or obj.stat().st_size > MAX_SEED_BYTES:
            continue
        files = {obj.name: obj.read_bytes()}
        for other in sorted(obj.parent.rglob("*")):
            wanted = other.is_file() and other != obj and other.suffix.lower() not in (".obj", ".mbin")
            if wanted and other.stat().st_size <= MAX_SEED_BYTES:
                files[other.relative_to(obj.parent).as_posix()] = other.read_bytes()
        seeds.append(files)
    return seeds


def _obj_strategy(seeds: list[Files]) -> Any:
    @st.composite
    def inputs(draw: Any) -> Files:
        files = dict(draw(st.sampled_from(seeds)))
        first = next(iter(files))
        files[first] = draw(mutated_bytes(files[first], OBJ_TOKENS))
        return files

    return inputs()


def _mtl_strategy(seeds: list[Files]) -> Any:
    with_mtl = [s for s in seeds if any(n.lower().endswith(".mtl") for n in s)]

    @st.composite
    def inputs(draw: Any) -> Files:
        files = dict(draw(st.sampled_from(with_mtl)))
        mtl = draw(st.sampled_from(sorted(n for n in files if n.lower().endswith(".mtl"))))
        files[mtl] = draw(mutated_bytes(files[mtl], MTL_TOKENS))
        return files

    return inputs()


def _run_obj(files: Files, folder: Path) -> None:
    from meshtool.normalise import NormaliseOptions, prepare

    prepare(write_input(files, folder), NormaliseOptions())


# -- .mbin -------------------------------------------------------------------------------------------------


def _mbin_seeds(_scratch: Path) -> list[Files]:
    return [
        {"asset.mbin": p.read_bytes()}
        for p in sorted(FIXTURES.rglob("*.mbin"))
        if "fuzz" not in p.relative_to(FIXTURES).parts and p.stat().st_size <= 4 * MAX_SEED_BYTES
    ]


def _mbin_strategy(seeds: list[Files]) -> Any:
    @st.composite
    def inputs(draw: Any) -> Files:
        seed = draw(st.sampled_from(seeds))["asset.mbin"]
        return {"asset.mbin": draw(mutated_pack(seed))}

    return inputs()


def _run_mbin(files: Files, folder: Path) -> None:
    from meshtool.packfile import load
    from meshtool.packfile.export import describe, to_glb, to_msh, unpack_files

    path = write_input(files, folder)
    with load(path, verify=True) as packed:
        describe(packed)
        unpack_files(packed, "asset")
        to_msh(packed)
        to_glb(packed)


# -- scenes ------------------------------------------------------------------------------------------------


def _scene_seeds(_scratch: Path) -> list[Files]:
    return [{p.name: p.read_bytes()} for p in sorted((FIXTURES / "scenes").glob("*.toml")) if "commands" not in p.name]


def _scene_strategy(seeds: list[Files]) -> Any:
    @st.composite
    def inputs(draw: Any) -> Files:
        name, data = next(iter(draw(st.sampled_from(seeds)).items()))
        if draw(st.booleans()):  # values changed in a document that still parses: reaches the loader's checks
            return {f"scenes/{name}": draw(mutated_toml(data))}
        return {f"scenes/{name}": draw(mutated_bytes(data, TOML_TOKENS))}

    return inputs()


def _run_scene(files: Files, folder: Path) -> None:
    from simrun.scene import load_scene

    assets = folder.parent / "scene-assets"  # the files the fixture scenes name, at the same relative places
    if not assets.is_dir():
        for sub in ("scenes", "urdf"):
            shutil.copytree(FIXTURES / sub, assets / sub, ignore=shutil.ignore_patterns("*.toml"))
    ((name, data),) = files.items()
    scene = assets / name
    scene.write_bytes(data)
    world = load_scene(scene)
    world.compile()


# -- .simlog -----------------------------------------------------------------------------------------------


def _simlog_seeds(scratch: Path) -> list[Files]:
    """Short recordings of the fixture scenes (made once per run with ``simrun play --record``)."""
    seeds = []
    plays = [
        ("boebot.toml", ["--commands", str(FIXTURES / "scenes" / "square.commands.toml"), "--duration", "1.2"]),
        ("basic.toml", ["--duration", "1.1"]),
    ]
    for scene, extra in plays:
        out = scratch / f"{Path(scene).stem}.simlog"
        command = [sys.executable, "-c", "from simrun.cli import main; main()", "play"]
        command += [str(FIXTURES / "scenes" / scene), "--record", str(out), *extra]
        env = dict(os.environ, MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"))
        subprocess.run(command, capture_output=True, check=False, timeout=300, env=env)
        if out.is_file():
            seeds.append({"run.simlog": out.read_bytes()})
    return seeds


def _simlog_strategy(seeds: list[Files]) -> Any:
    @st.composite
    def inputs(draw: Any) -> Files:
        data = draw(st.sampled_from(seeds))["run.simlog"]
        # the header is JSON after 16 bytes: mutate it as text half of the time, the records otherwise
        if len(data) > 16 and draw(st.integers(0, 2)):
            length = int.from_bytes(data[12:16], "little")
            original = data[16 : 16 + length]
            structured = draw(st.booleans())
            header = mutated_json(draw, original) if structured else draw(mutated_bytes(original, SIMLOG_TOKENS, 4))
            fix = structured or draw(st.booleans())
            size = len(header).to_bytes(4, "little") if fix else data[12:16]
            return {"run.simlog": data[:12] + size + header + data[16 + length :]}
        return {"run.simlog": draw(mutated_bytes(data, SIMLOG_TOKENS, 6))}

    return inputs()


def _run_simlog(files: Files, folder: Path) -> None:
    from simrun.simlog import Simlog

    log = Simlog(write_input(files, folder))
    try:
        dict(log.header)
        log.commands()
        for _ in log.records():
            pass
        for _ in log.sensor_readings():
            pass
    finally:
        with contextlib.suppress(Exception):
            log.close()


def _meshtool_errors() -> tuple[type[BaseException], ...]:
    from meshtool.errors import MeshtoolError

    return (MeshtoolError,)


def _simrun_errors() -> tuple[type[BaseException], ...]:
    from simrun.errors import SimrunError

    return (SimrunError,)


def targets() -> dict[str, Target]:
    """Every target by name."""
    return {
        "obj": Target("obj", _obj_seeds, _obj_strategy, _run_obj, _meshtool_errors),
        "mtl": Target("mtl", _obj_seeds, _mtl_strategy, _run_obj, _meshtool_errors),
        "mbin": Target("mbin", _mbin_seeds, _mbin_strategy, _run_mbin, _meshtool_errors),
        "scene": Target("scene", _scene_seeds, _scene_strategy, _run_scene, _simrun_errors),
        "simlog": Target("simlog", _simlog_seeds, _simlog_strategy, _run_simlog, _simrun_errors),
    }
