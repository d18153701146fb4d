"""``simrun test``: the click layer over :mod:`simrun.scenetest`.

Exit codes (as ``meshtool validate``): 0 every run passed; 1 a run failed or could not finish, or a scene,
commands file or expectation is invalid (one ``error:`` line with FILE:LINE), or the Dask scheduler cannot
be reached; 2 usage (bad options, ``--seeds``/``--vary`` values, no scene found); 3 simrun itself failed
(a worker crashed or a bug; ``SIMRUN_DEBUG=1`` shows the traceback).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import NoReturn

import click

from meshtool.cli.common import batch_progress, executor_options, progress_option
from meshtool.cli.output import (
    EXIT_INPUT,
    EXIT_INTERNAL,
    EXIT_OK,
    EXIT_USAGE,
    exit_code_of,
    fail,
    problem,
    report,
    say,
    tell,
    verdict,
    wrote,
)
from meshtool.files.safeopen import printable
from simrun.errors import SimrunError, UsageError

#: A test failed (docs/cli.md: exit 1, as a check that failed in every command).
EXIT_FAILED = EXIT_INPUT


def _jobs() -> int:
    """Worker processes by default: the usable CPUs, at most 8."""
    return max(1, min(8, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1))


@click.command("test")
@click.argument("paths", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option("--seeds", default="0", show_default=True, help="Seeds: START:STOP (STOP excluded), N or N1,N2,...")
@click.option(
    "--vary",
    multiple=True,
    metavar="KEY=SPEC",
    help="Vary NAME.PARAMETER: START:STOP:COUNT (a grid), uniform(A,B), normal(MEAN,SD), choice(V1,...) or a "
    "number. Repeatable.",
)
@click.option(
    "--max-runs",
    type=click.IntRange(1, 1_000_000),  # vary.MAX_RUNS (vary loads numpy: imported when the command runs)
    default=10_000,  # vary.DEFAULT_MAX_RUNS
    show_default=True,
    metavar="N",
    help="Refuse more runs per scene than N (seeds x the values of every --vary grid), before planning any.",
)
@executor_options
@click.option(
    "--timeout",
    type=click.FloatRange(0, min_open=True),
    default=None,
    metavar="SECONDS",
    help="Stop a run after this long (an error for that run): it runs in a worker process, even with -j 1.",
)
@click.option(
    "--format", "fmt", type=click.Choice(["text", "json", "junit", "github", "html"]), default="text", show_default=True
)
@click.option("-o", "--output", type=click.Path(path_type=Path, dir_okay=False), help="Write the report here.")
@click.option(
    "--record-failures",
    "record_dir",
    type=click.Path(path_type=Path, file_okay=False),
    default=None,
    help="Write each failed run (scene as run, its files, a .simlog for simrun resim) under this folder.",
)
@click.option("--thumbnails/--no-thumbnails", default=None, help="Picture failed runs (default: only for html).")
@click.option("--force", is_flag=True, help="Replace files under --record-failures that simrun did not write.")
@progress_option
@click.option("-v", "--verbose", is_flag=True, help="Text report: list every run and expectation.")
def test_command(
    paths: tuple[Path, ...],
    seeds: str,
    vary: tuple[str, ...],
    max_runs: int,
    jobs: int | None,
    executor: str,
    scheduler: str | None,
    scheduler_timeout: float,
    timeout: float | None,
    fmt: str,
    output: Path | None,
    record_dir: Path | None,
    thumbnails: bool | None,
    force: bool,
    show_progress: bool | None,
    verbose: bool,
) -> None:
    """Run every scene under PATHS x seed x variation and check its [[expect]] tables (docs/scene-format.md)."""
    from meshtool.files.outdir import write_file
    from meshtool.work.batch import BatchError
    from simrun.outfile import output_policy
    from simrun.scenetest.reports import render, session_line, to_text, verdict_line
    from simrun.scenetest.runner import TestOptions, run_tests
    from simrun.scenetest.spec import SpecError
    from simrun.scenetest.vary import VaryError, check_run_count, parse_seeds, parse_vary

    if scheduler and executor != "dask":
        _usage("--scheduler needs --executor dask")
    try:
        options = TestOptions(
            seeds=parse_seeds(seeds),
            axes=[parse_vary(v) for v in vary],
            jobs=jobs or _jobs(),
            executor=executor,
            scheduler=scheduler,
            connect_timeout=scheduler_timeout,
            timeout=timeout,
            record_dir=record_dir,
            thumbnails=fmt == "html" if thumbnails is None else thumbnails,
        )
        keys = [a.key for a in options.axes]
        if len(set(keys)) != len(keys):
            _usage("--vary: a key is given twice")
        check_run_count(options.seeds, options.axes, max_runs)  # before any scene is read or run planned
        with output_policy(force, list(paths)), batch_progress(show_progress) as progress:
            result = run_tests(list(paths), options, progress)
        # names on disk that are not UTF-8 (surrogate escapes) are shown as \xNN, as everywhere else
        text = printable(to_text(result, verbose) if fmt == "text" else render(result, fmt))
        if output is not None:
            write_file(output, text.encode("utf-8"))
    except (SpecError, VaryError) as exc:  # a usage error, or a missing input: exit 1 (docs/cli.md)
        fail(exc, "simrun", "usage error" if exit_code_of(exc) == EXIT_USAGE else "error")
    except BatchError as exc:  # dask.distributed missing, or the scheduler unreachable: one line, exit 1
        if exc.code == "dask-missing":
            problem(f"{exc.message} ({exc.hint})", EXIT_FAILED)
        problem(f"{exc.message}; {exc.hint}", EXIT_FAILED)
    except SimrunError as exc:
        fail(exc, "simrun")
    except OSError as exc:
        problem(str(exc), EXIT_FAILED)
    tell(session_line(result))
    if output is None:
        report(text) if fmt == "json" else say(text, nl=False)
    else:  # the verdict last: it is the message of --json's envelope when the report went to a file
        wrote(output, kind=f"scene test report ({fmt})", err=True)
        (verdict if result.failed() else tell)(verdict_line(result))
    if result.internal():
        sys.exit(EXIT_INTERNAL)
    sys.exit(EXIT_FAILED if result.failed() else EXIT_OK)


def _usage(message: str) -> NoReturn:
    fail(UsageError(message), "simrun", "usage error")
