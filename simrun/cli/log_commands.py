"""The ``simrun`` commands over a recorded log: ``replay`` (video, GLB/glTF, USD, HTML, MCAP) and ``resim``.

Thin click layers over :mod:`simrun.record`, registered on the group by :mod:`simrun.cli.main`; the library is
imported inside the command that uses it.
"""

from __future__ import annotations

from pathlib import Path

import click

from meshtool.cli import output as out
from meshtool.files.safeopen import printable
from simrun.cli.types import DEFAULT_SIZE_TEXT, FPS, MODES, OUT, SECONDS, Number, _size
from simrun.errors import SimrunError
from simrun.outfile import check_output, output_policy, reading, refuse_inputs, scene_files, write_bytes


@click.command("replay")
@click.argument("log", type=click.Path(path_type=Path, dir_okay=False))
@click.option("--video", type=OUT, default=None, help="OUT.gif or OUT.mp4.")
@click.option("--glb", type=OUT, default=None, help="Animated GLB: visual meshes, one animation (Y-up, metres).")
@click.option("--gltf", type=OUT, default=None, help="The same as one .gltf file (buffers as data: URIs).")
@click.option("--usd", type=OUT, default=None, help="USD (.usd/.usda/.usdc): the physics export + time samples.")
@click.option("--html", type=OUT, default=None, help="A page that plays the recording in a browser, offline.")
@click.option("--mcap", type=OUT, default=None, help="MCAP with Foxglove schemas: body transforms, poses, sensors.")
@click.option(
    "--render-mode", type=click.Choice([m for m in MODES if m != "none"]), default="visual", show_default=True
)
@click.option("--camera", default=None, help="Camera name.")
@click.option("--size", default=DEFAULT_SIZE_TEXT, show_default=True, help="Frame size WxH.")
@click.option(
    "--fps",
    type=FPS,
    default=None,
    help="Frames per simulated second of the video (default 15); of the animations, keyframes per second "
    "(default: every recorded frame) plus those needed to stay within --tolerance.",
)
@click.option(
    "--tolerance",
    type=Number(1e-9, 1.0, low_open=True),
    default=1e-3,
    show_default=True,
    help="With --fps: the largest pose error of the animations between keyframes, metres and radians.",
)
@click.option("--force", is_flag=True, help="Replace existing outputs simrun did not write (never an input).")
def replay(
    log: Path,
    video: Path | None,
    render_mode: str,
    camera: str | None,
    size: str,
    fps: float | None,
    glb: Path | None = None,
    gltf: Path | None = None,
    usd: Path | None = None,
    html: Path | None = None,
    mcap: Path | None = None,
    tolerance: float = 1e-3,
    force: bool = False,
) -> None:
    """Replay a .simlog kinematically (the recorded poses, no physics) into a video and/or files anyone can watch.

    --glb/--gltf (three.js, Blender, any glTF viewer), --usd (usdview, Omniverse) and --html (a browser)
    animate the recorded body poses.
    """
    width, height = _size(size)
    outputs = {k: v for k, v in (("glb", glb), ("gltf", gltf), ("usd", usd), ("html", html)) if v is not None}
    if video is None and not outputs and mcap is None:
        raise click.UsageError("give --video, --glb, --gltf, --usd, --html and/or --mcap")
    _note_truncated(log)
    with output_policy(force, [log]):  # every output, before the first is written or any is otherwise checked
        _refuse_replay_inputs(log, [video, mcap, *outputs.values()])
    if mcap is not None:
        from simrun.record.mcap_export import export_mcap

        with output_policy(force, [log]):
            summary = export_mcap(log, mcap)
        topics = ", ".join(f"{topic} {n}" for topic, n in summary.messages.items())
        out.wrote(mcap, f"wrote {mcap} ({summary.size} bytes; messages: {topics}) from {printable(log)}", kind="mcap")
    if outputs:
        from simrun.record.replay_export import export_recording

        with output_policy(force, [log]):
            for item in export_recording(log, outputs, fps, tolerance):
                text = f"wrote {item.path} ({item.size} bytes, {item.keyframes} keyframes) from {printable(log)}"
                out.wrote(item.path, text, bytes=item.size, keyframes=item.keyframes)
    if video is None:
        return
    fps = 15.0 if fps is None else fps
    from simrun.record.simlog import Simlog, check_model, check_scene, replay_states
    from simrun.run.play import encode_gif, encode_mp4
    from simrun.run.render import FrameRenderer
    from simrun.run.session import video_kind
    from simrun.scene.scene_file import load_scene

    with output_policy(force, [log]):
        recording = Simlog(log)
        scene = recording.scene_path()
        check_scene(recording, scene)
        world = reading(load_scene(scene), scene=scene)
        check_model(recording, world)
        refuse_inputs([video])  # the .mp4 writer does not go through write_bytes: checked before rendering
        check_output(video)
        renderer = FrameRenderer(world.model, width, height, render_mode, camera, world.data)
        frames, next_frame = [], 0.0
        for t in replay_states(world, recording):
            if t + 1e-9 >= next_frame:
                frames.append(renderer.render(world.data))
                next_frame += 1.0 / fps
        recording.close()
        if video_kind(video) == "gif":
            write_bytes(video, encode_gif(frames, fps))
        else:
            encode_mp4(frames, fps, video)
    out.wrote(video, f"wrote {video}: {len(frames)} frame(s) replayed from {printable(log)}", kind="video")


def _refuse_replay_inputs(log: Path, targets: list[Path | None]) -> None:
    """Refuse any of ``targets`` that is the recording, its scene or a file the scene's world reads."""
    from simrun.record.simlog import Simlog, check_scene
    from simrun.scene.scene_file import load_scene

    recording = Simlog(log)
    try:
        scene = recording.scene_path()
        check_scene(recording, scene)
    finally:
        recording.close()
    world = load_scene(scene)
    world.compile()
    refuse_inputs(targets, inputs=scene_files(scene), world=world)


def _note_truncated(log: Path) -> None:
    """One ``note:`` line when the recording was cut short (killed, a full disk): it is read up to its last chunk."""
    from simrun.record.simlog import truncation_note

    text = truncation_note(log)
    if text is not None:
        out.note(text)


@click.command("resim")
@click.argument("log", type=click.Path(path_type=Path, dir_okay=False))
@click.option(
    "--from",
    "start",
    type=SECONDS,
    default=None,
    help="Re-simulate from the last checkpoint at or before this time, seconds (default: the first checkpoint).",
)
@click.option(
    "--controller",
    type=click.Path(path_type=Path, dir_okay=False),
    default=None,
    help="The Python controller module the recorded run used (its SHA-256 must match the recorded one).",
)
def resim(log: Path, start: float | None, controller: Path | None) -> None:
    """Re-simulate a .simlog from a checkpoint and check it matches the recording bit for bit.

    It starts from the recording's first checkpoint (a recording started while a served world ran holds
    one of that instant), streams the recording and stops at the first frame that differs, naming its
    time and what differs. A recording never names code to run: when the run used a Python controller,
    give the same file with --controller; it runs only if its SHA-256 equals the recorded one. The
    recorded scene path is relative to the recording, so this works from any folder.
    """
    from simrun.run.session import run_resim

    _note_truncated(log)
    done = run_resim(log, start, controller)
    if done.mismatch is not None:
        raise SimrunError(
            f"{log}: re-simulation differs from the recording at t = {done.mismatch.time:.3f} s "
            f"({done.compared} frame(s) from t = {done.start:g} s were identical): {done.mismatch.what}"
        )
    out.stats(frames_compared=done.compared, from_s=done.start)
    out.say(f"{printable(log)}: {done.compared} frame(s) re-simulated from t = {done.start:g} s: bit-identical")
