"""The ``simrun`` commands over a scene file: ``check``, ``export``, ``play``, ``view`` and ``snapshot``.

Thin click layers over the library, registered on the group by :mod:`simrun.cli.main` (which also gives them
``--allow-root``); numpy, Pillow, MuJoCo and the exporters are imported inside the command that uses them.
"""

from __future__ import annotations

import io
import os
import sys
from pathlib import Path
from typing import Any

import click

from meshtool.cli import output as out
from meshtool.cli.output import EXIT_INPUT
from simrun.cli.types import DEFAULT_SIZE_TEXT, FPS, MODES, SECONDS, _size
from simrun.errors import SimrunError
from simrun.outfile import check_output, output_policy, reading, refuse_inputs, write_bytes


@click.command("check")
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


@click.command("export")
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


@click.command("play")
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


@click.command("view")
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


@click.command("snapshot")
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
