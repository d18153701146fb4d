"""Write a ``.simlog`` as files anyone can watch: animated GLB / glTF, animated USD, an HTML player.

One kinematic replay of the recording (each frame's state through ``mj_forward``, in the recorded scene,
refused when the scene changed since) feeds every output; a recording with edits (``simrun serve --edit``) is
replayed with its edits applied and shows every body for its lifetime
(:mod:`simrun.record.replay_edits`). ``simrun replay --glb/--gltf/--usd/--html`` and
``simrun play --record RUN.simlog --record-as glb,html`` call :func:`export_recording`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

from meshtool.files.safeopen import printable
from meshtool.formats import check_suffix, output_named
from simrun.errors import SimrunError
from simrun.outfile import refuse_inputs, scene_files, write_bytes, write_text
from simrun.record.replay_edits import edited_gltf, edited_replay
from simrun.record.replay_glb import recording_gltf
from simrun.record.replay_html import recording_html, viewer_bundle
from simrun.record.replay_tracks import animation_keys, read_tracks
from simrun.record.replay_usd import export_recording_usd
from simrun.record.simlog import Simlog, check_model, check_scene
from simrun.scene.scene_file import load_scene

#: The outputs of the formats registry (:data:`meshtool.formats.OUTPUTS`) a recording is exported to.
KINDS = ("glb", "gltf", "usd", "html")


def _record_formats() -> dict[str, str]:
    """``--record-as`` names: each kind (its own suffix, else its first) and each other suffix of a kind."""
    names: dict[str, str] = {}
    for kind in KINDS:
        suffixes = output_named(kind).suffixes
        names[kind] = f".{kind}" if f".{kind}" in suffixes else suffixes[0]
        names.update({s[1:]: s for s in suffixes if s[1:] not in names})
    return names


#: Formats by name (``--record-as``) and the suffix each writes.
FORMATS = _record_formats()
#: Default bound on the pose error of decimated animations, metres and radians.
TOLERANCE = 1e-3


@dataclass(frozen=True)
class Written:
    """One output: its path, size in bytes, seconds spent writing it, and keyframes per moving body."""

    path: Path
    size: int
    seconds: float
    keyframes: int


def export_recording(
    log_path: Path,
    outputs: dict[str, Path],
    fps: float | None = None,
    tolerance: float = TOLERANCE,
) -> list[Written]:
    """Replay ``log_path`` once and write each requested output.

    Args:
        log_path: The ``.simlog``.
        outputs: Format (``glb``, ``gltf``, ``usd``, ``html``) to output path; USD takes ``.usd``,
            ``.usda`` or ``.usdc``.
        fps: Keyframe rate of the animation; ``None`` keys every recorded frame.
        tolerance: With ``fps``, the largest pose error between keyframes (metres and radians).

    Returns:
        What was written, in the order of ``outputs``.

    Raises:
        SimrunError: A bad recording, a changed scene, a refused output or a missing viewer bundle.
    """
    for kind, path in outputs.items():
        if kind not in KINDS:
            raise SimrunError(f"unknown output format {kind!r} (known: {', '.join(KINDS)})")
        wrong = check_suffix(path, kind)
        if wrong is not None:
            raise SimrunError(f"{path}: {wrong}")
    if "html" in outputs:
        viewer_bundle()  # a missing bundle fails before the replay, not after the other outputs
    recording = Simlog(log_path)
    try:
        scene = recording.scene_path()
        check_scene(recording, scene)
        world = load_scene(scene)
        world.compile()
        check_model(recording, world)
        refuse_inputs(outputs.values(), inputs=[log_path, *scene_files(scene)], world=world)  # before any is written
        edited = edited_replay(scene, recording)  # simrun serve --edit: the edited world (replay_edits)
        if edited is not None:
            world = edited.world
        tracks = read_tracks(world, recording) if edited is None else edited.tracks
    finally:
        recording.close()
    keys = animation_keys(tracks, fps, tolerance, tolerance)
    count = max((len(k) for k in keys.values()), default=0)
    written = []
    for kind, path in outputs.items():
        start = time.perf_counter()
        gltf = (lambda: recording_gltf(world, tracks, keys)) if edited is None else (lambda: edited_gltf(edited, keys))
        if kind == "glb":
            write_bytes(path, gltf().glb())
        elif kind == "gltf":
            write_bytes(path, gltf().gltf())
        elif kind == "usd":
            export_recording_usd(world, tracks, keys, path, None if edited is None else edited.alive)
        else:
            glb = None if edited is None else gltf().glb()
            write_text(path, recording_html(world, tracks, keys, printable(log_path.stem), glb))  # bytes as \xNN
        seconds = time.perf_counter() - start
        written.append(Written(path, path.stat().st_size, seconds, count))
    return written


def beside(log_path: Path, formats: str) -> dict[str, Path]:
    """Outputs named like the recording (``run.simlog`` -> ``run.glb``...) for a comma-separated format list.

    Raises:
        SimrunError: An unknown format name.
    """
    outputs: dict[str, Path] = {}
    for name in (part.strip().lower() for part in formats.split(",")):
        if not name:
            continue
        if name not in FORMATS:
            raise SimrunError(f"unknown recording format {name!r} (choose from {', '.join(FORMATS)})")
        kind = "usd" if name.startswith("usd") else name
        if kind in outputs:
            raise SimrunError(f"recording format {kind!r} given twice")
        outputs[kind] = log_path.with_suffix(FORMATS[name])
    if not outputs:
        raise SimrunError("no recording format given (choose from " + ", ".join(FORMATS) + ")")
    return outputs
