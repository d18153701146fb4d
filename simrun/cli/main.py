"""The ``simrun`` command line: a thin layer over the library."""

from __future__ import annotations

import functools
import io
import os
import sys
from pathlib import Path
from typing import Any

import click

from meshtool.cli import output as out
from meshtool.cli.common import VocabularyGroup
from meshtool.cli.output import EXIT_INPUT, fail
from meshtool.files.safeopen import printable
from simrun import __version__
from simrun.cli.scenetest import test_command
from simrun.cli.serve import serve_command
from simrun.cli.types import FPS, OUT, SECONDS, Number
from simrun.errors import SimrunError
from simrun.outfile import check_output, output_policy, reading, refuse_inputs, scene_files, write_bytes

# Before anything imports numpy: single-threaded OpenBLAS (its idle threads spin; see meshtool/cli/main.py).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
# Start-up (issue 28): this module imports click and simrun's light modules only; numpy, Pillow, MuJoCo and
# the exporters (glb_export -> trimesh) are imported inside the command that uses them, so ``simrun --help``
# and every ``simrun COMMAND --help`` stay close to a bare click program (tests/test_perf_startup.py).
#: Render modes (simrun.run.render.MODES, which imports MuJoCo; tests/test_perf_startup.py checks they agree).
MODES = ("visual", "wireframe", "physics", "combined", "none")
#: The default image size (simrun.run.session.DEFAULT_SIZE, checked equal by tests/test_perf_startup.py).
DEFAULT_SIZE = (640, 480)
#: The one default image size of play, replay and snapshot (docs/cli.md).
DEFAULT_SIZE_TEXT = f"{DEFAULT_SIZE[0]}x{DEFAULT_SIZE[1]}"

#: Exit codes: the one table of :data:`meshtool.cli.output.EXIT_CODES` (docs/cli.md), mapped by
#: :func:`meshtool.cli.output.fail`; what a command produced is said through :mod:`meshtool.cli.output`.
#: ``SIMRUN_DEBUG=1`` gives the traceback of an internal error (exit 3).


class _Group(VocabularyGroup):
    """The command group: a user error is one ``error:`` line (exit 1), a bug one ``internal error:`` line (3).

    The vocabulary shared with meshtool (``--json``, ``-q``, ``-v``, exit codes: docs/cli.md) comes from
    :class:`meshtool.cli.common.VocabularyGroup`.
    """

    program = "simrun"

    def run_command(self, ctx: click.Context) -> Any:
        """Run the command, mapping simrun's errors to exit codes; then the notes of the model cache."""
        try:
            return self._mapped(ctx)
        finally:  # a damaged or foreign compiled-model cache entry: compiled again, said once
            model_cache = sys.modules.get("simrun.world.model_cache")  # no cache opened when it was never imported
            for note in model_cache.notes() if model_cache is not None else ():
                out.note(note)

    def _mapped(self, ctx: click.Context) -> Any:
        try:
            return super().run_command(ctx)
        except (click.exceptions.ClickException, click.exceptions.Exit, click.exceptions.Abort):
            raise
        except Exception as exc:  # one mapping (meshtool.cli.output.fail): its kind decides 1 or 2; a bug is 3
            fail(exc, "simrun")


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="simrun")
def main() -> None:
    """Run MuJoCo worlds of meshtool assets.

    Exit codes: 0 ok, 1 invalid input or a failed check (one 'error:' line naming the file and line), 2 usage,
    3 simrun failed (a bug; SIMRUN_DEBUG=1 shows the traceback).
    """


main.add_command(serve_command)  # simrun serve (simrun/cli/serve.py)
main.add_command(test_command)  # simrun test: scene tests with [[expect]] (simrun/cli/scenetest.py)


@main.command("doctor")
@click.option("--json", "as_json", is_flag=True, help="Print the report as one JSON object.")
def doctor(as_json: bool) -> None:
    """Check MuJoCo: version, compile and step a model, which GL backend renders and which headless ones start."""
    from simrun.doctor import check_environment

    report = check_environment()
    choice = report.choice
    gl = {"backend": choice.backend, "reason": choice.reason, "problem": choice.problem} if choice else None
    document: dict[str, Any] = {"status": "ok" if report.physics_ok else "error", "mujoco": report.mujoco_version}
    document |= {"physics_ok": report.physics_ok, "physics_error": report.physics_error}
    document |= {"rendering": gl, "backends": {k: v is None for k, v in report.gl.items()}, "problems": report.gl}
    out.report(document)
    for line in report.lines():
        out.say(line)
    if not report.physics_ok:
        raise SystemExit(EXIT_INPUT)


@main.command("check")
@click.argument("scene", type=click.Path(path_type=Path, dir_okay=False))
@click.option("--duration", "seconds", type=SECONDS, default=1.0, show_default=True, help="Simulated seconds to step.")
@click.option("--seconds", "seconds", type=SECONDS, hidden=True, help="Deprecated spelling of --duration.")
@click.option("--json", "as_json", is_flag=True, help="Print the result as one JSON object.")
def check(scene: Path, seconds: float, as_json: bool) -> None:
    """Load SCENE, compile it, bind its services and sensors, and step it; fail on any warning or non-finite state.

    Warnings about the scene (option overrides, initial penetrations, ground that holds a fixed robot) are
    printed, not failed on.
    """
    import numpy as np

    from simrun.scene.scene_file import load_scene
    from simrun.world.checks import scene_warnings

    world = load_scene(scene)
    world.check_bindings()
    found = scene_warnings(world)
    world.run(seconds)
    warnings = world.warnings()
    if warnings:
        raise SimrunError(f"{scene}: MuJoCo warnings after {seconds:g} s: {warnings}")
    if not np.isfinite(world.data.qpos).all():
        raise SimrunError(f"{scene}: the state became non-finite within {seconds:g} s")
    model = world.model
    counts = {"entities": len(world), "bodies": model.nbody - 1, "geoms": model.ngeom, "meshes": model.nmesh}
    result: dict[str, Any] = {
        "status": "ok",
        "scene": str(scene),
        **counts,
        "textures": model.ntex,
        "duration_s": seconds,
    }
    result |= {"services": len(world.services), "sensors": len(world.sensors), "warnings": found}
    out.report(result)
    for line in found:
        out.tell(f"warning: {scene}: {line}")
    out.say(
        f"{scene}: ok: {len(world)} entities, {model.nbody - 1} bodies, {model.ngeom} geoms, {model.nmesh} meshes, "
        f"{model.ntex} textures; stepped {seconds:g} s with no warning from MuJoCo"
        + (f", {len(found)} scene warning{'s' if len(found) != 1 else ''} (above)" if found else "")
    )


@main.command("export")
@click.argument("scene", type=click.Path(path_type=Path, dir_okay=False))
@click.option(
    "--mjcf",
    type=click.Path(path_type=Path, dir_okay=False),
    default=None,
    help="Write MJCF XML with its .obj meshes and PNG textures beside it (a folder that loads on its own).",
)
@click.option(
    "--mjz",
    type=click.Path(path_type=Path, dir_okay=False),
    default=None,
    help="Write an .mjz: MJCF + textures + the compiled model (reloads bit-identically).",
)
@click.option(
    "--usd",
    type=click.Path(path_type=Path, dir_okay=False),
    default=None,
    help="Write a USD stage (.usda/.usdc) with UsdPhysics bodies, colliders and joints.",
)
@click.option(
    "--glb",
    type=click.Path(path_type=Path, dir_okay=False),
    default=None,
    help="Write a GLB (Y-up, metres, colours) for web viewers.",
)
@click.option("--glb-collision", is_flag=True, help="Also put the collision geoms in the GLB, as hidden nodes.")
@click.option("--force", is_flag=True, help="Replace existing outputs simrun did not write (never an input).")
def export(
    scene: Path,
    mjcf: Path | None,
    mjz: Path | None,
    usd: Path | None,
    glb: Path | None,
    glb_collision: bool,
    force: bool = False,
) -> None:
    """Export SCENE as MJCF (a self-contained folder), a compiled binary model, USD and/or GLB."""
    if mjcf is None and mjz is None and usd is None and glb is None:
        raise click.UsageError("give --mjcf, --mjz, --usd and/or --glb")
    from simrun.scene.scene_file import load_scene

    with output_policy(force, [scene]):
        world = reading(load_scene(scene), scene=scene)
        world.compile()
        refuse_inputs([mjcf, mjz, usd, glb])  # before the first is written: never over a file the scene reads
        if mjcf is not None:
            from simrun.export.mjcf_builder import export_world_mjcf

            written = export_world_mjcf(world, mjcf)
            out.wrote(mjcf, f"wrote {mjcf} and {len(written) - 1} mesh and texture file(s) beside it", kind="mjcf")
        if mjz is not None:
            from simrun.world.archive import save_mjz

            save_mjz(world, mjz)
            out.wrote(mjz, kind="mjz")
        if usd is not None:
            from simrun.export.usd import export_world_usd

            unmapped = export_world_usd(world, usd)
            out.wrote(usd, kind="usd")
            for gap in unmapped:  # no UsdPhysics counterpart: listed, not silently dropped (docs/interop.md)
                out.note(f"{usd}: not in the USD: {gap}")
        if glb is not None:
            from simrun.export.glb import export_world_glb

            export_world_glb(world, glb, collision=glb_collision)
            out.wrote(glb, kind="glb")


def _size(text: str) -> tuple[int, int]:
    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise click.BadParameter(f"expected WxH, got {text!r}") from None
    if not (16 <= width <= 4096 and 16 <= height <= 4096):
        raise click.BadParameter("width and height must be 16..4096")
    return width, height


@main.command("play")
@click.argument("scene", type=click.Path(path_type=Path, dir_okay=False))
@click.option("--duration", type=SECONDS, default=5.0, show_default=True, help="Simulated seconds.")
@click.option(
    "--commands",
    "commands_file",
    type=click.Path(path_type=Path, dir_okay=False),
    default=None,
    help="TOML of timed service calls ([[commands]] t, service, entity, call, args), or a .py with step(world).",
)
@click.option("--video", type=click.Path(path_type=Path, dir_okay=False), default=None, help="OUT.gif or OUT.mp4.")
@click.option(
    "--frames",
    "frames_dir",
    type=click.Path(path_type=Path, file_okay=False),
    default=None,
    help="Write every frame as PNG into this folder.",
)
@click.option(
    "--render-mode",
    type=click.Choice(list(MODES)),
    default=None,
    help="visual | wireframe | physics | combined | none (default: visual with --video/--frames, else none).",
)
@click.option(
    "--camera",
    default=None,
    help="Camera name, or follow:ENTITY for a camera following that entity (default: the main view, else a free "
    "camera).",
)
@click.option("--size", default=DEFAULT_SIZE_TEXT, show_default=True, help="Frame size WxH.")
@click.option("--fps", type=FPS, default=15.0, show_default=True, help="Frames per simulated second.")
@click.option("--realtime", is_flag=True, help="Do not run faster than the wall clock.")
@click.option(
    "--record",
    type=click.Path(path_type=Path, dir_okay=False),
    default=None,
    help="Record a .simlog (frames every 20 ms, checkpoints every second).",
)
@click.option("--seed", type=int, default=None, help="Reseed every sensor's noise (sensor k gets seed + k).")
@click.option("--record-sensors", default=None, help="Comma-separated sensor names whose readings --record keeps.")
@click.option(
    "--record-as",
    default=None,
    help="Also write the --record recording as glb, gltf, usd (usda, usdc) and/or html beside it "
    "(comma-separated; RUN.simlog -> RUN.glb...), as 'simrun replay' does.",
)
@click.option("--json", "as_json", is_flag=True, help="Print the summary as one JSON object.")
@click.option("--force", is_flag=True, help="Replace existing outputs simrun did not write (never an input).")
def play_command(
    scene: Path,
    duration: float,
    commands_file: Path | None,
    video: Path | None,
    frames_dir: Path | None,
    render_mode: str | None,
    camera: str | None,
    size: str,
    fps: float,
    realtime: bool,
    record: Path | None,
    seed: int | None,
    record_sensors: str | None,
    as_json: bool,
    force: bool = False,
    record_as: str | None = None,
) -> None:
    """Run SCENE headless: timed commands, optional video or frames, and a summary."""
    from simrun.run.session import PlayOptions, run_play

    width, height = _size(size)
    watchable = None
    if record_as is not None:
        from simrun.record.replay_export import beside

        if record is None:
            raise click.UsageError("--record-as needs --record RUN.simlog")
        try:
            watchable = beside(record, record_as)
        except SimrunError as exc:
            raise click.BadParameter(str(exc), param_hint="--record-as") from None
    chosen = tuple(n.strip() for n in record_sensors.split(",") if n.strip()) if record_sensors else ()
    options = PlayOptions(
        duration,
        commands_file,
        video,
        frames_dir,
        render_mode,
        camera,
        (width, height),
        fps,
        realtime,
        record,
        seed,
        chosen,
    )
    with output_policy(force, [scene, commands_file]):
        from meshtool.work.progress import report, subject

        def progress(t: float) -> None:  # the progress line on a terminal's stderr (meshtool.work.progress.Display)
            report("simulated seconds", int(min(t, duration)), max(int(duration), 1))

        written = []
        if watchable is not None:
            options.also = tuple(watchable.values())  # checked against the scene's files with --record
            for target in watchable.values():
                check_output(target)  # refused before simulating, like --video and --record
        with subject(scene.name):
            report("loading the scene and compiling it in MuJoCo")
            result = run_play(scene, options, progress)
        if record is not None and watchable is not None:
            from simrun.record.replay_export import export_recording

            written = export_recording(record, watchable)
    summary = result.to_dict()
    if watchable is not None:
        summary["recording_outputs"] = {str(item.path): item.size for item in written}
    out.report(summary)
    out.say(
        f"{scene}: {summary['simulated_s']:g} s simulated in {summary['wall_s']:.2f} s "
        f"({summary['steps_per_s']:.0f} steps/s, {summary['realtime_factor']:.1f}x real time), "
        f"{summary['frames']} frame(s)"
    )
    for name, metres in summary["distances_m"].items():
        out.say(f"  {name}: drove {metres:.3f} m")
    for name, count in summary["sensor_samples"].items():
        out.say(f"  sensor {name}: {count} sample(s)")
    for item in written:
        out.wrote(item.path, f"  wrote {item.path} ({item.size} bytes)", bytes=item.size)


@main.command("replay")
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


@main.command("resim")
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


@main.command("view")
@click.argument("scene", type=click.Path(path_type=Path, dir_okay=False))
def view(scene: Path) -> None:
    """Open SCENE in MuJoCo's viewer; arrows drive the first robot (cmd_vel), space stops it."""
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        out.problem(
            "no display: simrun view needs a desktop session; use "
            f"'simrun play {scene} --video OUT.gif' to see it headless",
            EXIT_INPUT,
        )
    from simrun.run.viewer import run_viewer
    from simrun.scene.scene_file import load_scene

    run_viewer(load_scene(scene))


@main.command("snapshot")
@click.argument("scene", type=click.Path(path_type=Path, dir_okay=False))
@click.option("-o", "--output", type=click.Path(path_type=Path, dir_okay=False), required=True, help="OUT.png")
@click.option(
    "--render-mode", type=click.Choice([m for m in MODES if m != "none"]), default="visual", show_default=True
)
@click.option(
    "--camera",
    default=None,
    help="Camera name, or follow:ENTITY for a camera following that entity (default: the main view, else a free "
    "camera).",
)
@click.option("--size", default=DEFAULT_SIZE_TEXT, show_default=True, help="Image size WxH.")
@click.option(
    "--duration", "at_time", type=SECONDS, default=0.0, show_default=True, help="Simulated seconds before the picture."
)
@click.option("--at", "at_time", type=SECONDS, hidden=True, help="Deprecated spelling of --duration.")
def snapshot(scene: Path, output: Path, render_mode: str, camera: str | None, size: str, at_time: float) -> None:
    """Render one picture of SCENE after simulating --duration seconds."""
    from PIL import Image

    from simrun.run.render import FrameRenderer
    from simrun.scene.scene_file import load_scene

    width, height = _size(size)
    with output_policy(False, [scene]):
        world = reading(load_scene(scene), scene=scene)
        world.compile()
        refuse_inputs([output])  # before simulating: never over the scene or a file it reads
        world.run(at_time)
        renderer = FrameRenderer(world.model, width, height, render_mode, camera, world.data)
        buffer = io.BytesIO()
        Image.fromarray(renderer.render(world.data)).save(buffer, format="PNG")
        write_bytes(output, buffer.getvalue())
    out.wrote(output, f"wrote {output} ({width}x{height}, {render_mode})", kind="png")


#: Folders MJCF models may read from besides the scene's and their own (simrun.robots.mjcf_read.ALLOW_ROOTS_ENV;
#: this module imports no MuJoCo, so the name is written here and tests/test_mjcf_hostile.py checks they agree).
ALLOW_ROOTS_ENV = "SIMRUN_ALLOW_ROOTS"


def _allow_root(command: click.Command) -> click.Command:
    """Give a scene command ``--allow-root DIR`` (repeatable): MJCF models may read files inside DIR too.

    The folders go to the reader through ``SIMRUN_ALLOW_ROOTS`` (absolute, ``os.pathsep``-separated) for as long
    as the command runs, so the processes it starts (``simrun test`` runs, Dask workers) allow them as well.
    """
    command.params.append(
        click.Option(
            ["--allow-root", "allow_roots"],
            multiple=True,
            type=click.Path(path_type=Path, file_okay=False, exists=True),
            help="A folder MJCF models may read files from besides the scene's and their own (repeatable; "
            "docs/limits.md).",
        )
    )
    callback = command.callback
    assert callback is not None

    def run(*args: Any, allow_roots: tuple[Path, ...] = (), **kwargs: Any) -> Any:
        before = os.environ.get(ALLOW_ROOTS_ENV)
        if allow_roots:
            known = [p for p in (before or "").split(os.pathsep) if p]
            os.environ[ALLOW_ROOTS_ENV] = os.pathsep.join([*known, *(os.path.abspath(p) for p in allow_roots)])
        try:
            return callback(*args, **kwargs)
        finally:
            if allow_roots and before is None:
                os.environ.pop(ALLOW_ROOTS_ENV, None)
            elif allow_roots and before is not None:
                os.environ[ALLOW_ROOTS_ENV] = before

    command.callback = functools.update_wrapper(run, callback)
    return command


for _command in (check, export, play_command, snapshot, view, test_command, serve_command):
    _allow_root(_command)
