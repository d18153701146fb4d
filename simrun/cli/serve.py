"""``simrun serve``: a thin click layer over :func:`simrun.serve.server.serve` (docs/serve.md)."""

from __future__ import annotations

from pathlib import Path

import click

from meshtool.cli.output import say, wrote
from meshtool.files.safeopen import printable
from meshtool.formats import suffix
from simrun.cli.types import OUT, Number
from simrun.errors import SimrunError
from simrun.outfile import output_policy


@click.command("serve")
@click.argument("scene", type=click.Path(path_type=Path, dir_okay=False))
@click.option("--host", default="127.0.0.1", show_default=True, help="Address to listen on (others need --token).")
@click.option("--port", type=click.IntRange(0, 65535), default=8765, show_default=True, help="TCP port (0: any free).")
@click.option("--realtime/--lockstep", default=True, help="Run with the wall clock, or step only on POST /api/step.")
@click.option("--rate", type=Number(0.01, 1000.0), default=1.0, show_default=True, help="Real-time factor.")
@click.option("--paused", is_flag=True, help="Start paused.")
@click.option("--record", type=OUT, default=None, help="Record the session to this .simlog (written at shutdown).")
@click.option(
    "--record-as",
    type=click.Choice(["simlog", "mcap"]),
    default="simlog",
    show_default=True,
    help="mcap: also write the recording as MCAP beside it (same name, .mcap).",
)
@click.option("--record-sensors", default=None, help="Comma-separated sensor names whose readings --record keeps.")
@click.option("--seed", type=int, default=None, help="Reseed every sensor's noise (sensor k gets seed + k).")
@click.option("--token", envvar="SIMRUN_TOKEN", default=None, help="Bearer token every request must carry.")
@click.option(
    "--foxglove-port", type=click.IntRange(0, 65535), default=None,
    help="Also stream the world (poses, joints, sensors, clock, scene) in the Foxglove WebSocket protocol on "
    "127.0.0.1 (0: any free port).",
)  # fmt: skip
@click.option("--foxglove-mcap", type=OUT, default=None, help="Also write the Foxglove stream to this MCAP as it runs.")
@click.option(
    "--allow-origin", "allow_origins", multiple=True, metavar="ORIGIN",
    help="Let pages of this web origin (scheme://host[:port]) use the server, besides its own; repeatable.",
)  # fmt: skip
@click.option(
    "--edit", is_flag=True,
    help="Allow edits of the running world over the API (insert, change, remove, move, push entities; docs/serve.md).",
)  # fmt: skip
@click.option(
    "--request-rate", type=Number(1.0, 1e6), default=None,
    help="Requests a wall second one client address may send in real time (a burst of twice as many; changing "
    "requests half as many, a burst of this many); beyond, 429.  [default: 300]",
)  # fmt: skip
@click.option("--force", is_flag=True, help="Replace existing outputs simrun did not write (never an input).")
def serve_command(
    scene: Path,
    host: str,
    port: int,
    realtime: bool,
    rate: float,
    paused: bool,
    record: Path | None,
    record_as: str,
    record_sensors: str | None,
    seed: int | None,
    token: str | None,
    force: bool,
    foxglove_port: int | None = None,
    foxglove_mcap: Path | None = None,
    allow_origins: tuple[str, ...] = (),
    edit: bool = False,
    request_rate: float | None = None,
) -> None:
    """Run SCENE and serve it: HTTP/JSON services and sensors, a WebSocket stream, a dashboard at /.

    Stop with Ctrl+C or SIGTERM (the recording is written then). docs/serve.md describes the interface.
    """
    from simrun.serve.loop import ServeOptions
    from simrun.serve.server import serve

    sensors = tuple(n.strip() for n in record_sensors.split(",") if n.strip()) if record_sensors else ()
    mcap = record.with_suffix(suffix("mcap")) if record is not None and record_as == "mcap" else None
    options = ServeOptions(scene, not realtime, rate, record=record, record_sensors=sensors, record_mcap=mcap,
                           seed=seed, paused=paused, extra={"edit": edit})  # fmt: skip
    if request_rate is not None:
        options.request_rate = request_rate
    with output_policy(force, [scene]):
        served = serve(
            options,
            host,
            port,
            token,
            on_ready=lambda url: say(f"{'foxglove' if url.startswith('ws:') else 'serving'} {url}"),
            foxglove_port=foxglove_port,
            foxglove_mcap=foxglove_mcap,
            allow_origins=allow_origins,
        )
    for path in served.written:
        wrote(path, f"wrote {printable(path)}")
    if served.error:
        raise SimrunError(served.error)
