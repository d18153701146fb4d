"""The ``simrun`` command line."""

from __future__ import annotations

import click

from simrun import __version__
from simrun.doctor import check_environment


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
        raise SystemExit(1)
