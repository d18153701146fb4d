"""The ``meshtool`` commands that write a MuJoCo model: ``mjcf`` (of .mbin or mesh files) and ``urdf`` (a robot).

Each command turns its options into the library's frozen options dataclass (:mod:`meshtool.cli.command_support`),
calls the library, and maps the outcome to output and an exit code (see :mod:`meshtool.cli.main`). Modules only
one command needs (MJCF, URDF) are imported by that command.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from meshtool.cli.command_support import (
    UNITS,
    _guard,
    _hull_options,
    _is_folder,
    force_option,
    hull_options,
    output_dir_option,
)
from meshtool.cli.output import (
    findings,
    told_once,
    wrote,
)
from meshtool.errors import OptionsError
from meshtool.files.outdir import overwrite_allowed
from meshtool.files.resolve import find_files
from meshtool.findings import Finding
from meshtool.formats import mesh_suffixes, suffix


@click.command("mjcf")
@click.argument("src", type=click.Path(path_type=Path))  # a missing file: exit 1 (docs/cli.md)
@output_dir_option("Folder to write NAME/ (NAME.xml, meshes, textures) into, per asset.")
@click.option("--free-joint", is_flag=True, help="Give each body a free joint.")
@click.option("--density", type=float, default=1000.0, show_default=True, help="Collision density, kg/m^3.")
@click.option("--mass", type=float, default=None, help="Total body mass in kg (overrides --density).")
@click.option(
    "--units",
    type=click.Choice([*UNITS, "auto"]),
    default=None,
    help="For a mesh file: the unit it was modelled in (as obj2bin --units).",
)
@click.option(
    "--up", type=click.Choice(["auto", "y", "z"]), default="auto", help="For a mesh file: its up axis (as obj2bin)."
)
@force_option
def mjcf(
    src: Path,
    out_dir: Path,
    free_joint: bool,
    density: float,
    mass: float | None,
    units: str | None,
    up: str,
    force: bool,
) -> None:
    """Write a MuJoCo model for SRC: an .mbin, a mesh file (packed first, as obj2bin does) or a folder of .mbin."""
    from meshtool.mjcf.asset_model import MjcfOptions, write_mjcf
    from meshtool.packfile import load
    from meshtool.pipeline import ConvertOptions
    from meshtool.repair.normalise import NormaliseOptions, safe_file_stem

    with _guard(False):
        options = MjcfOptions(free_joint=free_joint, density=density, mass=mass)
        if src.suffix.lower() in mesh_suffixes() and not _is_folder(src):
            from meshtool.mjcf.mesh_model import mesh_mjcf

            convert_options = ConvertOptions(NormaliseOptions(units=units, up=up))
            xml, _, found = mesh_mjcf(src, out_dir, convert_options, options, force=force)
            wrote(xml, kind="mjcf")
            findings(found)
            return
        sources = find_files(src, suffix("mbin")) if _is_folder(src) else [src]
        if not sources:
            raise OptionsError(f"no .mbin files under {src}")
        stems = [safe_file_stem(p.stem) or "asset" for p in sources]
        clash = next((p for p, n in zip(sources, stems, strict=True) if stems.count(n) > 1), None)
        if clash is not None:
            raise OptionsError(f"two .mbin files would both become {safe_file_stem(clash.stem)!r}", hint="rename one")
        told: list[Finding] = []
        for path in sources:
            with load(path) as packed:
                xml, found = write_mjcf(
                    packed, out_dir, safe_file_stem(path.stem) or "asset", path, options, force=force, inputs=sources
                )
            told += found
            wrote(xml, kind="mjcf")
    told_once(told)


def _package_dir(_ctx: click.Context, _param: click.Parameter, values: tuple[str, ...]) -> tuple[tuple[str, Path], ...]:
    pairs = []
    for value in values:
        name, sep, folder = value.partition("=")
        if not sep or not folder:  # an empty NAME maps package:///... (talos_full_v2 writes those)
            raise click.BadParameter(f"expected NAME=DIR, got {value!r}")
        pairs.append((name, Path(folder)))
    return tuple(pairs)


@click.command("urdf")
@click.argument("robot", type=click.Path(path_type=Path, dir_okay=False))
@output_dir_option("Folder for NAME.xml (MJCF), its OBJ meshes and PNG textures, and meshes/*.mbin.")
@click.option(
    "--package-dir",
    "package_dirs",
    multiple=True,
    callback=_package_dir,
    help="Folder of a ROS package for package://NAME/... paths, as NAME=DIR (repeatable; =DIR maps package:///...).",
)
@click.option("--actuators", is_flag=True, help="Add a motor per moving joint, limited to its URDF effort.")
@click.option("--free-base", is_flag=True, help="Give the root link a free joint (mobile robots).")
@click.option("--allow-outside", is_flag=True, help="Let relative mesh paths leave the robot's package folder.")
@click.option(
    "--package-search",
    is_flag=True,
    help="Look for package://NAME in folders named NAME above the URDF and beside them "
    "(default: only the robot's own package and --package-dir).",
)
@force_option
@hull_options
def urdf(
    robot: Path,
    out_dir: Path,
    package_dirs: tuple[tuple[str, Path], ...],
    actuators: bool,
    free_base: bool,
    allow_outside: bool,
    package_search: bool,
    force: bool,
    **hull_kw: Any,
) -> None:
    """Import ROBOT (a URDF): every mesh normalised, packed and hulled; an MJCF of the robot."""
    from meshtool.urdf.import_robot import UrdfOptions, import_urdf
    from meshtool.urdf.write import write_import

    with _guard(False), overwrite_allowed(force):
        options = UrdfOptions(package_dirs, _hull_options(hull_kw), actuators, free_base, allow_outside, package_search)
        result = import_urdf(robot, options)
        findings(result.findings)
        write_import(result, out_dir)
        xml = out_dir / (result.name + suffix("mjcf"))
        wrote(
            xml,
            f"wrote {xml}: {len(result.links)} links, {len(result.joints)} moving "
            f"joints, {len(result.mbins)} mesh(es) in {out_dir / 'meshes'}",
            kind="mjcf",
        )
