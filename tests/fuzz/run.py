"""The fuzz harness: ``make fuzz`` (or ``python tests/fuzz/run.py``), not part of ``make test``.

Runs every target of :mod:`targets` (or those named) for its share of ``FUZZ_SECONDS`` (default 600 in all),
or for ``FUZZ_SECONDS_PER_TARGET`` each, each in a child process driven by hypothesis. A crash is any exception
other than the target's documented error base class (``RecursionError``, ``MemoryError``, ``KeyError``... all
count), or a hang: an input still running after ``FUZZ_INPUT_TIMEOUT`` seconds (default 10; interrupted by
SIGALRM in the child, and the child is killed by this parent if native code does not return). The child's
address space is capped at ``FUZZ_MEMORY_MB`` (default 4096; 0: no cap), so an allocation blow-up is a
``MemoryError`` crash rather than a machine out of memory.

New crashes are shrunk by hypothesis (fewest mutations), written to ``OUT/crashes/<target>-<id>/`` (the input
files and ``traceback.txt``; ``OUT`` is ``out/fuzz`` by default) and counted; a crash with the same exception
type and place is recorded once. A summary (inputs tried, refusals, crashes per target) goes to
``OUT/summary.json`` and stdout: per target the inputs run, clean refusals, inputs accepted, crashing inputs,
and each distinct crash with the inputs that hit it and where it was raised. Exit status 1 when anything
crashed or hung.

``--seed S`` (``FUZZ_SEED``) makes a run repeatable: hypothesis round ``k`` of a child is seeded ``S + k``
instead of at random; ``--max-inputs N`` (``FUZZ_MAX_INPUTS``) stops each target after N inputs (a quick
check: ``tests/test_fuzz_mjcf.py``).

Usage::

    python tests/fuzz/run.py [--seconds 600 | --seconds-per-target 600] [--targets stl,ply] [--out out/fuzz]
        [--seed S] [--max-inputs N]

    make fuzz FUZZ_TARGETS=mjcf FUZZ_SECONDS=300     # one target (FUZZ_TARGETS: comma-separated)
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import pickle
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import traceback
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))


class Hang(BaseException):
    """Raised by SIGALRM when one input runs past the per-input timeout."""


def signature(exc: BaseException) -> str:
    """Exception type and the innermost frame in the project (what makes two crashes the same)."""
    frames = traceback.extract_tb(exc.__traceback__)
    ours = [f for f in frames if "/meshtool/" in f.filename or "/simrun/" in f.filename] or frames
    where = f"{Path(ours[-1].filename).name}:{ours[-1].name}" if ours else "?"
    return f"{type(exc).__name__} at {where}"


def raised_at(exc: BaseException) -> str:
    """The innermost frame of a traceback, anywhere (``file:line function``): where a library raised it."""
    frames = traceback.extract_tb(exc.__traceback__)
    return f"{Path(frames[-1].filename).name}:{frames[-1].lineno} {frames[-1].name}" if frames else "?"


def limit_memory(megabytes: int) -> None:
    """Cap this process's address space (``RLIMIT_AS``) at ``megabytes`` MiB (0: leave it)."""
    if megabytes > 0:
        cap = megabytes * 1024 * 1024
        _soft, hard = resource.getrlimit(resource.RLIMIT_AS)
        resource.setrlimit(resource.RLIMIT_AS, (cap if hard == resource.RLIM_INFINITY else min(cap, hard), hard))


def save_crash(out: Path, target: str, sig: str, files: dict[str, bytes], text: str) -> Path:
    """Write a crash's input files and traceback under ``out/crashes``."""
    key = hashlib.sha256(sig.encode()).hexdigest()[:10]
    folder = out / "crashes" / f"{target}-{key}"
    if folder.exists():
        shutil.rmtree(folder)
    (folder / "input").mkdir(parents=True)
    for name, data in files.items():
        path = folder / "input" / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)
    (folder / "traceback.txt").write_text(f"{sig}\n\n{text}")
    (folder / "input.pickle").write_bytes(pickle.dumps(files))
    return folder


# -- child: one target under hypothesis ------------------------------------------------------------------


def child(
    target_name: str,
    seconds: float,
    out: Path,
    input_timeout: float,
    memory_mb: int = 0,
    fixed_seed: int | None = None,
    max_inputs: int = 0,
) -> None:
    """Fuzz one target until the deadline (or ``max_inputs`` inputs, 0: no limit); progress in
    ``out/state-<target>.json``; ``fixed_seed``: hypothesis round ``k`` seeded ``fixed_seed + k``."""
    from hypothesis import HealthCheck, Phase, given, settings
    from hypothesis import seed as hseed
    from hypothesis import strategies as st
    from targets import targets

    target = targets()[target_name]
    state_file = out / f"state-{target_name}.json"
    state = json.loads(state_file.read_text()) if state_file.is_file() else {}
    stats: dict[str, Any] = {
        "tried": 0, "refused": 0, "crashed": 0, "crashes": {}, "hangs": {}, "seeds": 0, "crash_inputs": {},
        "raised_at": {}, **state,
    }  # fmt: skip
    known: set[str] = set(stats["crashes"]) | set(stats["hangs"])
    scratch = Path(tempfile.mkdtemp(prefix=f"fuzz-{target_name}-"))
    seeds = target.seeds(scratch)
    stats["seeds"] = len(seeds)
    if not seeds:
        raise SystemExit(f"{target_name}: no seeds")
    strategy = target.strategy(seeds)
    allowed = target.allowed()
    limit_memory(memory_mb)  # after the seeds (the simlog seeds are recorded by a simrun child process)
    inflight = out / f"inflight-{target_name}.pickle"
    deadline = time.monotonic() + seconds
    failures: dict[str, tuple[dict[str, bytes], str]] = {}
    counter = [0]

    def on_alarm(_signum: int, _frame: Any) -> None:
        raise Hang(f"input still running after {input_timeout:g} s")

    signal.signal(signal.SIGALRM, on_alarm)

    def flush() -> None:
        state_file.write_text(json.dumps(stats, indent=1, sort_keys=True))

    @settings(
        max_examples=200,
        deadline=None,
        database=None,
        phases=[Phase.generate, Phase.shrink],
        suppress_health_check=list(HealthCheck),
        print_blob=False,
    )
    @given(st.data())
    def fuzz_one(data: Any) -> None:
        inflight.write_bytes(pickle.dumps(None))  # drawing: a watchdog kill now is the generator's, no input's
        files = data.draw(strategy)  # always drawn: hypothesis needs the same draws when it replays
        if time.monotonic() > deadline or done():
            return
        counter[0] += 1
        folder = scratch / f"in{counter[0]}"
        folder.mkdir()
        inflight.write_bytes(pickle.dumps(files))
        stats["tried"] += 1
        signal.setitimer(signal.ITIMER_REAL, input_timeout)
        try:
            target.run(files, folder)
        except allowed:
            stats["refused"] += 1
        except Hang as exc:  # recorded as found, not shrunk (each shrink step would cost the timeout)
            sig = "hang"
            stats["crashed"] += 1
            stats["crash_inputs"][sig] = stats["crash_inputs"].get(sig, 0) + 1
            if sig not in known:
                known.add(sig)
                saved = save_crash(out, target_name, sig, files, f"{exc}\n")
                stats["hangs"][sig] = str(saved)
                print(f"[{target_name}] HANG -> {saved}", flush=True)
        except Exception as exc:
            sig = signature(exc)
            stats["crashed"] += 1
            stats["crash_inputs"][sig] = stats["crash_inputs"].get(sig, 0) + 1
            stats["raised_at"].setdefault(sig, raised_at(exc))
            if sig in known:
                return
            failures[sig] = (files, "".join(traceback.format_exception(exc)))
            raise
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)
            shutil.rmtree(folder, ignore_errors=True)

    def done() -> bool:
        return bool(max_inputs) and stats["tried"] >= max_inputs

    rounds = 0
    while time.monotonic() < deadline and not done():
        failures.clear()
        round_seed = int.from_bytes(os.urandom(4), "little") if fixed_seed is None else fixed_seed + rounds
        rounds += 1
        try:
            hseed(round_seed)(fuzz_one)()
        except Exception as exc:
            if not failures:  # the harness itself failed (hypothesis said why): record it once
                failures[signature(exc)] = ({}, "".join(traceback.format_exception(exc)))
        for sig, (files, text) in failures.items():  # the last input seen per crash is the shrunk one
            known.add(sig)
            saved = save_crash(out, target_name, sig, files, text)
            stats["crashes"][sig] = str(saved)
            print(f"[{target_name}] CRASH {sig} -> {saved}", flush=True)
        flush()
    flush()
    shutil.rmtree(scratch, ignore_errors=True)


# -- parent: time budget, watchdog, summary ----------------------------------------------------------------


def fuzz_target(
    name: str, seconds: float, out: Path, input_timeout: float, memory_mb: int = 0, extra: tuple[str, ...] = ()
) -> dict[str, Any]:
    """Run one target's child processes until its time is used (restarting after a native hang or crash);
    ``extra``: more child arguments (``--seed``, ``--max-inputs``)."""
    state_file = out / f"state-{name}.json"
    state_file.unlink(missing_ok=True)
    inflight = out / f"inflight-{name}.pickle"
    end = time.monotonic() + seconds
    native_hangs: list[str] = []
    while time.monotonic() < end - 1:
        remaining = end - time.monotonic()
        inflight.unlink(missing_ok=True)
        command = [sys.executable, __file__, "--child", name, "--seconds", f"{remaining:.1f}", "--out", str(out)]
        command += ["--input-timeout", str(input_timeout), "--memory-mb", str(memory_mb), *extra]
        proc = subprocess.Popen(command, start_new_session=True, stdin=subprocess.DEVNULL)
        while proc.poll() is None:
            time.sleep(1)
            stale = inflight.is_file() and time.time() - inflight.stat().st_mtime > 3 * input_timeout + 30
            if stale or time.monotonic() > end + 120:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
                if stale:
                    files = pickle.loads(inflight.read_bytes())
                    what = "native-hang" if files is not None else "generator-hang"  # None: while drawing an input
                    text = "killed by the watchdog" + ("" if files is not None else " while drawing an input")
                    saved = save_crash(out, name, f"{what}-{len(native_hangs)}", files or {}, text + "\n")
                    native_hangs.append(str(saved))
                    print(f"[{name}] {what.upper().replace('-', ' ')} -> {saved}", flush=True)
                break
        if proc.returncode == 0:  # its time used or its inputs run
            break
        if proc.returncode not in (-signal.SIGKILL, None):
            print(f"[{name}] child exited with {proc.returncode}", flush=True)
            if proc.returncode < 0:  # a native crash (segfault): the in-flight input is the culprit
                files = pickle.loads(inflight.read_bytes()) if inflight.is_file() else {}
                sig = f"signal-{-proc.returncode}-{len(native_hangs)}"
                saved = save_crash(out, name, sig, files or {}, "child died of a signal\n")
                native_hangs.append(str(saved))
            else:
                break
    stats: dict[str, Any] = json.loads(state_file.read_text()) if state_file.is_file() else {}
    stats.setdefault("hangs", {}).update({f"native-{k}": v for k, v in enumerate(native_hangs)})
    return stats


def main() -> int:
    """Parse arguments and fuzz (or be one target's child)."""
    from targets import targets

    known = list(targets())
    env = os.environ.get
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=float(env("FUZZ_SECONDS", 600)), help="in all, split evenly")
    parser.add_argument(
        "--seconds-per-target",
        type=float,
        default=float(env("FUZZ_SECONDS_PER_TARGET") or 0) or None,
        help="for each target (instead of --seconds in all)",
    )
    parser.add_argument(
        "--targets", "--target", default=env("FUZZ_TARGETS") or ",".join(known), help=f"of {','.join(known)}"
    )
    parser.add_argument("--out", type=Path, default=Path(env("FUZZ_OUT", "out/fuzz")))
    parser.add_argument("--input-timeout", type=float, default=float(env("FUZZ_INPUT_TIMEOUT", 10)))
    parser.add_argument("--memory-mb", type=int, default=int(env("FUZZ_MEMORY_MB", 4096)), help="0: no cap")
    parser.add_argument("--seed", type=int, default=int(env("FUZZ_SEED")) if env("FUZZ_SEED") else None)
    parser.add_argument("--max-inputs", type=int, default=int(env("FUZZ_MAX_INPUTS") or 0), help="per target")
    parser.add_argument("--child", default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    if args.child:
        child(args.child, args.seconds, args.out, args.input_timeout, args.memory_mb, args.seed, args.max_inputs)
        return 0
    names = [n.strip() for n in args.targets.split(",") if n.strip()]
    unknown = [n for n in names if n not in known]
    if unknown or not names:
        parser.error(f"unknown target(s) {', '.join(unknown) or '(none)'}; known: {', '.join(known)}")
    share = args.seconds_per_target or args.seconds / len(names)
    summary: dict[str, Any] = {
        "seconds": share * len(names),
        "seconds_per_target": share,
        "input_timeout": args.input_timeout,
        "memory_mb": args.memory_mb,
        "targets": {},
    }
    extra = ("--seed", str(args.seed)) if args.seed is not None else ()
    extra += ("--max-inputs", str(args.max_inputs)) if args.max_inputs else ()
    summary |= {"seed": args.seed, "max_inputs": args.max_inputs}
    started = time.monotonic()
    for name in names:
        print(f"fuzzing {name} for {share:.0f} s", flush=True)
        summary["targets"][name] = fuzz_target(name, share, args.out, args.input_timeout, args.memory_mb, extra)
    summary["wall_seconds"] = round(time.monotonic() - started, 1)
    for s in summary["targets"].values():
        s["accepted"] = s.get("tried", 0) - s.get("refused", 0) - s.get("crashed", 0)
    (args.out / "summary.json").write_text(json.dumps(summary, indent=1, sort_keys=True))
    return report(summary)


def report(summary: dict[str, Any]) -> int:
    """Print the per-target counts and every distinct crash; 1 when anything crashed or hung."""
    bad = 0
    head = ("target", "seeds", "tried", "refused", "accepted", "crashed", "distinct", "hangs")
    print(f"{head[0]:<9}" + "".join(f"{h:>9}" for h in head[1:]))
    for name, s in summary["targets"].items():
        crashes, hangs = len(s.get("crashes", {})), len(s.get("hangs", {}))
        bad += crashes + hangs
        row = (s.get("seeds", 0), s.get("tried", 0), s.get("refused", 0), s.get("accepted", 0), s.get("crashed", 0))
        print(f"{name:<9}" + "".join(f"{v:>9}" for v in (*row, crashes, hangs)))
    for name, s in summary["targets"].items():
        for sig, where in {**s.get("crashes", {}), **s.get("hangs", {})}.items():
            inputs = s.get("crash_inputs", {}).get(sig, 1)
            raised = s.get("raised_at", {}).get(sig)
            print(f"  {name}: {sig} ({inputs} input(s){', raised in ' + raised if raised else ''}) -> {where}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
