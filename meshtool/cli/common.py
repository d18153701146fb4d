"""The command-line vocabulary shared by ``meshtool``, ``obj2bin`` and ``simrun`` (docs/cli.md).

Every command of the three gets, from :class:`VocabularyGroup` / :class:`VocabularyCommand`:

- ``--json``: one JSON object on stdout, errors included (``{"status": "error", "exit_code": 1, "error":
  {"message": ...}}``), rendered from the command's :class:`meshtool.cli.output.Outcome` (its own document,
  or its lines, outputs, findings and stats); ``--format json`` means the same where a command has ``--format``;
- ``-q/--quiet``: nothing on stdout unless ``--json``, and no findings (warnings, notes) on stderr: errors
  still are, and the exit code says the rest (:func:`meshtool.cli.output.quiet_requested`);
- ``-v/--verbose``: more detail (``MESHTOOL_VERBOSE=1``: every finding); ``-vv`` also the traceback of an
  internal error (``MESHTOOL_DEBUG=1`` / ``SIMRUN_DEBUG=1``);
- the exit codes of :data:`meshtool.cli.output.EXIT_CODES`, and one ``error:`` line on stderr for a mistake: libraries'
  warnings and log records (numpy, trimesh, yourdfpy) are shown only with -v (:func:`quiet_libraries`).

Progress displays go to stderr and only when stderr is a terminal (:func:`progress_enabled`). The batch
commands (``obj2bin DIR``, ``meshtool validate``, ``simrun test``) draw one batch line
(:meth:`meshtool.work.progress.Tick.line`) there, or, with ``--progress`` where stderr is not a terminal
(a CI log), write it as a plain line at most every :data:`PLAIN_PERIOD_S` seconds and once at the end
(:func:`batch_progress`).
"""

from __future__ import annotations

import contextlib
import contextvars
import io
import logging
import os
import sys
import time
import warnings
from collections.abc import Iterator, Sequence
from typing import Any

import click

from meshtool.cli.output import (
    DEBUG_VARIABLES,
    EXIT_INPUT,
    EXIT_OK,
    begin,
    current,
    end,
    render_json,
    usage_failed,
)
from meshtool.work.progress import Display, Tick, TickSink, reporting

#: Seconds between two plain batch lines (``--progress`` into a log).
PLAIN_PERIOD_S = 1.0


def executor_options(func: Any) -> Any:
    """Add ``-j/--jobs``, ``--executor``, ``--scheduler`` and ``--scheduler-timeout``.

    The options of the commands that spread work over processes or a Dask cluster (``validate``, ``simrun test``).
    """
    for decorator in reversed(
        [
            click.option(
                "-j", "--jobs", type=click.IntRange(1, 256), default=None, help="Workers (default: CPUs, at most 8)."
            ),
            click.option("--executor", type=click.Choice(["local", "dask"]), default="local", show_default=True),
            click.option(
                "--scheduler", default=None, metavar="ADDRESS", help="Dask scheduler (tcp://host:8786); needs dask."
            ),
            click.option(
                "--scheduler-timeout",
                type=click.FloatRange(0, min_open=True),
                default=30.0,
                show_default=True,
                metavar="SECONDS",
                help="How long to try reaching --scheduler.",
            ),
        ]
    ):
        func = decorator(func)
    return func


def progress_option(func: Any) -> Any:
    """Add ``--progress/--no-progress``: the batch line on stderr (default: only when stderr is a terminal)."""
    return click.option(
        "--progress/--no-progress",
        "show_progress",
        default=None,
        help="Show the progress line on stderr [default: only on a terminal; into a log: one line a second].",
    )(func)


@contextlib.contextmanager
def batch_progress(show: bool | None) -> Iterator[TickSink | None]:
    """The callback that draws a batch's progress line, for the length of the batch (``None``: draw nothing).

    Args:
        show: ``--progress`` (``True``), ``--no-progress`` (``False``: the stage line of the work is not drawn
            either) or neither (``None``: on a terminal only, never with ``--json`` or ``-q``).

    On a terminal the line is the progress display's (redrawn in place, cleared before other output); else,
    with ``--progress``, a plain line on stderr at most every :data:`PLAIN_PERIOD_S` seconds and the last one.
    """
    display = _DISPLAY.get()
    if show is False:
        with reporting(None):
            yield None
        return
    if display is not None:
        try:
            yield lambda tick: display.batch(tick.line())
        finally:
            display.batch(None)
        return
    if not show:
        yield None
        return
    yield _PlainLines(time.monotonic)


class _PlainLines:
    """Batch lines written whole to stderr (a log): one per :data:`PLAIN_PERIOD_S` at most, and the last."""

    def __init__(self, clock: Any) -> None:
        self.clock = clock
        self.written: float | None = None

    def __call__(self, tick: Tick) -> None:
        now = self.clock()
        if tick.done < tick.total and self.written is not None and now - self.written < PLAIN_PERIOD_S:
            return
        self.written = now
        sys.stderr.write(tick.line() + "\n")
        sys.stderr.flush()


def progress_enabled() -> bool:
    """Whether to draw progress: only on a terminal's stderr (never into a pipe, a log or a JSON stream)."""
    return _is_tty(sys.stderr)


def _is_tty(stream: Any) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):
        return False


class Progress(Display):
    """A progress display on stderr for long work (stages, parts); silent when not on a terminal.

    :class:`meshtool.work.progress.Display` on ``sys.stderr``: a spinner, the file, the stage, the elapsed time.
    """

    def __init__(self, enabled: bool | None = None) -> None:
        super().__init__(sys.stderr, enabled)


#: The progress display drawing on this command's terminal, when one does.
_DISPLAY: contextvars.ContextVar[Progress | None] = contextvars.ContextVar("meshtool_display", default=None)


class _ClearFirst(io.TextIOBase):
    """A stream (stdout, stderr) of the progress line's terminal: the line is cleared before text is written."""

    def __init__(self, display: Progress, target: Any = None) -> None:
        super().__init__()
        self.display = display
        self.target = display.stream if target is None else target

    def write(self, text: str) -> int:
        """Clear the progress line, then write."""
        return self.display.write_above(self.target, text)

    def flush(self) -> None:
        """Flush the terminal."""
        self.target.flush()

    def isatty(self) -> bool:
        """The terminal's answer."""
        return bool(self.target.isatty())


def _flags(args: Sequence[str]) -> tuple[bool, bool, int]:
    """(json, quiet, verbosity) from a command's raw arguments (before click parses them)."""
    as_json = quiet = False
    verbose = 0
    previous = ""
    for arg in args:
        if arg == "--":
            break
        if arg == "--json" or arg == "--format=json" or (previous == "--format" and arg == "json"):
            as_json = True
        elif arg in ("-q", "--quiet"):
            quiet = True
        elif arg == "--verbose":
            verbose += 1
        elif arg.startswith("-v") and set(arg[1:]) == {"v"}:
            verbose += len(arg) - 1
        previous = arg
    return as_json, quiet, verbose


def equip(command: click.Command) -> click.Command:
    """Give a command the shared options it lacks (``-q``, ``-v``, ``--json``); the flags are read by the group."""
    if getattr(command, "_vocabulary", False):
        return command
    taken = {opt for param in command.params for opt in getattr(param, "opts", [])}
    extra: list[click.Option] = []
    if "-q" not in taken and "--quiet" not in taken:
        extra.append(click.Option(["-q", "--quiet"], is_flag=True, expose_value=False, help="Print nothing on stdout."))
    if "-v" not in taken and "--verbose" not in taken:
        extra.append(
            click.Option(
                ["-v", "--verbose"],
                count=True,
                expose_value=False,
                help="More detail; -vv also the traceback of an internal error.",
            )
        )
    if "--json" not in taken:
        fmt = next((p for p in command.params if "--format" in getattr(p, "opts", [])), None)
        choices = getattr(getattr(fmt, "type", None), "choices", ())
        text = "The same as --format json." if "json" in choices else "Print one JSON object on stdout."
        extra.append(click.Option(["--json"], is_flag=True, expose_value=False, help=text))
    command.params.extend(extra)
    command._vocabulary = True  # type: ignore[attr-defined]
    return command


def _with_format(command: click.Command, args: list[str]) -> list[str]:
    """``--json`` as ``--format json`` for a command whose ``--format`` offers json (and has no ``--json``)."""
    own = {opt for param in command.params if param.expose_value for opt in getattr(param, "opts", [])}
    if "--json" in args and "--json" not in own and "--format" in own:
        at = args.index("--json")
        return [*args[:at], "--format", "json", *args[at + 1 :]]
    return args


@contextlib.contextmanager
def quiet_libraries() -> Iterator[None]:
    """Keep what libraries say off stderr: Python warnings and log records nobody configured.

    Python warnings are numpy's ``RuntimeWarning: overflow``, trimesh's...; log records yourdfpy's ``Using
    different parsing approach.``. A command's own output is its ``error:`` line and findings; -v (or the
    debug variable) shows the rest.
    """
    root = logging.getLogger()
    handler = logging.NullHandler()  # a handler on the root: logging's last-resort stderr printer stays unused
    root.addHandler(handler)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            yield
    finally:
        root.removeHandler(handler)


@contextlib.contextmanager
def vocabulary(program: str, name: str, args: Sequence[str]) -> Iterator[None]:
    """Run one command with the shared ``--json`` / ``-q`` / ``-v`` behaviour (see the module).

    Without -v (or the program's debug variable) libraries' warnings and log records are not shown
    (:func:`quiet_libraries`).
    """
    verbose = _flags(args)[2]
    loud = verbose >= 1 or bool(os.environ.get(DEBUG_VARIABLES.get(program, "MESHTOOL_DEBUG")))
    with contextlib.ExitStack() as stack:
        if not loud:
            stack.enter_context(quiet_libraries())
        with _vocabulary(program, name, args):
            yield


@contextlib.contextmanager
def _vocabulary(program: str, name: str, args: Sequence[str]) -> Iterator[None]:
    as_json, quiet, verbose = _flags(args)
    token = begin(name, as_json, quiet)
    try:
        with _run_vocabulary(as_json, quiet, verbose, program):
            yield
    finally:
        end(token)


@contextlib.contextmanager
def _run_vocabulary(as_json: bool, quiet: bool, verbose: int, program: str) -> Iterator[None]:
    if verbose >= 1 and program in ("meshtool", "obj2bin"):
        os.environ["MESHTOOL_VERBOSE"] = "1"
    if verbose >= 2:
        os.environ[DEBUG_VARIABLES.get(program, "MESHTOOL_DEBUG")] = "1"
    if not as_json:
        display = Progress(enabled=progress_enabled() and not quiet)
        token = _DISPLAY.set(display if display.enabled else None)
        try:
            with reporting(display if display.enabled else None), contextlib.ExitStack() as stack:
                if display.enabled:
                    stack.enter_context(contextlib.redirect_stderr(_ClearFirst(display)))
                    if not quiet and _is_tty(sys.stdout):  # the same terminal: a line never runs into the progress
                        stack.enter_context(contextlib.redirect_stdout(_ClearFirst(display, sys.stdout)))
                if quiet:  # click's own text too (the result lines are not said with -q)
                    stack.enter_context(contextlib.redirect_stdout(io.StringIO()))
                yield
        finally:
            _DISPLAY.reset(token)
            display.close()
        return
    extra = io.StringIO()  # only click's own text (--help, --version) reaches stdout in JSON mode
    try:
        with contextlib.redirect_stdout(extra):
            yield
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else (EXIT_OK if exc.code is None else EXIT_INPUT)
        _emit(code, extra.getvalue())
        raise
    except click.exceptions.Exit as exc:
        _emit(exc.exit_code, extra.getvalue())
        raise
    except click.ClickException as exc:
        usage_failed(exc.format_message(), exc.exit_code)
        _emit(exc.exit_code, extra.getvalue())
        raise
    _emit(EXIT_OK, extra.getvalue())


def _emit(code: int, extra: str) -> None:
    """Write the command's one JSON document (:func:`meshtool.cli.output.render_json`) on the real stdout."""
    sys.stdout.write(render_json(current(), code, extra) + "\n")
    sys.stdout.flush()


class VocabularyGroup(click.Group):
    """A click group whose commands share the vocabulary of the module (options added when they are fetched)."""

    program = "meshtool"

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        """The command, equipped with the shared options."""
        command = super().get_command(ctx, cmd_name)
        return equip(command) if command is not None else None

    def resolve_command(
        self, ctx: click.Context, args: list[str]
    ) -> tuple[str | None, click.Command | None, list[str]]:
        """Also maps ``--json`` to ``--format json`` where that is the command's spelling."""
        name, command, rest = super().resolve_command(ctx, args)
        if command is not None:
            rest = _with_format(command, rest)
        return name, command, rest

    def invoke(self, ctx: click.Context) -> Any:
        """Run the command inside :func:`vocabulary`."""
        with warnings.catch_warnings():  # click 8.2 deprecates protected_args (click 9 keeps them in args)
            warnings.simplefilter("ignore", DeprecationWarning)
            args = [*ctx.protected_args, *ctx.args]
        name = args[0] if args else ""
        with vocabulary(self.program, name, args[1:]):
            return self.run_command(ctx)

    def run_command(self, ctx: click.Context) -> Any:
        """The group's own invocation (a subclass adds its error mapping here)."""
        return super().invoke(ctx)


class VocabularyCommand(click.Command):
    """A single-command program (``obj2bin``) with the shared vocabulary."""

    program = "obj2bin"

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        equip(self)

    def main(self, args: Sequence[str] | None = None, *rest: Any, **kwargs: Any) -> Any:
        """The console-script entry: the raw arguments decide ``--json``/``-q``/``-v`` before click parses them."""
        raw = list(sys.argv[1:] if args is None else args)
        with vocabulary(self.program, self.name or "", raw):
            return super().main(raw, *rest, **kwargs)
