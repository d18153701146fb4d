"""Recordings anyone can watch: the demo run as GLB, glTF, USD and HTML against the MP4 of the same run.

Usage: MUJOCO_GL=egl python bench/recordings.py [--repeat 3] [--out docs/benchmarks.md]   (no corpus needed)

Records the ``make demo`` run (fixtures/scenes/boebot.toml with square.commands.toml, 40 simulated
seconds, frames every 20 ms: 2,000 frames) once, then times each ``simrun replay`` command end to end as a
user runs it (a new process: start-up, scene load and compile, replay of every frame, export, atomic
write), best of --repeat, and reports the bytes written. The export-only column is the time spent writing
that format once the recording is replayed (``simrun.record.replay_export.Written.seconds``).
"""

from __future__ import annotations

import argparse
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import mujoco
from _report import write_section

from simrun.record.replay_export import export_recording

BEGIN, END = "<!-- recordings:begin -->", "<!-- recordings:end -->"
ROOT = Path(__file__).resolve().parent.parent
SIMRUN = [str(Path(sys.executable).parent / "simrun")]
DURATION = "40"


def _run(args: list[str]) -> float:
    start = time.perf_counter()
    done = subprocess.run([*SIMRUN, *args], capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"simrun {' '.join(args)} failed: {done.stderr.strip()}")
    return time.perf_counter() - start


def main() -> None:
    """Run the benchmark and write its section."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "benchmarks.md")
    options = parser.parse_args()
    os.environ.setdefault("MUJOCO_GL", "egl")
    scenes = ROOT / "fixtures" / "scenes"
    with tempfile.TemporaryDirectory(prefix="simrun-bench-") as tmp:
        folder = Path(tmp)
        log = folder / "demo.simlog"
        record = ["play", str(scenes / "boebot.toml"), "--duration", DURATION]
        record += ["--commands", str(scenes / "square.commands.toml"), "--record", str(log)]
        play_s = _run(record)
        cases = [
            ("GLB, every frame", ["--glb", "demo.glb"], {"glb": "demo.glb"}, None),
            ("GLB, `--fps 5` (error <= 1 mm / 1 mrad)", ["--glb", "thin.glb", "--fps", "5"], {"glb": "thin.glb"}, 5.0),
            ("glTF (one file, base64 buffer)", ["--gltf", "demo.gltf"], {"gltf": "demo.gltf"}, None),
            ("USD (`.usd`, crate)", ["--usd", "demo.usd"], {"usd": "demo.usd"}, None),
            ("USD (`.usda`, text)", ["--usd", "demo.usda"], {"usd": "demo.usda"}, None),
            ("HTML player (GLB + three.js inline)", ["--html", "demo.html"], {"html": "demo.html"}, None),
            ("MP4 320x240, 15 fps (`--video`)", ["--video", "demo.mp4", "--size", "320x240", "--fps", "15"], {}, None),
            ("MP4 640x480, 30 fps", ["--video", "big.mp4", "--size", "640x480", "--fps", "30"], {}, None),
        ]
        rows = []
        for label, args, outputs, fps in cases:
            target = folder / args[1]
            wall = min(
                _run(["replay", str(log), args[0], str(target), *args[2:], "--force"]) for _ in range(options.repeat)
            )
            export = "-"
            if outputs:
                paths = {k: folder / v for k, v in outputs.items()}
                export = f"{min(export_recording(log, paths, fps)[0].seconds for _ in range(options.repeat)):.3f}"
            rows.append(f"| {label} | {target.stat().st_size:,} | {wall:.2f} | {export} |")
            print(rows[-1], file=sys.stderr)
        simlog_bytes = log.stat().st_size
    lines = [
        BEGIN,
        "## Recordings: the demo run as GLB, glTF, USD and HTML vs MP4",
        "",
        f"`MUJOCO_GL=egl python bench/recordings.py --repeat {options.repeat}`: the `make demo` run "
        f"(boebot.toml + square.commands.toml, {DURATION} simulated seconds, 2,000 frames, 4 moving bodies; "
        f"`simrun play --record` took {play_s:.2f} s, the `.simlog` is {simlog_bytes:,} bytes), each "
        f"`simrun replay` command timed end to end in a new process, best of {options.repeat}. "
        f"Machine: {platform.machine()}, {os.cpu_count()} CPUs, CPython {platform.python_version()}, MuJoCo "
        f"{mujoco.__version__}; load average {os.getloadavg()[1]:.1f} at the end (wall times grow with it).",
        "",
        "| output | bytes | `simrun replay` wall s | export only, s |",
        "|---|---|---|---|",
        *rows,
        "",
        "The animated files are viewpoint-free (orbit, zoom, any time) and exact to float32 at every kept "
        "frame; the MP4 is one camera at one size. The HTML page carries the three.js bundle (~0.8 MB) once, "
        "so it costs the GLB plus a constant. The wall time is mostly what every output shares: start-up, "
        "scene compile and the kinematic replay of the 2,000 frames; the MP4 adds rendering every frame (EGL).",
        END,
    ]
    write_section(options.out, "\n".join(lines), BEGIN, END)


if __name__ == "__main__":
    main()
