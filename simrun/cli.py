"""The ``simrun`` command line: a thin layer over the library."""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Iterator
from pathlib import Path

import click
import numpy as np

from simrun import __version__
from simrun.archive import save_mjz
from simrun.doctor import check_environment
from simrun.errors import SimrunError
from simrun.outfile import write_text
from simrun.scene import load_scene

EXIT_OK, EXIT_INPUT, EXIT_USAGE = 0, 1, 2


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="simrun")
def main() -> None:
    """Run MuJoCo worlds of meshtool assets."""


@main.command("doctor")
def doctor() -> None:
    """Check MuJoCo: version, compile and step a model, and which headless GL backends start."""
    report = check_environment()
    for line in report.lines():
        click.echo(line)
    if not report.physics_ok:
        raise SystemExit(EXIT_INPUT)


@main.command("check")
@click.argument("scene", type=click.Path(path_type=Path, dir_okay=False))
@click.option("--seconds", type=float, default=1.0, show_default=True, help="Simulated time to step.")
def check(scene: Path, seconds: float) -> None:
    """Load SCENE, compile it and step it; fail on any MuJoCo warning or non-finite state."""
    with _guard():
        world = load_scene(scene)
        world.run(seconds)
        warnings = world.warnings()
        if warnings:
            raise SimrunError(f"{scene}: MuJoCo warnings after {seconds:g} s: {warnings}")
        if not np.isfinite(world.data.qpos).all():
            raise SimrunError(f"{scene}: the state became non-finite within {seconds:g} s")
    model = world.model
    click.echo(
        f"{scene}: ok: {len(world)} entities, {model.nbody - 1} bodies, {model.ngeom} geoms, {model.nmesh} meshes, "
        f"{model.ntex} textures; stepped {seconds:g} s with no warning"
    )


@main.command("export")
@click.argument("scene", type=click.Path(path_type=Path, dir_okay=False))
@click.option("--mjcf", type=click.Path(path_type=Path, dir_okay=False), default=None, help="Write MJCF XML.")
@click.option(
    "--mjz",
    type=click.Path(path_type=Path, dir_okay=False),
    default=None,
    help="Write an .mjz: MJCF + textures + the compiled model (reloads bit-identically).",
)
def export(scene: Path, mjcf: Path | None, mjz: Path | None) -> None:
    """Export SCENE as MJCF (assets embedded from memory) and/or a compiled binary model."""
    if mjcf is None and mjz is None:
        raise click.UsageError("give --mjcf and/or --mjz")
    with _guard():
        world = load_scene(scene)
        world.compile()
        if mjcf is not None:
            write_text(mjcf, world.spec.to_xml())
            click.echo(f"wrote {mjcf}")
        if mjz is not None:
            save_mjz(world, mjz)
            click.echo(f"wrote {mjz}")


@contextlib.contextmanager
def _guard() -> Iterator[None]:
    try:
        yield
    except SimrunError as exc:
        click.echo(f"error: {exc}", err=True)
        sys.exit(EXIT_INPUT)
