"""What the ``meshtool`` conversion commands share: click options, their library options, the error guard.

The option decorators (``--force``, ``-o/--output``, the normalise and hull options), their conversion into
the library's frozen options dataclasses, the result document and summary line of a converted asset, and
:func:`_guard`, which maps library errors to exit 1 and bugs to exit 3 (see :mod:`meshtool.cli.main`). The
commands themselves live in :mod:`meshtool.cli.mesh_commands` (normalize, obj2bin, hulls),
:mod:`meshtool.cli.model_commands` (mjcf, urdf), :mod:`meshtool.cli.pack` and :mod:`meshtool.cli.validate`.
"""

from __future__ import annotations

import contextlib
import os
import stat
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from meshtool.cli.output import (
    exit_on_bug,
    fail,
    report,
)
from meshtool.errors import MeshtoolError
from meshtool.findings import Finding
from meshtool.hulls.options import MODES, PRESETS, HullOptions

#: The --units names (meshtool.frame.units.UNIT_FACTORS, which imports numpy; tests/test_perf_startup.py checks
#: they agree). Start-up (issue 28): the library is imported inside each command, so ``--help`` stays light.
UNITS = ("m", "cm", "mm", "in", "ft")

if TYPE_CHECKING:
    from meshtool.repair.normalise import NormaliseOptions

force_option = click.option(
    "--force",
    is_flag=True,
    help="Replace an existing output that meshtool did not write (an input is never replaced).",
)


def output_dir_option(help_text: str) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """The required ``-o/--output`` folder option (``out_dir``), with the command's own help."""
    return click.option(
        "-o",
        "--output",
        "out_dir",
        required=True,
        type=click.Path(path_type=Path, file_okay=False),
        help=help_text,
    )


def normalise_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """The normaliser's options, shared by ``meshtool normalize`` and ``obj2bin``."""
    decorators = [
        click.option(
            "--units",
            type=click.Choice([*UNITS, "auto"]),
            default=None,
            help="Unit the source was modelled in (default m); auto: what a URDF/SDF/MJCF using the mesh says.",
        ),
        click.option("--scale", type=float, default=1.0, show_default=True, help="Extra uniform scale after --units."),
        click.option(
            "--up",
            type=click.Choice(["auto", "y", "z"]),
            default="auto",
            show_default=True,
            help="Up axis of the source: y (rotated to Z-up), z (kept) or auto (from evidence; see docs/findings.md).",
        ),
        click.option(
            "--search-path",
            "search_paths",
            multiple=True,
            type=click.Path(path_type=Path, file_okay=False),
            help="Extra folder where MTL and texture references may resolve (repeatable).",
        ),
        click.option(
            "--model-root",
            type=click.Path(path_type=Path, file_okay=False, exists=True),
            default=None,
            help="Folder at or above the mesh holding its models: references resolve inside it, and its "
            "URDF/SDF/MJCF files are searched for the mesh's consumers (default: found; docs/findings.md).",
        ),
        click.option("--strict", is_flag=True, help="Fail (exit 1) instead of writing when there are warnings."),
        click.option("--json", "as_json", is_flag=True, help="Print one JSON object on stdout instead of text."),
    ]
    for decorator in reversed(decorators):
        func = decorator(func)
    return func


def hull_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """Collision-hull options of ``obj2bin``."""
    decorators = [
        click.option(
            "--hulls",
            "hull_mode",
            type=click.Choice(list(MODES)),
            default="convex",
            show_default=True,
            help="none; convex (one hull); decompose (CoACD per part); objects (one hull per o/g part).",
        ),
        click.option(
            "--preset",
            type=click.Choice(list(PRESETS)),
            default=None,
            help="Budgets for an engine: mujoco (32 hulls x 64 vertices), mjx (8 x 32), physx-gpu (16 x 64).",
        ),
        click.option("--max-hulls", type=click.IntRange(1, 4096), default=None, help="Most hulls per part."),
        click.option(
            "--max-hull-vertices",
            type=click.IntRange(4, 100000),
            default=None,
            help="Most vertices per hull (default 64).",
        ),
        click.option(
            "--min-thickness",
            type=float,
            default=0.001,
            show_default=True,
            help="Smallest hull thickness in metres (capped at 5 % of the part's size).",
        ),
        click.option("--merge-parts", is_flag=True, help="Decompose the whole mesh at once, not part by part."),
        click.option("--threshold", type=float, default=0.05, show_default=True, help="CoACD concavity threshold."),
        click.option(
            "--timeout",
            "timeout_s",
            type=float,
            default=300.0,
            show_default=True,
            help="Seconds one CoACD run may take.",
        ),
        click.option(
            "--time-budget",
            "time_budget_s",
            type=click.FloatRange(min=0, min_open=True),
            default=180.0,
            show_default=True,
            help="Seconds all CoACD runs of one asset may take; parts left then get their convex hull.",
        ),
        click.option(
            "--cache-dir",
            type=click.Path(path_type=Path, file_okay=False),
            default=None,
            help="Cache of decompositions and passed MuJoCo checks (default: the user cache folder).",
        ),
        click.option("--no-cache", is_flag=True, help="Do not read or write the caches."),
    ]
    for decorator in reversed(decorators):
        func = decorator(func)
    return func


def _normalise_options(kw: dict[str, Any], **overrides: Any) -> NormaliseOptions:
    """Build :class:`NormaliseOptions` from the click keywords (removing them from ``kw``), then ``overrides``."""
    from meshtool.repair.normalise import NormaliseOptions

    values = {key: kw.pop(key) for key in ("units", "scale", "up", "search_paths", "strict", "model_root")}
    values.update(overrides)
    return NormaliseOptions(**values)


def _user_cache() -> Path:
    import platformdirs

    return Path(platformdirs.user_cache_dir("meshtool"))


def _check_cache(hull_cache: Path | None) -> Path | None:
    """Where passing MuJoCo checks are remembered.

    ``checks`` beside the default ``hulls`` cache, or inside a ``--cache-dir``; nothing with ``--no-cache``.
    """
    if hull_cache is None:
        return None
    return hull_cache.parent / "checks" if hull_cache == _user_cache() / "hulls" else hull_cache / "checks"


def _hull_options(kw: dict[str, Any]) -> HullOptions:
    """Build :class:`HullOptions` from the click keywords (removing them from ``kw``)."""
    preset, max_hulls, max_vertices = kw.pop("preset"), kw.pop("max_hulls"), kw.pop("max_hull_vertices")
    cache_dir, no_cache = kw.pop("cache_dir"), kw.pop("no_cache")
    values: dict[str, Any] = {
        "mode": kw.pop("hull_mode"),
        "min_thickness": kw.pop("min_thickness"),
        "merge_parts": kw.pop("merge_parts"),
        "threshold": kw.pop("threshold"),
        "timeout_s": kw.pop("timeout_s"),
        "time_budget_s": kw.pop("time_budget_s"),
        "cache_dir": None if no_cache else (cache_dir or _user_cache() / "hulls"),
    }
    if max_hulls is not None:
        values["max_hulls"] = max_hulls
    if max_vertices is not None:
        values["max_hull_vertices"] = max_vertices
    return HullOptions.preset(preset, **values) if preset else HullOptions(**values)


def _is_folder(path: Path) -> bool:
    """Whether ``path`` is a folder; a path that cannot be looked at (missing, too long) is not: the reader says why."""
    try:
        return stat.S_ISDIR(os.stat(path).st_mode)
    except (OSError, ValueError):
        return False


def _summary(stats: dict[str, Any]) -> str:
    return (
        f"{stats['vertices']} vertices, {stats['triangles']} triangles, "
        f"{stats['materials']} material(s), {stats['textures']} texture(s), "
        f"extent {' x '.join(f'{e:.4g}' for e in stats['bbox']['extent'])} m"
    )


def _report(status: str, output: Path, findings: list[Finding], stats: dict[str, Any]) -> dict[str, Any]:
    return {"status": status, "output": str(output), "findings": [f.to_dict() for f in findings], "stats": stats}


@contextlib.contextmanager
def _guard(as_json: bool) -> Iterator[None]:
    """Map library errors to exit 1 (one ``error:`` line) and bugs to exit 3."""
    try:
        yield
    except MeshtoolError as exc:
        if as_json:  # the command's own JSON document (normalize, obj2bin, hulls, info --json)
            report({"status": "error", "output": None, "error": exc.to_dict(), "findings": [], "stats": None})
        fail(exc)
    except Exception as exc:  # a bug in meshtool: say so, keep the traceback for MESHTOOL_DEBUG
        exit_on_bug(exc)
