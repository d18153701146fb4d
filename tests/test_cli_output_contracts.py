"""The reporting layer (``meshtool/cli/output.py``) called in-process, checked against docs/cli.md.

Ground truth is outside the layer: docs/cli.md's exit-code table and ``--json`` description, what reaches
stdout and stderr (pytest's ``capsys``), the JSON parser reading the rendered document, and the errors'
own ``one_line``/``to_dict`` (``meshtool.errors``, ``simrun.errors``). Each test runs inside its own
outcome (:func:`begin` ... :func:`end`), as a command does.
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterator
from pathlib import Path

import pytest

from meshtool.cli import output as out
from meshtool.errors import MeshtoolError, OutputError
from meshtool.findings import info, warning
from meshtool.validate.runner import ValidateError
from simrun.errors import SceneError, UsageError

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture
def text() -> Iterator[out.Outcome]:
    """A text-mode command's outcome."""
    token = out.begin("cmd", as_json=False, quiet=False)
    yield out.current()
    out.end(token)


def _in(as_json: bool = False, quiet: bool = False, command: str = "cmd") -> out.Outcome:
    out.begin(command, as_json=as_json, quiet=quiet)
    return out.current()


@pytest.fixture(autouse=True)
def _isolated(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """No outcome leaks between tests; no verbose or debug variable from the caller's shell."""
    for variable in ("MESHTOOL_VERBOSE", "MESHTOOL_DEBUG", "SIMRUN_DEBUG"):
        monkeypatch.delenv(variable, raising=False)
    token = out._OUTCOME.set(None)
    yield
    out._OUTCOME.reset(token)


def test_the_exit_codes_are_docs_cli_md_s_table() -> None:
    rows = re.findall(r"^\| (\d) \| (.+) \|$", (ROOT / "docs" / "cli.md").read_text(), flags=re.MULTILINE)
    documented = {when: int(code) for code, when in rows}
    assert set(out.EXIT_CODES.items()) <= set(documented.items())
    assert (out.EXIT_OK, out.EXIT_INPUT, out.EXIT_USAGE, out.EXIT_INTERNAL) == (0, 1, 2, 3)
    assert out.DEBUG_VARIABLES == {"meshtool": "MESHTOOL_DEBUG", "obj2bin": "MESHTOOL_DEBUG", "simrun": "SIMRUN_DEBUG"}


def test_outside_a_command_there_is_one_fresh_text_outcome() -> None:
    first = out.current()
    assert first == out.Outcome() and out.current() is first
    assert not out.quiet_requested()
    token = out.begin("export", as_json=True, quiet=True)
    inner = out.current()
    assert (inner.command, inner.as_json, inner.quiet) == ("export", True, True) and out.quiet_requested()
    out.end(token)
    assert out.current() is first


def test_text_mode_says_lines_on_stdout_and_status_on_stderr(
    text: out.Outcome, capsys: pytest.CaptureFixture[str]
) -> None:
    out.say("two\nlines")
    out.say("same line ", nl=False)
    out.say("")
    out.wrote("a.glb", kind="glb", bytes=12)
    out.wrote(Path("b.usda"), "made b.usda", err=True)
    out.note("a note")
    out.tell("report in r.json")
    out.failed_item("x.obj: broken")
    captured = capsys.readouterr()
    assert captured.out == "two\nlines\nsame line \nwrote a.glb\n"
    assert captured.err == "made b.usda\nnote: a note\nreport in r.json\nerror: x.obj: broken\n"
    assert text.lines == ["two", "lines", "same line ", "", "wrote a.glb"]
    assert text.outputs == [{"path": "a.glb", "kind": "glb", "bytes": 12}, {"path": "b.usda"}]
    assert text.notes == ["a note"]
    assert text.messages == ["made b.usda", "report in r.json", "error: x.obj: broken"]


def test_quiet_keeps_everything_for_the_record_and_says_only_status(capsys: pytest.CaptureFixture[str]) -> None:
    outcome = _in(quiet=True)
    out.say("result")
    out.wrote("a.glb")
    out.note("hidden")
    out.tell("status")
    out.failed_item("bad")
    captured = capsys.readouterr()
    # docs/cli.md: -q is nothing on stdout and no findings or notes on stderr; errors still on stderr
    assert (captured.out, captured.err) == ("", "status\nerror: bad\n")
    assert outcome.lines == ["result", "wrote a.glb"] and outcome.notes == ["hidden"]


def test_json_mode_holds_lines_and_batch_errors_back_but_says_notes(capsys: pytest.CaptureFixture[str]) -> None:
    outcome = _in(as_json=True)
    out.say("result")
    out.note("seen")
    out.failed_item("bad")
    out.tell("status")
    captured = capsys.readouterr()
    assert (captured.out, captured.err) == ("", "note: seen\nstatus\n")
    document = json.loads(out.render_json(outcome, 0))
    assert document == {
        "status": "ok",
        "command": "cmd",
        "exit_code": 0,
        "output": ["result"],
        "outputs": [],
        "findings": [],
        "notes": ["seen"],
        "stats": {},
    }


def test_verdict_stats_and_report(text: out.Outcome, capsys: pytest.CaptureFixture[str]) -> None:
    out.verdict("FAILED: 2 assets")
    out.verdict("FAILED: later")
    assert text.error == {"message": "FAILED: 2 assets"}
    assert capsys.readouterr().err == "FAILED: 2 assets\nFAILED: later\n"
    out.stats(frames=3)
    out.stats(seconds=1.5, frames=4)
    assert text.stats == {"frames": 4, "seconds": 1.5}
    out.report({"own": [1]})
    assert text.document == {"own": [1]}
    assert json.loads(out.render_json(text, 1)) == {"own": [1]}


def test_problem_says_one_error_line_and_exits(capsys: pytest.CaptureFixture[str]) -> None:
    outcome = _in(as_json=True)
    with pytest.raises(SystemExit) as exited:
        out.problem("first\n  second  \n\n")
    assert exited.value.code == out.EXIT_INPUT
    assert outcome.error == {"message": "first; second"}
    assert capsys.readouterr().err == "error: first; second\n"
    with pytest.raises(SystemExit) as exited:
        out.problem("usage", code=out.EXIT_USAGE)
    assert exited.value.code == 2


@pytest.mark.parametrize(
    ("error", "code"),
    [
        (MeshtoolError("refused", path="a.obj", line=3, hint="fix it"), 1),
        (OutputError("exists", path="o.glb"), 1),
        (SceneError("mass: negative", path="s.toml", line=14, key="entities[3]", entity="box"), 1),
        (UsageError("--seeds 'x': expected N"), 2),
        (ValidateError("the executor died"), 3),
        (ValidateError("bad option", usage=True), 2),
        (ValueError("a bug"), 3),
        (KeyboardInterrupt(), 3),
    ],
    ids=lambda v: type(v).__name__ if isinstance(v, BaseException) else str(v),
)
def test_every_error_maps_to_its_documented_exit_code(error: BaseException, code: int) -> None:
    assert out.exit_code_of(error) == code


class _Odd(MeshtoolError):
    """A project error whose exit code is not one the table has."""

    exit_code = 7


class _Text(MeshtoolError):
    exit_code = "2"


def test_an_exit_code_outside_the_table_is_an_input_error() -> None:
    assert out.exit_code_of(_Odd("m")) == 1 and out.exit_code_of(_Text("m")) == 1
    assert isinstance(MeshtoolError("m"), out.ReportedError) and not isinstance(ValueError(), out.ReportedError)


def test_fail_reports_the_error_s_line_and_fields(capsys: pytest.CaptureFixture[str]) -> None:
    outcome = _in(as_json=True, command="play")
    error = SceneError("mass: expected a positive number", path="s.toml", line=14, key="entities[3]", entity="box")
    with pytest.raises(SystemExit) as exited:
        out.fail(error, "simrun")
    assert exited.value.code == 1
    line = "s.toml:14: entities[3] 'box': mass: expected a positive number"
    assert capsys.readouterr().err == f"error: {line}\n"
    assert outcome.error == {**error.to_dict(), "message": line}
    document = json.loads(out.render_json(outcome, 1))
    assert document["status"] == "error" and document["command"] == "play" and document["exit_code"] == 1
    assert document["error"]["line"] == 14 and document["error"]["entity"] == "box"
    with pytest.raises(SystemExit) as exited:
        out.fail(UsageError("--size: bad\nvalue"), "simrun", prefix="usage error")
    assert exited.value.code == 2
    assert capsys.readouterr().err == "usage error: --size: bad value\n"


def test_a_bug_is_an_internal_error_unless_the_debug_variable_is_set(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    outcome = _in()
    with pytest.raises(SystemExit) as exited:
        out.fail(ZeroDivisionError("division by zero"))
    assert exited.value.code == 3
    assert capsys.readouterr().err == (
        "internal error: ZeroDivisionError: division by zero (please report; MESHTOOL_DEBUG=1 shows more)\n"
    )
    assert outcome.error == {
        "type": "ZeroDivisionError",
        "message": "ZeroDivisionError: division by zero",
        "internal": True,
    }
    with pytest.raises(SystemExit):
        out.exit_on_bug(KeyError("k"), "simrun")
    assert "(please report; SIMRUN_DEBUG=1 shows more)" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        out.fail(KeyError("k"), "simrun")  # a bug in simrun names simrun's variable
    assert "(please report; SIMRUN_DEBUG=1 shows more)" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        out.exit_on_bug(KeyError("k"), "other")
    assert "MESHTOOL_DEBUG=1" in capsys.readouterr().err
    monkeypatch.setenv("SIMRUN_DEBUG", "1")
    with pytest.raises(KeyError):
        out.exit_on_bug(KeyError("k"), "simrun")
    with pytest.raises(SystemExit):
        out.exit_on_bug(KeyError("k"), "meshtool")  # the other program's variable does not count
    monkeypatch.setenv("MESHTOOL_DEBUG", "1")
    with pytest.raises(ZeroDivisionError):
        out.fail(ZeroDivisionError("x"), "obj2bin")


def test_a_usage_error_click_reported_is_the_json_error_unless_one_is_set() -> None:
    outcome = _in(as_json=True)
    out.usage_failed("No such option: --x\n", 2)
    assert outcome.error == {"message": "No such option: --x", "exit_code": 2}
    out.usage_failed("later", 2)
    assert outcome.error == {"message": "No such option: --x", "exit_code": 2}


def test_single_line_joins_lines_and_shows_stray_bytes() -> None:
    assert out.single_line("  a \n\n b\r\nc  ") == "a; b; c"
    assert out.single_line("") == ""
    assert out.single_line("bad \udcfe.obj") == "bad \\xfe.obj"


def test_render_json_of_a_failure_without_an_error_uses_the_last_status_line() -> None:
    quiet = out.Outcome(command="test", messages=["first", "FAILED: 3 of 4"], lines=["  ", "r"])
    document = json.loads(out.render_json(quiet, 1, extra="Usage: x\n\n"))
    assert document["error"] == {"message": "FAILED: 3 of 4"}
    assert document["output"] == ["Usage: x", "r"] and document["status"] == "error"
    assert json.loads(out.render_json(out.Outcome(), 2))["error"] == {"message": "failed (exit code 2)"}
    assert out.render_json(out.Outcome(document='{"a": 1}\n\n'), 0) == '{"a": 1}'
    assert out.render_json(out.Outcome(document={"b": 2}), 0) == '{"b": 2}'
    assert "\n" not in out.render_json(out.Outcome(lines=["x"], stats={"n": 1}), 0)


def test_findings_show_warnings_and_count_notes_in_text(capsys: pytest.CaptureFixture[str]) -> None:
    outcome = _in()
    lost = warning("texture-missing", "texture t.png not found", "m.mtl", 4)
    read = info("material-default", "no material: grey")
    out.findings([lost, read])
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err == (
        "warning: m.mtl:4: texture t.png not found [texture-missing]\n"
        "note: 1 more note(s) on how the input was read (-v shows them)\n"
    )
    assert outcome.findings == [lost.to_dict(), read.to_dict()]


def test_findings_of_a_folder_run_are_grouped_under_each_asset(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("MESHTOOL_VERBOSE", "1")
    outcome = _in()
    a = warning("texture-missing", "t.png not found")
    b = info("material-default", "grey", "b.obj")
    out.findings_of([("a.obj", [a]), ("b.obj", [b]), ("c.obj", [])])
    assert capsys.readouterr().err == (
        "a.obj:\n  warning: t.png not found [texture-missing]\nb.obj:\n  info: b.obj: grey [material-default]\n"
    )
    assert outcome.findings == [{**a.to_dict(), "asset": "a.obj"}, {**b.to_dict(), "asset": "b.obj"}]


def test_told_notes_are_said_once_per_code_for_the_whole_command(capsys: pytest.CaptureFixture[str]) -> None:
    outcome = _in()
    ignored = [info("mujoco-ignores-map", "MuJoCo ignores the normal map", f"{n}.mtl") for n in "abc"]
    out.findings_of([("a.obj", ignored[:1]), ("b.obj", ignored[1:])])
    assert (
        capsys.readouterr().err
        == "note: a.mtl: MuJoCo ignores the normal map (and in 2 more file(s)) [mujoco-ignores-map]\n"
    )
    assert len(outcome.findings) == 3
    out.told_once(ignored[1:])
    assert capsys.readouterr().err == (
        "note: b.mtl: MuJoCo ignores the normal map (and in 1 more file(s)) [mujoco-ignores-map]\n"
    )
    assert len(outcome.findings) == 5
    out.told_once(ignored[:1])
    assert capsys.readouterr().err == "note: a.mtl: MuJoCo ignores the normal map [mujoco-ignores-map]\n"
    assert len(outcome.findings) == 6
    out.told_once([info("mujoco-ignores-map", "no file")], record=False)
    assert capsys.readouterr().err == "note: no file [mujoco-ignores-map]\n"
    assert len(outcome.findings) == 6


def test_the_notes_of_every_asset_of_a_folder_run_are_counted_in_one_closing_line(
    capsys: pytest.CaptureFixture[str],
) -> None:
    _in()
    read = [info("material-default", f"{n}: grey") for n in "abc"]
    out.findings_of([("a.obj", read[:1]), ("b.obj", read[1:]), ("c.obj", [])])
    assert capsys.readouterr().err == "note: 3 more note(s) on how the input was read (-v shows them)\n"


@pytest.mark.parametrize(("as_json", "quiet"), [(True, False), (False, True)])
def test_findings_are_not_on_stderr_with_json_or_quiet(
    as_json: bool, quiet: bool, capsys: pytest.CaptureFixture[str]
) -> None:
    outcome = _in(as_json=as_json, quiet=quiet)
    found = [warning("texture-missing", "gone"), info("mujoco-ignores-map", "ignored")]
    out.findings(found, "a.obj")
    out.told_once(found[1:])
    assert capsys.readouterr().err == ""
    assert [f["asset"] for f in outcome.findings[:2]] == ["a.obj", "a.obj"] and len(outcome.findings) == 3
