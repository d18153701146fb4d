"""Benchmark: ``simrun test`` on the Boe-Bot square over many seeds: in one process, 2 workers, a Dask cluster.

Runs fixtures/scenes/boebot_square.toml (40 s simulated per run, 8 expectations, pose jitter per seed)
with each configuration and reports runs per second, the scaling efficiency of 2 workers over 1
(rate(2) / (2 x rate(1))), the CPU seconds a run costs, and the memory (RSS) of a worker.

The machine this runs on may be shared, so the seeds are split into rounds and every round runs the three
configurations one after the other in a rotating order, each in a fresh ``python`` process (timed from the
scene check to the last result: the worker pool's start-up is in every round, the Dask cluster is started
once and kept). Every round's JSON report must be byte-identical across the configurations, or the
benchmark stops. Memory: the peak RSS of the process (-j 1), of the largest worker process (-j 2), and the
RSS of each Dask worker after the last round.

The anchor (issue 41) is a plain ``mj_step`` loop over the same simulated seconds of the same model, run in
the same rotation; the CPU ratio of each configuration to it is reported with the goal (1.5x) met or short
by a factor, and a cProfile of a few -j 1 runs says where the rest goes.

Usage: python bench/scenetest.py [--seeds 200] [--rounds 4] [--profile 4] [--out docs/benchmarks.md] [--json FILE]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import logging
import os
import platform
import resource
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

os.environ.setdefault("MUJOCO_GL", "egl")

from _report import write_section

BEGIN, END = "<!-- scenetest:begin -->", "<!-- scenetest:end -->"
SCENE = Path(__file__).resolve().parent.parent / "fixtures" / "scenes" / "boebot_square.toml"
CONFIGS = {
    "j1": "in one process (-j 1)",
    "j2": "2 worker processes (-j 2)",
    "dask": "Dask LocalCluster, 2 workers",
    "mjstep": "anchor: a plain `mj_step` loop",
}
#: Goal of issue 41: ``simrun test`` CPU per run within this factor of the plain ``mj_step`` loop's.
GOAL = 1.5


def _cpu(who: int) -> float:
    usage = resource.getrusage(who)
    return usage.ru_utime + usage.ru_stime


def anchor(first: int, last: int) -> None:
    """The anchor over seeds first..last-1: what a user would write instead of ``simrun test``.

    The scene's model (compiled once, by simrun, as the test compiles it) stepped by a plain Python loop of
    ``mujoco.mj_step`` for the same simulated seconds per seed, from a fresh ``MjData``; no controls, no
    checks. Prints one JSON line like :func:`child` (no report: ``sha`` is ``None``).
    """
    import mujoco

    from simrun.scene.scene_file import load_scene
    from simrun.scenetest.spec import load_case

    cpu = _cpu(resource.RUSAGE_SELF) + _cpu(resource.RUSAGE_CHILDREN)  # after the imports
    started = time.perf_counter()
    duration = load_case(SCENE).duration
    model = load_scene(SCENE).model
    steps = round(duration / model.opt.timestep)
    step = mujoco.mj_step
    for _ in range(first, last):
        data = mujoco.MjData(model)
        for _ in range(steps):
            step(model, data)
    result: dict[str, Any] = {
        "seconds": time.perf_counter() - started,
        "runs": last - first,
        "cpu": _cpu(resource.RUSAGE_SELF) + _cpu(resource.RUSAGE_CHILDREN) - cpu,
        "memory": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        "sha": None,
        "report": [],
    }
    print(json.dumps(result))


def profile(seeds: int, top: int) -> list[str]:
    """The ``top`` entries (by own CPU time) of cProfile over ``seeds`` runs at -j 1 in this process, as lines."""
    import cProfile
    import io
    import pstats

    from simrun.scenetest import TestOptions, run_tests

    run_tests([SCENE], TestOptions(seeds=[0]))  # imports and first-use costs are not the runs'
    profiler = cProfile.Profile(time.process_time)
    profiler.enable()
    run_tests([SCENE], TestOptions(seeds=list(range(seeds))))
    profiler.disable()
    stats = pstats.Stats(profiler, stream=io.StringIO())
    total = stats.total_tt  # type: ignore[attr-defined]
    import simrun

    roots = sorted(
        {str(Path(simrun.__file__).resolve().parent.parent) + "/", *(p + "/" for p in sys.path if p)}, key=len
    )
    rows = []
    for (file, line, name), (_, calls, own, cumulative, _) in sorted(
        stats.stats.items(),  # type: ignore[attr-defined]
        key=lambda item: -item[1][2],
    )[:top]:
        short = next((file[len(r) :] for r in reversed(roots) if file.startswith(r)), file)
        where = f"{short}:{line}({name})" if file != "~" else name
        rows.append(f"| `{where}` | {calls} | {own:.3f} | {100 * own / total:.1f} % | {cumulative:.3f} |")
    return [
        f"cProfile of {seeds} runs at -j 1 in one process (CPU clock; {total:.2f} s in all), top {top} by own time:",
        "",
        "| function | calls | own s | own share | cumulative s |",
        "|---|---:|---:|---:|---:|",
        *rows,
    ]


def _bytecode() -> str:
    """Whether the project's modules ran from ``.pyc`` files (as installed users have them)."""
    import importlib.util

    import simrun.scenetest.expect
    import simrun.world.world

    present = all(
        Path(importlib.util.cache_from_source(m.__file__ or "")).exists()
        for m in (simrun.scenetest.expect, simrun.world.world)
    )
    writes = "not written (PYTHONDONTWRITEBYTECODE)" if sys.dont_write_bytecode else "written when missing"
    return f"`.pyc` {'present' if present else 'missing'} for the project's modules, {writes}"


def child(config: str, first: int, last: int, scheduler: str | None) -> None:
    """One configuration over seeds first..last-1 in this process: prints one JSON line of measurements."""
    if config == "mjstep":
        anchor(first, last)
        return
    from simrun.scenetest import TestOptions, run_tests
    from simrun.scenetest.reports import render

    seeds = list(range(first, last))
    if config == "dask":
        options = TestOptions(seeds=seeds, executor="dask", scheduler=scheduler, jobs=2)
    else:
        options = TestOptions(seeds=seeds, jobs=1 if config == "j1" else 2)
    cpu = _cpu(resource.RUSAGE_SELF) + _cpu(resource.RUSAGE_CHILDREN)  # after the imports
    started = time.perf_counter()
    report = run_tests([SCENE], options)
    seconds = time.perf_counter() - started
    assert not report.failed(), f"{config}: runs failed"
    text = render(report, "json")
    peak = resource.getrusage(resource.RUSAGE_SELF if config == "j1" else resource.RUSAGE_CHILDREN).ru_maxrss
    result = {
        "seconds": seconds,
        "runs": len(report.runs),
        "cpu": _cpu(resource.RUSAGE_SELF) + _cpu(resource.RUSAGE_CHILDREN) - cpu,
        "memory": peak / 1024,
        "sha": hashlib.sha256(text.encode()).hexdigest(),
        "report": json.loads(text)["runs"],
    }
    print(json.dumps(result))


def _worker_stats() -> tuple[float, float]:
    """This process's resident memory now (MiB) and CPU seconds so far (a Dask worker runs it)."""
    import psutil

    process = psutil.Process()
    cpu = process.cpu_times()
    return float(process.memory_info().rss) / 2**20, float(cpu.user + cpu.system)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seeds", type=int, default=200)
    parser.add_argument("--rounds", type=int, default=4)
    parser.add_argument("--out", type=Path, default=Path("docs/benchmarks.md"))
    parser.add_argument("--json", type=Path, default=None, help="also write every run of the report here")
    parser.add_argument("--profile", type=int, default=4, help="seeds of the cProfile run (0: none)")
    parser.add_argument("--child", nargs=4, default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        config, first, last, scheduler = args.child
        child(config, int(first), int(last), scheduler if scheduler != "-" else None)
        return
    from distributed import Client, LocalCluster

    totals: dict[str, dict[str, Any]] = {
        c: {"seconds": 0.0, "runs": 0, "cpu": 0.0, "memory": 0.0, "load": []} for c in CONFIGS
    }
    runs: list[Any] = []
    fixed: dict[str, list[float]] = {}  # per round: CPU s of an invocation with 2 runs (-j 2, Dask)
    edges = [round(k * args.seeds / args.rounds) for k in range(args.rounds + 1)]
    with (
        LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None, silence_logs=logging.ERROR
        ) as cluster,
        Client(cluster) as client,
    ):
        for r in range(args.rounds):
            order = list(CONFIGS)[r % len(CONFIGS) :] + list(CONFIGS)[: r % len(CONFIGS)]
            shas = set()
            for config in order:
                before = sum(c for _, c in client.run(_worker_stats).values()) if config == "dask" else 0.0
                load = os.getloadavg()[0]
                command = [sys.executable, __file__, "--child", config, str(edges[r]), str(edges[r + 1])]
                out = subprocess.run([*command, cluster.scheduler_address], capture_output=True, text=True)
                if out.returncode != 0:
                    sys.exit(f"round {r}, {config}: the run failed:\n{out.stderr[-3000:]}")
                result = json.loads(out.stdout.strip().splitlines()[-1])
                total = totals[config]
                total["seconds"] += result["seconds"]
                total["runs"] += result["runs"]
                total["cpu"] += result["cpu"]
                total["load"].append(load)
                if config == "dask":
                    stats = list(client.run(_worker_stats).values())
                    result["cpu"] += sum(c for _, c in stats) - before
                    total["cpu"] += sum(c for _, c in stats) - before
                    total["memory"] = [m for m, _ in sorted(stats)]
                else:
                    total["memory"] = max(total["memory"], result["memory"])
                total.setdefault("rounds", []).append(result["cpu"] / result["runs"])
                if result["sha"] is not None:
                    shas.add(result["sha"])
                if config == "j1":
                    runs.extend(result["report"])
            assert len(shas) == 1, f"round {r}: reports differ between executors"
            for config in ("j2", "dask"):  # what an invocation costs beyond its runs: 2 runs, one per worker
                before = sum(c for _, c in client.run(_worker_stats).values()) if config == "dask" else 0.0
                command = [sys.executable, __file__, "--child", config, str(edges[r]), str(edges[r] + 2)]
                out = subprocess.run([*command, cluster.scheduler_address], capture_output=True, text=True)
                if out.returncode != 0:
                    sys.exit(f"round {r}, {config} with 2 runs: the run failed:\n{out.stderr[-3000:]}")
                small = json.loads(out.stdout.strip().splitlines()[-1])["cpu"]
                if config == "dask":
                    small += sum(c for _, c in client.run(_worker_stats).values()) - before
                fixed.setdefault(config, []).append(small)
    if args.json is not None:
        args.json.write_text(json.dumps({"runs": runs}, indent=1) + "\n", encoding="utf-8")
    base = totals["j1"]["runs"] / totals["j1"]["seconds"]
    lines = [
        BEGIN,
        "## Scene tests: `simrun test` on the Boe-Bot square",
        "",
        f"`python bench/scenetest.py --seeds {args.seeds} --rounds {args.rounds} --profile {args.profile}`: "
        "fixtures/scenes/boebot_square.toml "
        f"(40 s simulated, 8 expectations, start jitter per seed) over {args.seeds} seeds per configuration, in "
        f"{args.rounds} rounds that run the three configurations and the anchor in turn (rotating order, each a fresh "
        "process; the "
        "pool's start-up is paid every round, the Dask cluster is started once). Every round's JSON report was "
        "byte-identical across the three. Wall s: from the scene check to the last result, summed over the rounds. "
        "Scaling efficiency: runs/s over (2 x runs/s of -j 1). CPU s per run: user + system time of every process "
        "involved (the test process, its workers, the Dask workers), which does not depend on what else the machine "
        "runs. Memory: peak RSS of the process (-j 1), of the largest worker process (-j 2), RSS of each Dask worker "
        "after the last round. Load: the 1-minute load average before each round (other jobs share the CPUs).",
        "",
        "| configuration | runs | wall s | runs/s | scaling efficiency | CPU s per run | memory per worker (MiB) "
        "| load average |",
        "|---|---:|---:|---:|---:|---:|---|---|",
    ]
    for config, label in CONFIGS.items():
        t = totals[config]
        rate = t["runs"] / t["seconds"]
        efficiency = "1.00 (base)" if config == "j1" else "" if config == "mjstep" else f"{rate / (2 * base):.2f}"
        memory = t["memory"] if isinstance(t["memory"], list) else [t["memory"]]
        lines.append(
            f"| {label} | {t['runs']} | {t['seconds']:.1f} | {rate:.2f} | {efficiency} | {t['cpu'] / t['runs']:.3f} "
            f"| {', '.join(f'{m:.0f}' for m in memory)} | {', '.join(f'{x:.1f}' for x in t['load'])} |"
        )
    anchor_cpu = totals["mjstep"]["cpu"] / totals["mjstep"]["runs"]
    lines += [
        "",
        f"Against the anchor (issue 41: CPU per run within {GOAL:g}x of a plain `mj_step` loop over the same 40 "
        "simulated seconds of the same compiled model, from a fresh `MjData` per run, no controls and no checks; "
        "ratio of the CPU sums, and each round's ratio):",
        "",
        "| configuration | CPU s per run / anchor's | per round | goal |",
        "|---|---:|---|---|",
    ]
    for config in ("j1", "j2", "dask"):
        t = totals[config]
        ratio = t["cpu"] / t["runs"] / anchor_cpu
        rounds = ", ".join(f"{a / b:.2f}" for a, b in zip(t["rounds"], totals["mjstep"]["rounds"], strict=True))
        verdict = f"met (<= {GOAL:g}x)" if ratio <= GOAL else f"short by {ratio / GOAL:.2f}x"
        lines.append(f"| {CONFIGS[config]} | {ratio:.2f}x | {rounds} | {verdict} |")
    j1_run = totals["j1"]["cpu"] / totals["j1"]["runs"]
    per_round = totals["j1"]["runs"] / args.rounds
    lines += [
        "",
        "What an invocation costs beyond its runs: each round also runs -j 2 and Dask over 2 seeds (one run per "
        "worker); their CPU less 2 runs at -j 1's CPU per run is the invocation's fixed cost (-j 2: two worker "
        "processes started, each importing MuJoCo and simrun and loading the scene; Dask: the client's imports "
        "and connection, the tasks' transfer, the workers' own CPU meanwhile). Spread over a round's "
        f"{per_round:.0f} runs it is the first part of the ratio; the rest is the runs themselves, against "
        "-j 1's.",
        "",
        "| configuration | fixed cost per invocation s (per round) | its share of the ratio | ratio less it | "
        "-j 1's ratio |",
        "|---|---|---:|---:|---:|",
    ]
    for config in ("j2", "dask"):
        costs = [c - 2 * j1_run for c in fixed[config]]
        cost = sum(costs) / len(costs)
        share = cost / per_round / anchor_cpu
        ratio = totals[config]["cpu"] / totals[config]["runs"] / anchor_cpu
        lines.append(
            f"| {CONFIGS[config]} | {cost:.2f} ({', '.join(f'{c:.2f}' for c in costs)}) | {share:.2f}x | "
            f"{ratio - share:.2f}x | {j1_run / anchor_cpu:.2f}x |"
        )
    rest = {
        config: (
            totals[config]["cpu"] / totals[config]["runs"]
            - sum(fixed[config]) / len(fixed[config]) / per_round
            + 2 * j1_run / per_round
        )
        / j1_run
        for config in ("j2", "dask")
    }
    lines += [
        "",
        f"Less their fixed cost, a run costs {rest['j2']:.2f}x its CPU at -j 1 in a -j 2 worker and "
        f"{rest['dask']:.2f}x in a Dask worker (what the worker adds around a run is not broken down here); the "
        "fixed cost is paid per invocation, so a suite of more runs per invocation than a round here spreads it "
        "thinner.",
    ]
    if args.profile:
        lines += ["", *profile(args.profile, 12)]
    bytecode = _bytecode()
    lines += [
        "",
        f"Machine: {platform.machine()}, {os.cpu_count()} CPUs, Python {platform.python_version()}; "
        f"Python bytecode: {bytecode}.",
        END,
    ]
    write_section(args.out, "\n".join(lines), BEGIN, END)
    print("\n".join(lines))


if __name__ == "__main__":
    main()
