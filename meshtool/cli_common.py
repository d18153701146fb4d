"""The command-line vocabulary shared by ``meshtool``, ``obj2bin`` and ``simrun`` (docs/cli.md).

Every command of the three gets, from :class:`VocabularyGroup` / :class:`VocabularyCommand`:

- ``--json``: one JSON object on stdout, errors included (``{"status": "error", "exit_code": 1, "error":
  {"message": ...}}``); a command that writes its own JSON keeps it, one with text output has its lines
  wrapped (``{"status": "ok", "command": ..., "output": [...]}``); ``--format json`` means the same where a
  command has ``--format``;
- ``-q/--quiet``: nothing on stdout unless ``--json``, and no findings (warnings, notes) on stderr: errors
  still are, and the exit code says the rest (:func:`quiet_requested`);
- ``-v/--verbose``: more detail (``MESHTOOL_VERBOSE=1``: every finding); ``-vv`` also the traceback of an
  internal error (``MESHTOOL_DEBUG=1`` / ``SIMRUN_DEBUG=1``);
- the exit codes of :data:`EXIT_CODES`, and one ``error:`` line on stderr for a mistake: libraries'
  warnings and log records (numpy, trimesh, yourdfpy) are shown only with -v (:func:`quiet_libraries`).

Progress displays go to stderr and only when stderr is a terminal (:func:`progress_enabled`).
"""

from __future__ import annotations

import contextlib
import contextvars
import io
import json
import logging
import os
import sys
import warnings
from collections.abc import Iterator, Sequence
from typing import Any, NoReturn, Protocol, runtime_checkable

import click

from meshtool.progress import Display, reporting
from meshtool.safeopen import printable

EXIT_OK, EXIT_INPUT, EXIT_USAGE, EXIT_INTERNAL = 0, 1, 2, 3
#: Exit code for each kind of outcome, the same in every command (docs/cli.md).
EXIT_CODES: dict[str, int] = {
    "success (warnings allowed)": EXIT_OK,
    "an input file that does not exist, cannot be read or is not the right kind of file": EXIT_INPUT,
    "an input refused: bad syntax, values out of range, a broken reference (one error line with file:line)": EXIT_INPUT,
    "a check failed: validate findings, a scene warning, a re-simulation that differs": EXIT_INPUT,
    "an output refused: it would replace an input or a file the tool did not write (--force)": EXIT_INPUT,
    "a service that cannot be reached (a Dask scheduler), a per-asset timeout": EXIT_INPUT,
    "usage: an unknown option or command, a bad option value, a missing argument": EXIT_USAGE,
    "the tool itself failed (a bug: 'internal error:' line; -vv shows the traceback)": EXIT_INTERNAL,
}
#: Environment variable that makes an internal error raise its traceback, per program.
DEBUG_VARIABLES = {"meshtool": "MESHTOOL_DEBUG", "obj2bin": "MESHTOOL_DEBUG", "simrun": "SIMRUN_DEBUG"}
#: ``-q`` of the command running now: its findings (warnings, notes) are not printed either (errors are).
_QUIET: contextvars.ContextVar[bool] = contextvars.ContextVar("meshtool_quiet", default=False)
#: The error the running command reported through :func:`fail`, with its fields (``--json`` shows them).
_ERROR: contextvars.ContextVar[dict[str, object] | None] = contextvars.ContextVar("meshtool_error", default=None)


def quiet_requested() -> bool:
    """Whether the running command was given ``-q``/``--quiet``: print no findings, only errors."""
    return _QUIET.get()


def exit_on_bug(exc: Exception, program: str = "meshtool") -> NoReturn:
    """Say that the tool failed (a bug: please report it) and exit 3; re-raise with its debug variable set."""
    variable = DEBUG_VARIABLES.get(program, "MESHTOOL_DEBUG")
    if os.environ.get(variable):
        raise exc
    message = _single_line(f"{type(exc).__name__}: {exc}")
    click.echo(f"internal error: {message} (please report; {variable}=1 shows more)", err=True)
    sys.exit(EXIT_INTERNAL)


@runtime_checkable
class ReportedError(Protocol):
    """What meshtool's and simrun's errors share (``MeshtoolError``, ``SimrunError``): one line and fields."""

    def one_line(self) -> str:
        """The error in one line: where, what, how to fix it."""

    def to_dict(self) -> dict[str, object]:
        """Its fields, JSON-ready."""


def exit_code_of(exc: BaseException) -> int:
    """The one mapping of errors to exit codes (:data:`EXIT_CODES`, docs/cli.md).

    An error of meshtool or simrun exits with its kind's ``exit_code`` where it has one (usage errors: 2; a
    validation whose executor failed: 3) and 1 otherwise (an input, check or output refused); anything else
    is a bug: 3.
    """
    if not isinstance(exc, ReportedError):
        return EXIT_INTERNAL
    code = getattr(exc, "exit_code", None)
    return code if isinstance(code, int) and code in (EXIT_INPUT, EXIT_USAGE, EXIT_INTERNAL) else EXIT_INPUT


def fail(exc: Exception, program: str = "meshtool", prefix: str = "error") -> NoReturn:
    """Report ``exc`` and exit with :func:`exit_code_of`: one ``PREFIX: ...`` line on stderr, its fields for ``--json``.

    A bug (not an error of the project's) goes to :func:`exit_on_bug`.
    """
    if not isinstance(exc, ReportedError):
        exit_on_bug(exc, program)
    line = _single_line(exc.one_line())
    _ERROR.set({**exc.to_dict(), "message": line})
    click.echo(f"{prefix}: {line}", err=True)
    sys.exit(exit_code_of(exc))


def _single_line(text: str) -> str:
    r"""Messages (MuJoCo's among them) may hold line breaks: joined with ``; ``; stray bytes shown as ``\xNN``."""
    return printable("; ".join(part.strip() for part in text.splitlines() if part.strip()))


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

    :class:`meshtool.progress.Display` on ``sys.stderr``: a spinner, the file, the stage, the elapsed time.
    """

    def __init__(self, enabled: bool | None = None) -> None:
        super().__init__(sys.stderr, enabled)


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


class _Tee(io.StringIO):
    """Keeps what is written (and passes it on to ``target`` when given)."""

    def __init__(self, target: Any = None) -> None:
        super().__init__()
        self.target = target

    def write(self, text: str) -> int:
        """Keep, and pass on."""
        if self.target is not None:
            self.target.write(text)
        return super().write(text)

    def flush(self) -> None:
        """Flush the target."""
        if self.target is not None:
            self.target.flush()

    def text(self) -> str:
        """Everything written."""
        return self.getvalue()


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
    token, reported = _QUIET.set(quiet), _ERROR.set(None)
    try:
        with _run_vocabulary(name, as_json, quiet, verbose, program):
            yield
    finally:
        _QUIET.reset(token)
        _ERROR.reset(reported)


@contextlib.contextmanager
def _run_vocabulary(name: str, as_json: bool, quiet: bool, verbose: int, program: str) -> Iterator[None]:
    if verbose >= 1 and program in ("meshtool", "obj2bin"):
        os.environ["MESHTOOL_VERBOSE"] = "1"
    if verbose >= 2:
        os.environ[DEBUG_VARIABLES.get(program, "MESHTOOL_DEBUG")] = "1"
    if not as_json:
        display = Progress(enabled=progress_enabled() and not quiet)
        try:
            with reporting(display if display.enabled else None), contextlib.ExitStack() as stack:
                if display.enabled:
                    stack.enter_context(contextlib.redirect_stderr(_ClearFirst(display)))
                    if not quiet and _is_tty(sys.stdout):  # the same terminal: a line never runs into the progress
                        stack.enter_context(contextlib.redirect_stdout(_ClearFirst(display, sys.stdout)))
                if quiet:
                    with contextlib.redirect_stdout(io.StringIO()):
                        yield
                else:
                    yield
        finally:
            display.close()
        return
    out, err = _Tee(), _Tee(sys.stderr)
    code = EXIT_OK
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            yield
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else (EXIT_OK if exc.code is None else EXIT_INPUT)
        _emit_json(name, out.text(), err.text(), code)
        raise
    except click.exceptions.Exit as exc:
        code = exc.exit_code
        _emit_json(name, out.text(), err.text(), code)
        raise
    except click.ClickException as exc:
        _emit_json(name, out.text(), f"error: {exc.format_message()}\n", exc.exit_code)
        raise
    _emit_json(name, out.text(), err.text(), code)


def _emit_json(name: str, out: str, err: str, code: int) -> None:
    """Pass the command's own JSON through, else wrap its text lines (and its error) in one JSON object."""
    text = out.strip()
    if text:
        try:
            json.loads(text)
        except ValueError:
            pass
        else:
            sys.stdout.write(out if out.endswith("\n") else out + "\n")
            sys.stdout.flush()
            return
    prefixes = ("error: ", "usage error: ", "internal error: ", "Error: ")  # the last is click's usage message
    lines = err.splitlines()
    errors = [line[len(p) :] for line in lines for p in prefixes if line.startswith(p)]
    verdicts = [line for line in lines if line.startswith("FAILED: ")]  # a report's (validate, simrun test)
    document: dict[str, Any] = {"status": "ok" if code == EXIT_OK else "error", "command": name, "exit_code": code}
    document["output"] = [line for line in out.splitlines() if line.strip()]
    if code != EXIT_OK:
        reported = _ERROR.get()
        message = (errors or verdicts or [line for line in lines if line.strip()][-1:] or ["failed"])[0]
        document["error"] = reported if reported is not None else {"message": message}
    sys.stdout.write(json.dumps(document) + "\n")
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
