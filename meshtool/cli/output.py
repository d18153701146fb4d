"""The one reporting layer of ``meshtool``, ``obj2bin`` and ``simrun``: what a command produced, and how it is shown.

A command does not print. It tells the running :class:`Outcome` what it did, and this module renders that as
text or as one JSON document, and maps errors to the exit codes of :data:`EXIT_CODES` (docs/cli.md):

- :func:`say` a result line (stdout), :func:`wrote` an output file (its path, kind and size; says
  ``wrote PATH ...``), :func:`findings` an asset's findings (stderr: warnings, and every note with ``-v``;
  grouped under the asset's name in a folder run), :func:`note` a ``note:`` line, :func:`tell` a status line
  on stderr (the report went to a file), :func:`verdict` a failed check's summary, :func:`stats` numbers,
  :func:`report` a command's own JSON document (``validate``'s report, ``simrun check``'s summary);
- :func:`fail` reports an error (one ``error:`` line, its fields for ``--json``) and exits with
  :func:`exit_code_of`; :func:`exit_on_bug` reports a bug (exit 3).

Text: lines as they come, findings and notes on stderr, nothing of either with ``-q`` (errors are always
shown). ``--json``: nothing on stdout until the command ends, then one object: the command's own document
when it has one, else ``{"status", "command", "exit_code", "output": [lines], "outputs": [files],
"findings", "notes", "stats", "error"}`` (:func:`render_json`). Findings are in it, not on stderr; notes are in both.
"""

from __future__ import annotations

import contextvars
import json
import os
import sys
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn, Protocol, runtime_checkable

import click

from meshtool.files.safeopen import printable

if TYPE_CHECKING:
    from meshtool.findings import Finding

EXIT_OK, EXIT_INPUT, EXIT_USAGE, EXIT_INTERNAL = 0, 1, 2, 3
#: Exit code for each kind of outcome, the same in every command (docs/cli.md).
EXIT_CODES: dict[str, int] = {
    "success (warnings allowed)": EXIT_OK,
    "an input file that does not exist, cannot be read or is not the right kind of file": EXIT_INPUT,
    "an input refused: bad syntax, values out of range, a broken reference (one error line with file:line)": EXIT_INPUT,
    "a check failed: validate findings, a scene warning, a re-simulation that differs": EXIT_INPUT,
    "an output refused: it would replace an input or a file the tool did not write (--force)": EXIT_INPUT,
    "an output that cannot be written: a name over 255 bytes, a missing or read-only folder, a full disk": EXIT_INPUT,
    "a service that cannot be reached (a Dask scheduler), a per-asset timeout": EXIT_INPUT,
    "usage: an unknown option or command, a bad option value, a missing argument": EXIT_USAGE,
    "the tool itself failed (a bug: 'internal error:' line; -vv shows the traceback)": EXIT_INTERNAL,
}
#: Environment variable that makes an internal error raise its traceback, per program.
DEBUG_VARIABLES = {"meshtool": "MESHTOOL_DEBUG", "obj2bin": "MESHTOOL_DEBUG", "simrun": "SIMRUN_DEBUG"}


@dataclass
class Outcome:
    """What the running command produced: the structured result that text and JSON are rendered from.

    Attributes:
        command: The command's name (``export``, ``check``; ``obj2bin``).
        as_json: ``--json`` (or ``--format json``): one JSON document on stdout at the end.
        quiet: ``-q``: no result lines, findings or notes in text (errors are shown).
        lines: Result lines (stdout in text).
        outputs: Files written: ``{"path", "kind", ...}`` (``bytes`` where known).
        findings: Findings as dicts (``asset`` names the input in a folder run).
        notes: ``note:`` lines without the prefix.
        messages: Status lines said on stderr (:func:`tell`).
        stats: Numbers the command reports (units in their keys or docs).
        document: The command's own JSON document, shown instead of the generic one.
        error: The reported error's fields (:func:`fail`) or a failed check's verdict.
    """

    command: str = ""
    as_json: bool = False
    quiet: bool = False
    lines: list[str] = field(default_factory=list)
    outputs: list[dict[str, Any]] = field(default_factory=list)
    findings: list[dict[str, Any]] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    messages: list[str] = field(default_factory=list)
    stats: dict[str, Any] = field(default_factory=dict)
    document: dict[str, Any] | str | None = None
    error: dict[str, object] | None = None


_OUTCOME: contextvars.ContextVar[Outcome | None] = contextvars.ContextVar("meshtool_outcome", default=None)


def current() -> Outcome:
    """The running command's outcome (a fresh text one outside a command: library use, tests)."""
    outcome = _OUTCOME.get()
    if outcome is None:
        outcome = Outcome()
        _OUTCOME.set(outcome)
    return outcome


def begin(command: str, as_json: bool, quiet: bool) -> contextvars.Token[Outcome | None]:
    """Start the outcome of one command (the vocabulary does); :func:`end` with the token."""
    return _OUTCOME.set(Outcome(command=command, as_json=as_json, quiet=quiet))


def end(token: contextvars.Token[Outcome | None]) -> None:
    """Forget the command's outcome."""
    _OUTCOME.reset(token)


def quiet_requested() -> bool:
    """Whether the running command was given ``-q``/``--quiet``: print no findings, only errors."""
    return current().quiet


def say(text: str, nl: bool = True) -> None:
    """A result line (or text: a report): stdout in text (not with ``-q``), ``output`` in JSON."""
    outcome = current()
    outcome.lines.extend(text.splitlines() or [""])
    if not outcome.as_json and not outcome.quiet:
        click.echo(text, nl=nl)


def wrote(path: Path | str, text: str | None = None, kind: str | None = None, err: bool = False, **fields: Any) -> None:
    """An output file or folder written: in ``outputs``; said as ``text`` (default ``wrote PATH``).

    ``err``: said on stderr (:func:`tell`), where stdout carries something else.
    """
    entry: dict[str, Any] = {"path": str(path)}
    if kind is not None:
        entry["kind"] = kind
    entry.update(fields)
    current().outputs.append(entry)
    (tell if err else say)(text if text is not None else f"wrote {path}")


def problem(text: str, code: int = EXIT_INPUT) -> NoReturn:
    """An error the command found itself (no exception carries it): one ``error:`` line, exit ``code``."""
    line = single_line(text)
    current().error = {"message": line}
    click.echo(f"error: {line}", err=True)
    sys.exit(code)


def failed_item(text: str) -> None:
    """One item of a batch failed (the batch goes on): an ``error:`` line on stderr in text; in ``messages``."""
    outcome = current()
    outcome.messages.append(f"error: {text}")
    if not outcome.as_json:
        click.echo(f"error: {text}", err=True)


def note(text: str) -> None:
    """A ``note:`` line on stderr (not with ``-q``; with ``--json`` too), and in ``notes`` of JSON."""
    outcome = current()
    outcome.notes.append(text)
    if not outcome.quiet:
        click.echo(f"note: {text}", err=True)


def tell(text: str) -> None:
    """A status line on stderr (a report written to a file, a session summary), in both modes; ``messages``."""
    current().messages.append(text)
    click.echo(text, err=True)


def verdict(text: str) -> None:
    """A failed check's one-line summary on stderr: the ``error`` message of ``--json`` unless an error is set."""
    outcome = current()
    if outcome.error is None:
        outcome.error = {"message": text}
    tell(text)


def stats(**numbers: Any) -> None:
    """Numbers the command reports (``stats`` in JSON)."""
    current().stats.update(numbers)


def report(document: dict[str, Any] | str) -> None:
    """The command's own JSON document (or its JSON text): what ``--json`` prints (text mode says its lines)."""
    current().document = document


def findings(found: Sequence[Finding], asset: str | None = None) -> None:
    """One asset's findings (``asset``: its name, as a heading in a folder run). See :func:`findings_of`."""
    findings_of([(asset, list(found))])


def findings_of(groups: Iterable[tuple[str | None, list[Finding]]]) -> None:
    """The findings of each asset, under its name when it has one; nothing on stderr with ``-q`` or ``--json``.

    Warnings are shown, notes on how the input was read only with ``-v`` (else counted in one closing line), and
    the :data:`~meshtool.changes.TOLD_NOTES` once per code for the whole command. ``--json`` has them all.
    """
    from meshtool.changes import TOLD_NOTES, split_findings

    outcome = current()
    groups = list(groups)
    for heading, found in groups:
        outcome.findings.extend({**f.to_dict(), **({"asset": heading} if heading is not None else {})} for f in found)
    if outcome.quiet or outcome.as_json:
        return
    verbose = bool(os.environ.get("MESHTOOL_VERBOSE"))
    told: list[Finding] = []
    hidden = 0
    for heading, found in groups:
        told += [f for f in found if f.code in TOLD_NOTES]
        shown, notes = split_findings(f for f in found if f.code not in TOLD_NOTES)
        listed = [*shown, *notes] if verbose else shown
        hidden += 0 if verbose else len(notes)
        if heading is not None and listed:
            click.echo(f"{heading}:", err=True)
        for finding in listed:
            click.echo(("  " if heading is not None else "") + finding.one_line(), err=True)
    told_once(told, record=False)
    if hidden:
        click.echo(f"note: {hidden} more note(s) on how the input was read (-v shows them)", err=True)


def told_once(told: Sequence[Finding], record: bool = True) -> None:
    """The :data:`~meshtool.changes.TOLD_NOTES` as ``note:`` lines, one per code for the whole command."""
    outcome = current()
    if record:
        outcome.findings.extend(f.to_dict() for f in told)
    if outcome.quiet or outcome.as_json:
        return
    for code in sorted({f.code for f in told}):
        same = [f for f in told if f.code == code]
        first = same[0]
        where = f"{first.where}: " if first.where else ""
        more = f" (and in {len(same) - 1} more file(s))" if len(same) > 1 else ""
        click.echo(f"note: {where}{first.message}{more} [{code}]", err=True)


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
    line = single_line(exc.one_line())
    current().error = {**exc.to_dict(), "message": line}
    click.echo(f"{prefix}: {line}", err=True)
    sys.exit(exit_code_of(exc))


def exit_on_bug(exc: Exception, program: str = "meshtool") -> NoReturn:
    """Say that the tool failed (a bug: please report it) and exit 3; re-raise with its debug variable set."""
    variable = DEBUG_VARIABLES.get(program, "MESHTOOL_DEBUG")
    if os.environ.get(variable):
        raise exc
    message = single_line(f"{type(exc).__name__}: {exc}")
    current().error = {"type": type(exc).__name__, "message": message, "internal": True}
    click.echo(f"internal error: {message} (please report; {variable}=1 shows more)", err=True)
    sys.exit(EXIT_INTERNAL)


def usage_failed(message: str, code: int) -> None:
    """A usage error click reported itself (its message): the ``error`` of ``--json``."""
    outcome = current()
    if outcome.error is None:
        outcome.error = {"message": single_line(message), "exit_code": code}


def single_line(text: str) -> str:
    r"""Messages (MuJoCo's among them) may hold line breaks: joined with ``; ``; stray bytes shown as ``\xNN``."""
    return printable("; ".join(part.strip() for part in text.splitlines() if part.strip()))


def render_json(outcome: Outcome, code: int, extra: str = "") -> str:
    """The one JSON document of a finished command (a line).

    The command's own document when it made one; else the generic object of the module docstring.
    ``extra`` is text something outside the command printed on stdout (click's ``--help``, ``--version``):
    its lines join ``output``.
    """
    if isinstance(outcome.document, str):
        return outcome.document.rstrip("\n")
    if outcome.document is not None:
        return json.dumps(outcome.document)
    document: dict[str, Any] = {"status": "ok" if code == EXIT_OK else "error", "command": outcome.command}
    document["exit_code"] = code
    document["output"] = [line for line in [*extra.splitlines(), *outcome.lines] if line.strip()]
    document["outputs"] = outcome.outputs
    document["findings"] = outcome.findings
    document["notes"] = outcome.notes
    document["stats"] = outcome.stats
    if code != EXIT_OK:
        document["error"] = outcome.error if outcome.error is not None else {"message": _last_words(outcome, code)}
    return json.dumps(document)


def _last_words(outcome: Outcome, code: int) -> str:
    """What to call a failure that reported no error: its last status line, or the exit code."""
    return outcome.messages[-1] if outcome.messages else f"failed (exit code {code})"
