"""simrun serve --force: the output policy holds in the simulation thread, where recordings are written.

The recording, its MCAP and every later take (``POST /api/recording/start``) are opened by the loop thread;
files there that simrun did not write are refused without ``--force`` and replaced with it.
"""

from __future__ import annotations

import os
import subprocess

from serve_helpers import SCENES, SIMRUN, serve

BOEBOT = SCENES / "boebot.toml"
SIMLOG_MAGIC, MCAP_MAGIC = b"\x89SIMLOG\n", b"\x89MCAP0\r\n"


def _foreign(path, text: str = "not simrun's\n") -> None:
    path.write_text(text)


def test_force_reaches_the_recordings_the_loop_thread_writes(tmp_path):
    record, mcap, take = tmp_path / "run.simlog", tmp_path / "run.mcap", tmp_path / "run-2.simlog"
    for path in (record, mcap, take):
        _foreign(path)
    args = ["serve", str(BOEBOT), "--port", "0", "--record", str(record), "--record-as", "mcap"]
    refused = subprocess.run([SIMRUN, *args], capture_output=True, text=True, timeout=120, check=False,
                             env=dict(os.environ, MUJOCO_GL="egl"))  # fmt: skip
    assert refused.returncode == 1
    assert refused.stderr.count("\n") == 1 and "pass --force" in refused.stderr, refused.stderr
    assert record.read_text() == "not simrun's\n"

    with serve(BOEBOT, "--record", str(record), "--record-as", "mcap", "--force") as server:
        assert server.post("/api/recording/stop")["written"] == [str(record), str(mcap)]
        started = server.post("/api/recording/start")  # the second take replaces run-2.simlog too
        assert started["path"] == str(take) and started["active"]
    assert record.read_bytes().startswith(SIMLOG_MAGIC)
    assert mcap.read_bytes().startswith(MCAP_MAGIC)
    assert take.read_bytes().startswith(SIMLOG_MAGIC)


def test_without_force_a_later_take_over_a_foreign_file_is_refused_and_kept(tmp_path):
    record, take = tmp_path / "run.simlog", tmp_path / "run-2.simlog"
    _foreign(take)
    with serve(BOEBOT, "--record", str(record)) as server:
        server.post("/api/recording/stop")
        status, answer = server.request("POST", "/api/recording/start", {})
        assert status == 422 and "pass --force" in answer["error"], answer
    assert take.read_text() == "not simrun's\n"
