"""Fuzz targets: each reader as a user reaches it, its seeds from ``fixtures/``, and the errors it may raise.

A target takes one input (a dict of file name -> bytes; the first entry is the file handed to the reader),
writes it into a fresh folder and runs the reader the way the CLI does. Raising the package's documented
error base class (:class:`meshtool.errors.MeshtoolError`, :class:`simrun.errors.SimrunError`) is a clean
refusal; any other exception is a crash.

Targets:
    obj: ``meshtool.repair.normalise.prepare`` on a mutated OBJ beside its fixture MTLs and textures.
    mtl: the same with the OBJ kept and one of its MTLs mutated.
    mbin: ``packfile.parse(verify=True)`` then what ``info``, ``unpack`` and ``export`` do with the pack.
    scene: ``simrun.scene.scene_file.load_scene`` then ``World.compile`` (what ``simrun check`` does), beside copies of
        the fixture scenes' assets.
    simlog: ``simrun.record.simlog.Simlog`` and every reading method, on recordings made from the fixture scenes.
    stl, ply, gltf, glb, collada: ``meshtool.repair.normalise.prepare`` (as ``meshtool normalize`` reaches it) on a
        mutated mesh file beside the buffers and textures it names; seeds: every fixture of the format (PLY
        also re-encoded as ASCII and both binary byte orders; glTF also with every file as a ``data:`` URI;
        the ``.gltf`` fixtures also packed as GLB).
    urdf: ``meshtool.urdf.import_robot.import_urdf`` then the model's MJCF build and compile (what
        ``meshtool urdf`` does, without writing), on a mutated fixture URDF inside its package (meshes,
        ``package.xml``) with the files beside the package.
    commands: ``simrun.run.commands.load_commands`` then, against the fixture scene it names
        (``SCENE.commands.toml``), the service bindings, ``check_commands`` and each command applied in
        time order (what ``simrun play SCENE --commands FILE`` does).
    mjcf: an ``MjcfRobot`` of a mutated MJCF model in a ``World``, compiled and stepped (what ``simrun check``
        does with a scene naming it; the model read by ``simrun/robots/mjcf_read.py``): :mod:`target_mjcf`.
"""

from __future__ import annotations

import base64
import contextlib
import json
import os
import shutil
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from urllib.parse import quote, unquote

from hypothesis import strategies as st
from mutate import (
    COMMAND_TOKENS,
    COMMAND_VALUES,
    MTL_TOKENS,
    OBJ_TOKENS,
    SIMLOG_TOKENS,
    TOML_TOKENS,
    mutated_buffer,
    mutated_bytes,
    mutated_document_json,
    mutated_json,
    mutated_pack,
    mutated_toml,
)
from mutate_mesh import (
    GLB_BIN,
    GLB_JSON,
    GLTF_TOKENS,
    GLTF_VALUES,
    join_glb,
    mutated_glb,
    mutated_ply,
    mutated_stl,
    reencode_ply,
)
from mutate_xml import COLLADA_ATTRIBUTES, URDF_ATTRIBUTES, collada_special, mutated_xml, urdf_special
from target_mjcf import mjcf_seeds, mjcf_strategy, run_mjcf

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
    from meshtool.repair.normalise import NormaliseOptions, prepare

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
    from simrun.scene.scene_file import load_scene

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
        command = [sys.executable, "-c", "from simrun.cli.main import main; main()", "play"]
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
    from simrun.record.simlog import Simlog

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


# -- STL, PLY, glTF/GLB, COLLADA: meshtool.repair.normalise.prepare picks the reader by suffix ------------------------


def _format_seeds(suffixes: tuple[str, ...], companions: tuple[str, ...]) -> list[Files]:
    """Every fixture with one of ``suffixes`` (identical files once), with the ``companions`` it names."""
    seeds, seen = [], set()
    for path in sorted(FIXTURES.rglob("*")):
        if path.suffix.lower() not in suffixes or not path.is_file() or path.stat().st_size > MAX_SEED_BYTES:
            continue
        if "fuzz" in path.relative_to(FIXTURES).parts or path.read_bytes() in seen:
            continue
        seen.add(path.read_bytes())
        files = {path.name: path.read_bytes()}
        for other in sorted(path.parent.rglob("*")):  # the files it names (a glTF buffer, a texture)
            name = other.relative_to(path.parent).as_posix()
            named = name.encode() in files[path.name] or quote(name).encode() in files[path.name]
            if named and other.suffix.lower() in companions and other.stat().st_size <= MAX_SEED_BYTES:
                files[name] = other.read_bytes()
        seeds.append(files)
    return seeds


def _first_mutated(seeds: list[Files], mutation: Callable[[bytes], Any]) -> Any:
    """Inputs: a seed with its first file (the one handed to the reader) mutated by ``mutation(data)``."""

    @st.composite
    def inputs(draw: Any) -> Files:
        files = dict(draw(st.sampled_from(seeds)))
        first = next(iter(files))
        files[first] = draw(mutation(files[first]))
        return files

    return inputs()


def _stl_seeds(_scratch: Path) -> list[Files]:
    return _format_seeds((".stl",), ())


def _stl_strategy(seeds: list[Files]) -> Any:
    return _first_mutated(seeds, mutated_stl)


def _ply_seeds(_scratch: Path) -> list[Files]:
    """The PLY fixtures, each also re-encoded in the other two formats (ASCII, little and big endian)."""
    seeds, seen = [], set()
    for files in _format_seeds((".ply",), (".png", ".jpg")):
        name, data = next(iter(files.items()))
        for fmt in ("ascii", "binary_little_endian", "binary_big_endian"):
            encoded = reencode_ply(data, fmt)
            if encoded is not None and encoded not in seen:
                seen.add(encoded)
                seeds.append({name: encoded, **{k: v for k, v in files.items() if k != name}})
        if data not in seen:
            seen.add(data)
            seeds.append(files)
    return seeds


def _ply_strategy(seeds: list[Files]) -> Any:
    return _first_mutated(seeds, mutated_ply)


def _data_uri(data: bytes, mime: str) -> str:
    return f"data:{mime};base64,{base64.b64encode(data).decode('ascii')}"


def _gltf_seeds(_scratch: Path) -> list[Files]:
    """The ``.gltf`` fixtures with their ``.bin`` and images, and each also with every file as a ``data:`` URI."""
    seeds = _format_seeds((".gltf",), (".bin", ".png", ".jpg"))
    for files in list(seeds):
        name, data = next(iter(files.items()))
        doc = json.loads(data)
        embedded = 0
        for key, mime in (("buffers", "application/octet-stream"), ("images", "image/png")):
            for item in doc.get(key, []):
                uri = unquote(str(item.get("uri", "")))
                if uri in files:
                    item["uri"] = _data_uri(files[uri], mime)
                    embedded += 1
        if embedded:
            seeds.append({name.replace(".gltf", "_embedded.gltf"): json.dumps(doc, indent=1).encode()})
    return seeds


def _gltf_strategy(seeds: list[Files]) -> Any:
    @st.composite
    def inputs(draw: Any) -> Files:
        files = dict(draw(st.sampled_from(seeds)))
        name = next(iter(files))
        for _ in range(draw(st.integers(1, 2))):
            op = draw(st.sampled_from(["json", "json", "json", "text", "bin", "data_uri"]))
            if op == "json":
                files[name] = mutated_document_json(draw, files[name], GLTF_VALUES)
            elif op == "text":
                files[name] = draw(mutated_bytes(files[name], GLTF_TOKENS, 4))
            elif op == "bin" and any(n.endswith(".bin") for n in files):
                bin_name = draw(st.sampled_from(sorted(n for n in files if n.endswith(".bin"))))
                files[bin_name] = draw(mutated_buffer(files[bin_name]))
            elif op == "data_uri":  # a data: buffer's bytes changed, written back as base64
                try:
                    doc = json.loads(files[name])
                    buffers = [b for b in doc.get("buffers", []) if str(b.get("uri", "")).startswith("data:")]
                except (ValueError, AttributeError, TypeError):
                    continue
                if buffers:
                    buffer = draw(st.sampled_from(buffers))
                    head, _, payload = buffer["uri"].partition(",")
                    raw = base64.b64decode(payload) if head.endswith(";base64") else b""
                    buffer["uri"] = _data_uri(draw(mutated_buffer(raw)), "application/octet-stream")
                    files[name] = json.dumps(doc).encode()
        return files

    return inputs()


def _glb_seeds(_scratch: Path) -> list[Files]:
    """The ``.glb`` fixtures, and the ``.gltf`` fixtures with one buffer packed as a GLB (images kept as files)."""
    seeds = _format_seeds((".glb",), (".png", ".jpg"))
    for files in _format_seeds((".gltf",), (".bin", ".png", ".jpg")):
        name, data = next(iter(files.items()))
        doc = json.loads(data)
        buffers = doc.get("buffers", [])
        uri = unquote(str(buffers[0].get("uri", ""))) if len(buffers) == 1 else ""
        if uri in files:
            del buffers[0]["uri"]
            packed = join_glb(2, [(GLB_JSON, json.dumps(doc).encode()), (GLB_BIN, files[uri])])
            rest = {k: v for k, v in files.items() if k not in (name, uri)}
            seeds.append({name.replace(".gltf", ".glb"): packed, **rest})
    return seeds


def _glb_strategy(seeds: list[Files]) -> Any:
    return _first_mutated(seeds, mutated_glb)


def _collada_seeds(_scratch: Path) -> list[Files]:
    return _format_seeds((".dae",), (".png", ".jpg"))


def _collada_strategy(seeds: list[Files]) -> Any:
    return _first_mutated(seeds, lambda data: mutated_xml(data, COLLADA_ATTRIBUTES, collada_special))


# -- URDF ------------------------------------------------------------------------------------------------------


def _urdf_seeds(_scratch: Path) -> list[Files]:
    """Each fixture URDF as ``PACKAGE/urdf/NAME.urdf`` with its package's files and the files beside the package
    (``fixtures/urdf/secret.stl``: what an escaping path would reach)."""
    seeds = []
    for urdf in sorted(FIXTURES.rglob("*.urdf")):
        if "fuzz" in urdf.relative_to(FIXTURES).parts or urdf.stat().st_size > MAX_SEED_BYTES:
            continue
        package = urdf.parent.parent if urdf.parent.name == "urdf" else urdf.parent
        base = package.parent
        files = {urdf.relative_to(base).as_posix(): urdf.read_bytes()}
        for other in [*sorted(package.rglob("*")), *sorted(base.glob("*"))]:
            if other.is_file() and other.suffix != ".urdf" and other.stat().st_size <= MAX_SEED_BYTES:
                files.setdefault(other.relative_to(base).as_posix(), other.read_bytes())
        seeds.append(files)
    return seeds


def _urdf_strategy(seeds: list[Files]) -> Any:
    @st.composite
    def inputs(draw: Any) -> Files:
        files = dict(draw(st.sampled_from(seeds)))
        first = next(iter(files))
        special = urdf_special(first.split("/")[0])
        files[first] = draw(mutated_xml(files[first], URDF_ATTRIBUTES, special))
        return files

    return inputs()


def _run_urdf(files: Files, folder: Path) -> None:
    import logging

    from meshtool.urdf.import_robot import UrdfOptions, import_urdf

    logging.getLogger("yourdfpy").setLevel(logging.CRITICAL)  # its parse-error log lines, once per input
    result = import_urdf(write_input(files, folder), UrdfOptions())  # what `meshtool urdf` does, then
    result.mjcf()  # the model built and compiled by the MJCF builder (write_import without writing)


# -- simrun commands files ---------------------------------------------------------------------------------------

#: Commands for the arm and base of ``arm_on_base.toml`` (the fixture commands file drives only a Boe-Bot).
_ARM_COMMANDS = b"""[[commands]]
t = 0.0
service = "ArmService"
entity = "base/arm"
call = "move_to"
args = [[0.5, -0.3, 0.8, 0.2, 0.0, 0.01], 0.5]

[[commands]]
t = 0.3
service = "ArmService"
entity = "base/arm"
call = "set_joint_targets"
args = [[0.0, 0.1, 0.2, 0.3, 0.4, 0.0]]

[[commands]]
t = 0.4
entity = "base"
call = "cmd_vel"
args = [0.1, 0.2]

[[commands]]
t = 0.5
entity = "base"
call = "all_stop"
"""


def _commands_seeds(_scratch: Path) -> list[Files]:
    """``SCENE.commands.toml`` inputs run against ``fixtures/scenes/SCENE.toml``: the fixture commands file
    for ``boebot.toml`` and retargeted to ``pioneer_room.toml``'s robot, and arm commands for ``arm_on_base``."""
    square = (FIXTURES / "scenes" / "square.commands.toml").read_bytes()
    return [
        {"boebot.commands.toml": square},
        {"pioneer_room.commands.toml": square.replace(b'"boebot"', b'"p3dx"')},
        {"arm_on_base.commands.toml": _ARM_COMMANDS},
    ]


def _commands_strategy(seeds: list[Files]) -> Any:
    @st.composite
    def inputs(draw: Any) -> Files:
        ((name, data),) = draw(st.sampled_from(seeds)).items()
        if draw(st.booleans()):
            return {name: draw(mutated_toml(data, COMMAND_VALUES))}
        return {name: draw(mutated_bytes(data, COMMAND_TOKENS))}

    return inputs()


def _run_commands(files: Files, folder: Path) -> None:
    from simrun.run.commands import check_commands, load_commands
    from simrun.run.session import prepare
    from simrun.scene.scene_file import load_scene

    path = write_input(files, folder)
    commands = load_commands(path)  # what `simrun play SCENE --commands FILE` reads, then
    world = load_scene(FIXTURES / "scenes" / path.name.replace(".commands.toml", ".toml"))
    prepare(world)
    check_commands(world, commands)  # as play() does before the run
    for command in commands:  # and each command applied in time order, a few steps apart
        command.apply(world)
        world.step(5)


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
        "stl": Target("stl", _stl_seeds, _stl_strategy, _run_obj, _meshtool_errors),
        "ply": Target("ply", _ply_seeds, _ply_strategy, _run_obj, _meshtool_errors),
        "gltf": Target("gltf", _gltf_seeds, _gltf_strategy, _run_obj, _meshtool_errors),
        "glb": Target("glb", _glb_seeds, _glb_strategy, _run_obj, _meshtool_errors),
        "collada": Target("collada", _collada_seeds, _collada_strategy, _run_obj, _meshtool_errors),
        "urdf": Target("urdf", _urdf_seeds, _urdf_strategy, _run_urdf, _meshtool_errors),
        "commands": Target("commands", _commands_seeds, _commands_strategy, _run_commands, _simrun_errors),
        "mjcf": Target("mjcf", mjcf_seeds, mjcf_strategy, run_mjcf, _simrun_errors),
    }
