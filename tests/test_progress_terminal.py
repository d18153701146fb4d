"""Progress on a real terminal (issue 31, item 4): the file, the stage, the elapsed time, a spinner that moves
while CoACD runs, lines cleared before other output; nothing when not a terminal or with -q.

The commands run on a pseudo-terminal (the ``pty`` module): what a user's terminal receives, byte for byte.
"""

from __future__ import annotations

import os
import pty
import re
import select
import subprocess
import sys
import time
from pathlib import Path

import pytest

from meshtool.work.progress import CLEAR, FRAMES, Display, elapsed_text

OBJ2BIN = [sys.executable, "-c", "from meshtool.cli.main import obj2bin; obj2bin()"]
# A U-shaped bracket (concave): CoACD splits it, which takes a moment.
BRACKET = """\
v 0 0 0
v 3 0 0
v 3 1 0
v 2 1 0
v 2 3 0
v 1 3 0
v 1 1 0
v 0 1 0
v 0 0 1
v 3 0 1
v 3 1 1
v 2 1 1
v 2 3 1
v 1 3 1
v 1 1 1
v 0 1 1
f 1 8 7 6 5 4 3 2
f 9 10 11 12 13 14 15 16
f 1 2 10 9
f 2 3 11 10
f 3 4 12 11
f 4 5 13 12
f 5 6 14 13
f 6 7 15 14
f 7 8 16 15
f 8 1 9 16
"""


def _on_terminal(argv: list[str], cwd: Path, columns: int = 200) -> tuple[int, bytes]:
    """Run ``argv`` with stdin, stdout and stderr on a new pseudo-terminal; its exit code and every byte shown."""
    master, slave = pty.openpty()
    env = {**os.environ, "COLUMNS": str(columns), "LINES": "40"}
    child = subprocess.Popen(argv, stdin=slave, stdout=slave, stderr=slave, cwd=cwd, env=env, close_fds=True)
    os.close(slave)
    shown = bytearray()
    while True:
        try:
            chunk = os.read(master, 65536)
        except OSError:  # EIO: the child closed the terminal
            break
        if not chunk:
            break
        shown += chunk
    os.close(master)
    return child.wait(timeout=300), bytes(shown)


@pytest.fixture
def bracket(tmp_path: Path) -> Path:
    path = tmp_path / "bracket part.obj"
    path.write_text(BRACKET)
    return path


def test_a_decomposition_shows_file_stage_elapsed_and_a_moving_spinner(bracket: Path, tmp_path: Path) -> None:
    code, shown = _on_terminal(
        [*OBJ2BIN, str(bracket), "--up", "z", "--hulls", "decompose", "--no-cache", "-o", "b.mbin"], tmp_path
    )
    text = shown.decode()
    assert code == 0, text
    drawn = [part for part in text.replace("\r\n", "\n").split(CLEAR) if part]
    lines = [p for p in drawn if p[:1] in FRAMES and p[1:2] == " "]
    assert lines, text
    stages = {re.sub(r" \d+/\d+", "", p[2:].rsplit("  ", 1)[0]) for p in lines}
    assert {"bracket part.obj: reading and normalising", "bracket part.obj: collision hulls"} <= stages
    assert "bracket part.obj: decomposing parts" in stages
    assert all(re.search(r"  \d+ s$", p) for p in lines)  # the stage's elapsed time ends every line
    assert len({p[0] for p in lines}) >= 2  # the spinner moved
    # the ticker redraws the same stage while nothing is reported: the line keeps moving during CoACD
    decomposing = [p for p in lines if "decomposing parts" in p]
    assert len(decomposing) >= 3 and len({p[0] for p in decomposing}) >= 2
    # output never runs into the progress line: it starts on a cleared line, and the line is gone at the end
    at = text.index("wrote b.mbin")
    assert text[:at].endswith(CLEAR)
    assert text.rstrip("\r\n").rsplit(CLEAR, 1)[-1].startswith("wrote b.mbin") or text.endswith(CLEAR)


@pytest.mark.parametrize("quiet", [["-q"], ["--json"]])
def test_quiet_and_json_draw_no_progress_on_a_terminal(bracket: Path, tmp_path: Path, quiet: list[str]) -> None:
    code, shown = _on_terminal([*OBJ2BIN, str(bracket), "--up", "z", "-o", "b.mbin", *quiet], tmp_path)
    assert code == 0, shown
    assert b"\x1b[K" not in shown and b"reading and normalising" not in shown


def test_nothing_drawn_into_a_pipe(bracket: Path, tmp_path: Path) -> None:
    done = subprocess.run([*OBJ2BIN, str(bracket), "--up", "z", "-o", "b.mbin"], cwd=tmp_path, capture_output=True)
    assert done.returncode == 0
    assert b"\x1b" not in done.stderr + done.stdout and b"\r" not in done.stderr + done.stdout


def test_a_narrow_terminal_gets_lines_cut_to_its_width(bracket: Path, tmp_path: Path) -> None:
    """A progress line longer than the terminal wraps, and ``\\r\\x1b[K`` then clears only its last row."""
    code, shown = _on_terminal([*OBJ2BIN, str(bracket), "--up", "z", "-o", "b.mbin"], tmp_path, columns=30)
    assert code == 0
    lines = [p for p in shown.decode().split(CLEAR) if p[:1] in FRAMES and p[1:2] == " "]
    assert lines and all(len(p) < 30 for p in lines)


def test_the_display_ticks_on_a_terminal_while_no_report_comes() -> None:
    master, slave = pty.openpty()
    with os.fdopen(slave, "w") as terminal:
        display = Display(terminal)
        assert display.enabled  # a pty is a terminal
        display("b.obj: checking in MuJoCo")
        time.sleep(0.5)  # the work (MuJoCo, CoACD) reports nothing for a while
        display.close()
        shown = b""
        while select.select([master], [], [], 0.5)[0]:  # everything the terminal got (reads may be partial)
            shown += os.read(master, 65536)
    os.close(master)
    shown = shown.decode()
    drawn = [p for p in shown.split(CLEAR) if p]
    assert len(drawn) >= 3 and all("b.obj: checking in MuJoCo  0 s" in p for p in drawn)
    assert shown.endswith(CLEAR)  # cleared at the end


def test_elapsed_text() -> None:
    assert [elapsed_text(s) for s in (0.4, 59.9, 65, 3723)] == ["0 s", "59 s", "1:05", "1:02:03"]


def test_a_folder_conversion_in_worker_processes_names_the_files_still_running(tmp_path: Path) -> None:
    """``converting [####] 90%`` stood still for minutes while CoACD ran on the last file, never naming it."""
    src = tmp_path / "src"
    src.mkdir()
    for name in ("a.obj", "b.obj"):
        (src / name).write_text(BRACKET)
    args = [*OBJ2BIN, str(src), "-o", str(tmp_path / "out"), "-j", "2", "--up", "z", "--hulls", "decompose"]
    code, shown = _on_terminal([*args, "--no-cache"], tmp_path)
    text = shown.decode()
    assert code == 0, text
    lines = [p for p in text.split(CLEAR) if p[:1] in FRAMES and p[1:2] == " "]
    assert any("converting (still running: a.obj, b.obj) 0/2" in p for p in lines), lines
    assert any(re.search(r"converting \(still running: [ab]\.obj\) 1/2", p) for p in lines), lines
    assert "2 written, 0 unchanged, 0 failed" in text
