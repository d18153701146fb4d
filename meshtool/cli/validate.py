"""``meshtool validate``: the click layer over :mod:`meshtool.validate`.

Exit codes: 0 no errors (warnings allowed unless ``--strict``); 1 errors (or warnings with ``--strict``);
2 usage (bad options, paths or configuration); 3 meshtool itself failed (an X001 finding, or the executor).
An unreachable Dask scheduler is exit 1 (one ``error:`` line with a hint).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Any, NoReturn

import click
import platformdirs

from meshtool.cli.common import batch_progress, executor_options, progress_option
from meshtool.cli.output import (
    EXIT_INPUT,
    EXIT_INTERNAL,
    EXIT_OK,
    exit_on_bug,
    fail,
    note,
    report,
    say,
    tell,
    verdict,
    wrote,
)
from meshtool.errors import MeshtoolError
from meshtool.files.outdir import write_file
from meshtool.formats import REPORT_FORMATS, report_format_for


def run_validate(*args: Any, **kwargs: Any) -> Any:
    """:func:`meshtool.validate.validate`, imported when a validation runs (it loads the rules, trimesh among them)."""
    from meshtool.validate import validate

    return validate(*args, **kwargs)


#: Report formats: the formats registry's (:data:`meshtool.formats.REPORT_FORMATS`, standard library only), as
#: meshtool.validate.reports.FORMATS (importing meshtool.validate loads the rules, trimesh among them:
#: tests/test_perf_startup.py checks they agree). ``validate --help`` imports none of it.
FORMATS = tuple(row.name for row in REPORT_FORMATS)


class FormatList(click.Choice[str]):
    """``--format``: one report format, or several separated by commas (``json,junit,html``), one ``-o`` each."""

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> str:
        """``value`` with each name checked against the choices (a usage error names the one that is not)."""
        names = []
        for name in str(value).split(","):  # a loop: super() needs the method's own frame
            names.append(super().convert(name.strip(), param, ctx))
        repeated = sorted({name for name in names if names.count(name) > 1})
        if repeated:
            self.fail(f"{', '.join(repeated)} named twice", param, ctx)
        return ",".join(names)

    def get_metavar(self, param: click.Parameter, ctx: click.Context | None = None) -> str:
        """``[text|json|junit|github|html][,...]``."""
        return f"[{'|'.join(self.choices)}][,...]"


#: How ``-o`` files are told apart without ``--format``, for the help text: ``.json json, .xml junit, ...``.
_BY_SUFFIX = ", ".join(f"{row.suffixes[0]} {row.name}" for row in REPORT_FORMATS if row.suffixes and row.name != "text")
#: The ``-o`` value that means stdout.
STDOUT = "-"


def report_plan(formats: str | None, outputs: tuple[Path, ...]) -> list[tuple[str, Path | None]]:
    """Which report goes where: (format, file or ``None`` for stdout) in the order given.

    ``--format`` alone: that report on stdout (text without it). With ``-o``: one format per ``-o`` in order
    (``--format json,junit -o r.json -o r.xml``), or, without ``--format``, each file's format by its suffix
    (:func:`meshtool.formats.report_format_for`; any other suffix: text, as a single ``-o`` always wrote).
    ``-o -`` is stdout (``--format github,junit -o - -o r.xml``: annotations and a file from one run).

    Raises:
        ConfigError: Several formats for stdout, counts that do not pair up, or one file named twice.
    """
    from meshtool.validate import ConfigError

    names = formats.split(",") if formats else None
    if not outputs:
        if names is not None and len(names) > 1:
            raise ConfigError(
                f"--format {formats} writes {len(names)} reports, stdout takes one",
                hint="name a file for each with -o (one -o per format, in order)",
            )
        return [(names[0] if names else "text", None)]
    seen: set[str] = set()
    for out in outputs:
        key = str(out) if str(out) == STDOUT else os.path.abspath(out)
        if key in seen:
            raise ConfigError("named twice with -o", path=str(out), hint="give each report its own file")
        seen.add(key)
    places = [None if str(out) == STDOUT else out for out in outputs]
    if names is None:
        return [(getattr(report_format_for(out), "name", "text") if out else "text", out) for out in places]
    if len(names) != len(outputs):
        raise ConfigError(
            f"--format names {len(names)} format{'s' if len(names) != 1 else ''} for {len(outputs)} -o files",
            hint="give one format per -o, in order (--format json,junit -o r.json -o r.xml), "
            "or drop --format to take each from its file's suffix",
        )
    return list(zip(names, places, strict=True))


#: A check failed: the findings fail the run (docs/cli.md: exit 1).
EXIT_FINDINGS = EXIT_INPUT


def default_jobs() -> int:
    """Worker processes by default: the usable CPUs, at most 8."""
    return max(1, min(8, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1))


@click.command("validate")
@click.argument("paths", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option(
    "--config",
    "config_file",
    type=click.Path(path_type=Path, dir_okay=False),
    default=None,
    help="pyproject.toml or meshtool.toml (default: the first found from the working folder upwards).",
)
@click.option(
    "--format",
    "fmt",
    type=FormatList(FORMATS),
    default=None,
    help="Report format, or several with one -o each (json,junit,html) [default: text, or each -o's suffix].",
)
@click.option(
    "-o",
    "--output",
    "outputs",
    multiple=True,
    type=click.Path(path_type=Path, dir_okay=False, allow_dash=True),
    help="Write a report here (-: stdout); repeat for several reports of one run, the format from --format (in "
    f"order) or the suffix ({_BY_SUFFIX}, else text). Replaces an earlier report; anything else only with --force.",
)
@click.option("--force", is_flag=True, help="Let -o replace a file that is not an earlier report (never an input).")
@executor_options
@click.option(
    "--timeout",
    type=click.FloatRange(0, max_open=False),
    default=None,
    metavar="SECONDS",
    help="Stop one asset's check after this long: an X002 finding, the run goes on (default: the "
    "configuration's timeout, else 300; 0: no limit).",
)
@click.option("--strict", is_flag=True, help="Warnings fail the run (exit 1).")
@click.option("--changed-only", is_flag=True, help="Report only assets changed since the cached run.")
@click.option(
    "--cache-dir",
    type=click.Path(path_type=Path, file_okay=False),
    envvar="MESHTOOL_CACHE_DIR",
    default=None,
    help="Result cache folder [default: the user cache folder; env MESHTOOL_CACHE_DIR].",
)
@click.option("--no-cache", is_flag=True, help="Check everything again and store nothing.")
@click.option("--thumbnails/--no-thumbnails", default=None, help="Render thumbnails (default: only for --format html).")
@progress_option
@click.option("-v", "--verbose", is_flag=True, help="Text report: list clean assets and notes too.")
def validate_command(
    paths: tuple[Path, ...],
    config_file: Path | None,
    fmt: str | None,
    outputs: tuple[Path, ...],
    jobs: int | None,
    executor: str,
    scheduler: str | None,
    scheduler_timeout: float,
    timeout: float | None,
    strict: bool,
    changed_only: bool,
    cache_dir: Path | None,
    no_cache: bool,
    thumbnails: bool | None,
    show_progress: bool | None,
    verbose: bool,
    force: bool,
) -> None:
    """Check OBJ sources and .mbin packs under PATHS against the rules of docs/validate-rules.md."""
    from meshtool.validate import ConfigError, ValidateError, ValidateOptions, find_config, load_config, render
    from meshtool.validate.reports import check_report_output
    from meshtool.validate.reports.text import summary_lines, to_text

    if scheduler and executor != "dask":
        _usage(ConfigError("--scheduler needs --executor dask"))
    if changed_only and no_cache:
        _usage(ConfigError("--changed-only needs the cache (drop --no-cache)"))
    try:
        plan = report_plan(fmt, outputs)
    except ConfigError as exc:
        _usage(exc)
    wanted = {name for name, _ in plan}
    want_thumbnails = "html" in wanted if thumbnails is None else thumbnails
    # The OpenGL backend of thumbnails is chosen by the physics plugin (simrun): EGL, then OSMesa, headless.
    texts: list[tuple[str, Path | None, str]] = []
    try:
        for _, out in plan:  # before the run: a refused -o costs nothing
            if out is not None:
                check_report_output(out, list(paths), force)
        config = load_config(config_file or find_config(Path.cwd()))
        options = ValidateOptions(
            config=config,
            jobs=jobs or default_jobs(),
            executor=executor,
            scheduler=scheduler,
            cache_dir=None if no_cache else (cache_dir or Path(platformdirs.user_cache_dir("meshtool")) / "validate"),
            changed_only=changed_only,
            thumbnails=want_thumbnails,
            timeout=timeout,
            connect_timeout=scheduler_timeout,
        )
        with batch_progress(show_progress) as progress:
            result = run_validate(list(paths), options, progress)
        for line in result.cache_notes:  # a damaged or foreign cache entry: checked again, said once
            note(line)
        for name, out in plan:  # every report from the one run's results
            text = (
                to_text(result, strict, colour=_colour(out), verbose=verbose)
                if name == "text"
                else render(result, name, strict)
            )
            texts.append((name, out, text))
        for _, out, text in texts:
            if out is not None:
                write_file(out, text.encode("utf-8"))
    except ConfigError as exc:
        _usage(exc)
    except ValidateError as exc:
        if exc.usage:
            _usage(exc)
        fail(exc)
    except MeshtoolError as exc:  # an input or output refused: exit 1 as in every command (docs/cli.md)
        fail(exc)
    except Exception as exc:  # a bug in meshtool: say so, keep the traceback for MESHTOOL_DEBUG
        exit_on_bug(exc)
    for name, out, text in texts:
        if out is None:  # the one report on stdout
            report(text) if name == "json" else say(text, nl=False)
    if any(out is not None for _, out, _ in texts):
        for name, out, _ in texts:
            if out is not None:
                wrote(out, kind=f"validate report ({name})", err=True)
        first, *rest = summary_lines(result, strict, colour=sys.stderr.isatty())  # the verdict, then the run
        (verdict if result.failed(strict) else tell)(first)
        for line in rest:
            tell(line)
    if result.internal_errors():
        sys.exit(EXIT_INTERNAL)
    sys.exit(EXIT_FINDINGS if result.failed(strict) else EXIT_OK)


def _usage(exc: MeshtoolError) -> NoReturn:
    fail(exc, prefix="usage error")  # its kind says exit 2


def _colour(output: Path | None) -> bool:
    return output is None and sys.stdout.isatty() and "NO_COLOR" not in os.environ
