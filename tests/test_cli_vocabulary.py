"""One command-line vocabulary (issue 14 item 6): every command of meshtool, obj2bin and simrun follows docs/cli.md."""

import json
import os
import pty
import subprocess
import sys
from pathlib import Path

import click
import pytest
from click.testing import CliRunner

from meshtool.cli.main import main as meshtool_main
from meshtool.cli.mesh_commands import obj2bin
from meshtool.cli.output import EXIT_CODES
from simrun.cli.main import main as simrun_main

ROOT = Path(__file__).resolve().parent.parent
DOC = (ROOT / "docs" / "cli.md").read_text()
HEAD = ROOT / "fixtures" / "head" / "Head 1.obj"
SCENE = ROOT / "fixtures" / "scenes" / "basic.toml"


def _commands() -> list[tuple[str, click.Command]]:
    found: list[tuple[str, click.Command]] = [("obj2bin", obj2bin)]
    for program, group in (("meshtool", meshtool_main), ("simrun", simrun_main)):
        ctx = click.Context(group)
        for name in group.list_commands(ctx):
            command = group.get_command(ctx, name)
            assert command is not None
            found.append((f"{program} {name}", command))
    return found


COMMANDS = _commands()


@pytest.mark.parametrize(("label", "command"), COMMANDS, ids=[c[0] for c in COMMANDS])
def test_every_command_has_the_shared_options(label, command):
    options = {opt for param in command.params for opt in getattr(param, "opts", [])}
    assert {"--json", "-q", "--quiet", "-v", "--verbose"} <= options, label


def _invoke(program: str, args: list[str]):
    runner = CliRunner()
    if program == "obj2bin":
        return runner.invoke(obj2bin, args)
    return runner.invoke({"meshtool": meshtool_main, "simrun": simrun_main}[program], args)


MISSING = "/nonexistent/missing"
#: Each command that reads an input file, called with one that does not exist.
MISSING_INPUT = [
    ("obj2bin", [f"{MISSING}.obj"]),
    ("meshtool", ["normalize", f"{MISSING}.obj", "-o", "{tmp}/out"]),
    ("meshtool", ["hulls", f"{MISSING}.obj"]),
    ("meshtool", ["info", f"{MISSING}.mbin"]),
    ("meshtool", ["unpack", f"{MISSING}.mbin", "-o", "{tmp}/out"]),
    ("meshtool", ["export", f"{MISSING}.mbin", "--glb", "{tmp}/out.glb"]),
    ("meshtool", ["mjcf", f"{MISSING}.mbin", "-o", "{tmp}/out"]),
    ("meshtool", ["urdf", f"{MISSING}.urdf", "-o", "{tmp}/out"]),
    ("meshtool", ["validate", MISSING]),
    ("simrun", ["check", f"{MISSING}.toml"]),
    ("simrun", ["play", f"{MISSING}.toml"]),
    ("simrun", ["export", f"{MISSING}.toml", "--glb", "{tmp}/out.glb"]),
    ("simrun", ["snapshot", f"{MISSING}.toml", "-o", "{tmp}/out.png"]),
    ("simrun", ["replay", f"{MISSING}.simlog", "--video", "{tmp}/out.gif"]),
    ("simrun", ["resim", f"{MISSING}.simlog"]),
    ("simrun", ["test", f"{MISSING}.toml"]),
]


def _ids(cases):
    return [" ".join([p, a[0]]) for p, a in cases]


@pytest.mark.parametrize(("program", "args"), MISSING_INPUT, ids=_ids(MISSING_INPUT))
def test_a_missing_input_is_exit_1_one_line_and_json_with_json(program, args, tmp_path):
    args = [a.replace("{tmp}", str(tmp_path)) for a in args]
    result = _invoke(program, args)
    assert result.exit_code == 1, (result.exit_code, result.output)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and "missing" in lines[0], result.stderr
    assert "Traceback" not in result.output
    result = _invoke(program, [*args, "--json"])
    assert result.exit_code == 1
    document = json.loads(result.stdout)
    assert document["status"] == "error"
    assert "missing" in json.dumps(document["error"])


BAD_VALUE = [
    ("obj2bin", [str(HEAD), "--scale", "x"]),
    ("meshtool", ["validate", str(HEAD.parent), "--jobs", "0"]),
    ("simrun", ["play", str(SCENE), "--duration", "nan"]),
    ("simrun", ["check", str(SCENE), "--duration", "-1"]),
    ("simrun", ["snapshot", str(SCENE), "-o", "x.png", "--size", "10x10"]),
]


@pytest.mark.parametrize(("program", "args"), BAD_VALUE, ids=_ids(BAD_VALUE))
def test_a_bad_option_value_is_exit_2_and_json_with_json(program, args):
    result = _invoke(program, args)
    assert result.exit_code == 2, result.output
    result = _invoke(program, [*args, "--json"])
    assert result.exit_code == 2
    document = json.loads(result.stdout)
    assert document["status"] == "error" and document["exit_code"] == 2


def test_json_success_of_a_text_command_wraps_its_lines(tmp_path):
    packed = ROOT / "fixtures" / "scenes" / "head.mbin"
    result = _invoke("meshtool", ["export", str(packed), "--glb", str(tmp_path / "h.glb"), "--json"])
    assert result.exit_code == 0, result.output
    document = json.loads(result.stdout)
    assert document["status"] == "ok" and document["command"] == "export"
    assert document["output"][0].startswith(f"wrote {tmp_path / 'h.glb'}")


def test_json_of_commands_with_their_own_report():
    result = _invoke("simrun", ["check", str(SCENE), "--json", "--duration", "0.1"])
    document = json.loads(result.stdout)
    assert result.exit_code == 0 and document["status"] == "ok" and document["bodies"] > 0
    result = _invoke("meshtool", ["validate", str(ROOT / "fixtures" / "validate" / "clean"), "--json", "--no-cache"])
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout)["format"] == "meshtool-validate-report"  # --json is --format json


def test_quiet_prints_nothing_on_stdout_and_keeps_errors(tmp_path):
    result = _invoke("simrun", ["check", str(SCENE), "-q", "--duration", "0.1"])
    assert result.exit_code == 0 and result.stdout == ""
    result = _invoke("simrun", ["check", f"{MISSING}.toml", "-q"])
    assert result.exit_code == 1 and result.stdout == "" and result.stderr.startswith("error: ")


def test_deprecated_spellings_still_work_hidden(tmp_path):
    result = _invoke("simrun", ["check", str(SCENE), "--seconds", "0.3"])
    assert result.exit_code == 0 and "stepped 0.3 s" in result.stdout
    help_text = _invoke("simrun", ["check", "--help"]).stdout
    assert "--duration" in help_text and "--seconds" not in help_text
    help_text = _invoke("simrun", ["snapshot", "--help"]).stdout
    assert "--duration" in help_text and "--at " not in help_text


def test_one_default_image_size():
    for name in ("play", "replay", "snapshot"):
        command = simrun_main.get_command(click.Context(simrun_main), name)
        size = next(p for p in command.params if p.name == "size")
        assert size.default == "640x480", name
    assert "default **640x480**" in DOC


def test_exit_code_table_is_documented():
    for what, code in EXIT_CODES.items():
        assert f"| {code} | {what} |" in DOC


def test_the_documented_exit_code_table_is_the_one_table():
    """docs/cli.md's exit-code table has exactly the rows of ``EXIT_CODES``, in its order."""
    section = DOC.split("## Exit codes", 1)[1].split("\n## ", 1)[0]
    rows = [line for line in section.splitlines() if line.startswith("| ") and not line.startswith("| exit")]
    assert rows == [f"| {code} | {what} |" for what, code in EXIT_CODES.items()]


@pytest.mark.parametrize("program", ["meshtool", "obj2bin", "simrun"])
def test_shell_completion_script_is_generated(program):
    variable = f"_{program.upper()}_COMPLETE"
    assert f"{variable}=bash_source {program}" in DOC
    env = dict(os.environ, **{variable: "bash_source"})
    result = subprocess.run(
        [str(Path(sys.executable).parent / program)], env=env, capture_output=True, text=True, timeout=120
    )
    assert result.returncode == 0 and "complete " in result.stdout and program in result.stdout


def _run_with_terminal_stderr(args: list[str]) -> tuple[int, bytes, bytes]:
    """Run with stderr on a pseudo-terminal (stdout a pipe), as a user at a terminal piping the output."""
    master, slave = pty.openpty()
    proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=slave, stdin=subprocess.DEVNULL)
    os.close(slave)
    err = b""
    while True:
        try:
            chunk = os.read(master, 4096)
        except OSError:
            break
        if not chunk:
            break
        err += chunk
    out = proc.stdout.read() if proc.stdout else b""
    proc.wait(timeout=300)
    os.close(master)
    return proc.returncode, out, err


def test_progress_goes_to_a_terminal_stderr_only(tmp_path):
    exe = str(Path(sys.executable).parent / "obj2bin")
    args = [exe, str(HEAD), "--units", "cm", "-o", str(tmp_path / "h.mbin")]
    code, out, err = _run_with_terminal_stderr(args)
    assert code == 0
    assert b"collision hulls" in err and b"packing" in err  # the stages of one file
    assert b"\x1b" not in out and out.startswith(b"wrote ")  # stdout stays the result
    plain = subprocess.run([*args, "--force"], capture_output=True, timeout=300)
    assert plain.returncode == 0
    assert b"collision hulls" not in plain.stderr and b"\x1b" not in plain.stderr  # not a terminal: silent
    code, out, err = _run_with_terminal_stderr([*args, "--force", "-q"])
    assert code == 0 and out == b"" and b"packing" not in err


def test_json_envelope_of_a_failed_report_written_to_a_file_names_the_verdict(tmp_path):
    report = tmp_path / "report.json"
    folder = ROOT / "fixtures" / "validate" / "S001_obj_unreadable"
    result = _invoke("meshtool", ["validate", str(folder), "--format", "json", "-o", str(report), "--no-cache"])
    assert result.exit_code == 1, result.output
    document = json.loads(result.stdout)
    assert document["status"] == "error" and document["exit_code"] == 1
    assert document["error"]["message"].startswith("FAILED: 1 assets, 0 clean; 1 errors"), document
    assert json.loads(report.read_text())["summary"]["errors"] == 1
