"""The ``meshtool`` command line: a thin click layer over the library.

Each command turns its options into the library's frozen options dataclass, calls the library, and maps
the outcome to output and an exit code:

* 0: written (warnings allowed);
* 1: the input could not be converted (one ``error:`` line on stderr, nothing written);
* 2: usage error (click);
* 3: meshtool itself failed (a bug: please report it; set ``MESHTOOL_DEBUG=1`` for the traceback).
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path
from typing import Any

import click

from meshtool import __version__
from meshtool.errors import MeshtoolError
from meshtool.findings import Severity
from meshtool.normalise import NormaliseOptions, normalise_to
from meshtool.units import UNIT_FACTORS

EXIT_OK, EXIT_INPUT, EXIT_USAGE, EXIT_INTERNAL = 0, 1, 2, 3


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="meshtool")
def main() -> None:
    """Make OBJ/MTL assets simulation-ready."""


@main.command("normalize")
@click.argument("src", type=click.Path(path_type=Path, dir_okay=False))
@click.option(
    "-o",
    "--output",
    "out_dir",
    required=True,
    type=click.Path(path_type=Path, file_okay=False),
    help="Folder to write NAME/ into (created when missing).",
)
@click.option(
    "--units",
    type=click.Choice(list(UNIT_FACTORS)),
    default=None,
    help="Unit the source was modelled in (default m).",
)
@click.option("--scale", type=float, default=1.0, show_default=True, help="Extra uniform scale after --units.")
@click.option(
    "--up",
    type=click.Choice(["y", "z"]),
    default=None,
    help="Up axis of the source: y (OBJ convention, rotated to Z-up; default) or z (kept).",
)
@click.option("--name", default=None, help="Output folder and file stem (default: the source stem made safe).")
@click.option(
    "--search-path",
    "search_paths",
    multiple=True,
    type=click.Path(path_type=Path, file_okay=False),
    help="Extra folder where MTL and texture references may resolve (repeatable).",
)
@click.option("--strict", is_flag=True, help="Fail (exit 1) instead of writing when there are warnings.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object on stdout instead of text.")
def normalize(
    src: Path,
    out_dir: Path,
    units: str | None,
    scale: float,
    up: str | None,
    name: str | None,
    search_paths: tuple[Path, ...],
    strict: bool,
    as_json: bool,
) -> None:
    """Normalise SRC (an OBJ file) into OUTPUT/NAME/: metres, Z-up, PNG textures, safe names."""
    try:
        options = NormaliseOptions(units=units, scale=scale, up=up, name=name, search_paths=search_paths, strict=strict)
        folder, asset = normalise_to(src, out_dir, options)
    except MeshtoolError as exc:
        _fail(exc, as_json)
    except Exception as exc:  # a bug in meshtool: say so, keep the traceback for MESHTOOL_DEBUG
        if os.environ.get("MESHTOOL_DEBUG"):
            raise
        click.echo(
            f"internal error: {type(exc).__name__}: {exc} (please report; MESHTOOL_DEBUG=1 shows more)",
            err=True,
        )
        sys.exit(EXIT_INTERNAL)
    if as_json:
        report: dict[str, Any] = {
            "status": "ok",
            "output": str(folder),
            "findings": [f.to_dict() for f in asset.findings],
            "stats": asset.stats,
        }
        click.echo(json.dumps(report))
        return
    stats = asset.stats
    click.echo(
        f"wrote {folder}: {stats['vertices']} vertices, {stats['triangles']} triangles, "
        f"{stats['materials']} material(s), {stats['textures']} texture(s), "
        f"extent {' x '.join(f'{e:.4g}' for e in stats['bbox']['extent'])} m"
    )
    for finding in asset.findings:
        if finding.severity is not Severity.INFO or os.environ.get("MESHTOOL_VERBOSE"):
            click.echo(finding.one_line(), err=True)


def _fail(exc: MeshtoolError, as_json: bool) -> None:
    click.echo(f"error: {exc.one_line()}", err=True)
    if as_json:
        click.echo(
            json.dumps({"status": "error", "output": None, "error": exc.to_dict(), "findings": [], "stats": None})
        )
    sys.exit(EXIT_INPUT)


if __name__ == "__main__":  # pragma: no cover
    main()
