"""Benchmark: ``simrun test`` on the Boe-Bot square over many seeds: in this process, 2 workers, a Dask cluster.

Runs fixtures/scenes/boebot_square.toml (40 s simulated per run, 8 expectations, pose jitter per seed)
once per configuration and reports runs per second, the scaling efficiency of 2 workers over 1
(rate(2) / (2 x rate(1))), and the peak memory (RSS) of a worker: the process itself for -j 1, the
largest worker process for -j 2 (``RUSAGE_CHILDREN``), every Dask worker (asked through the client). The
report of each configuration must be byte-identical (JSON), or the benchmark stops.

Usage: python bench/scenetest.py [--seeds 200] [--out docs/benchmarks.md]
"""

from __future__ import annotations

import argparse
import logging
import os
import platform
import resource
import time
from pathlib import Path
from typing import Any

os.environ.setdefault("MUJOCO_GL", "egl")

from _report import write_section

from simrun.scenetest import TestOptions, run_tests
from simrun.scenetest.reports import render

BEGIN, END = "<!-- scenetest:begin -->", "<!-- scenetest:end -->"
SCENE = Path(__file__).resolve().parent.parent / "fixtures" / "scenes" / "boebot_square.toml"


def _worker_stats() -> tuple[float, float]:
    """This process's resident memory now (MiB) and CPU seconds so far (a Dask worker runs it)."""
    import psutil

    process = psutil.Process()
    cpu = process.cpu_times()
    return float(process.memory_info().rss) / 2**20, float(cpu.user + cpu.system)


def _cpu(who: int) -> float:
    usage = resource.getrusage(who)
    return usage.ru_utime + usage.ru_stime


def run(label: str, options: TestOptions, cluster: Any = None) -> dict[str, Any]:
    load = os.getloadavg()[0]
    cpu_self, cpu_children = _cpu(resource.RUSAGE_SELF), _cpu(resource.RUSAGE_CHILDREN)
    started = time.perf_counter()
    report = run_tests([SCENE], options)
    seconds = time.perf_counter() - started
    assert not report.failed(), f"{label}: runs failed"
    cpu = _cpu(resource.RUSAGE_SELF) - cpu_self + _cpu(resource.RUSAGE_CHILDREN) - cpu_children
    memory: list[float] = []
    if cluster is not None:
        from distributed import Client

        with Client(cluster) as client:
            stats = sorted(client.run(_worker_stats).values())
        memory = [m for m, _ in stats]
        cpu += sum(c for _, c in stats)
    elif options.jobs > 1:
        memory = [resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024]
    else:
        memory = [resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024]
    return {
        "label": label,
        "runs": len(report.runs),
        "seconds": seconds,
        "json": render(report, "json"),
        "memory": memory,
        "rate": len(report.runs) / seconds,
        "cpu": cpu / len(report.runs),
        "load": (load, os.getloadavg()[0]),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seeds", type=int, default=200)
    parser.add_argument("--out", type=Path, default=Path("docs/benchmarks.md"))
    parser.add_argument("--json", type=Path, default=None, help="also write the (common) JSON report here")
    args = parser.parse_args()
    seeds = list(range(args.seeds))
    rows = [run("in this process (-j 1)", TestOptions(seeds=seeds, jobs=1))]
    rows.append(run("2 worker processes (-j 2)", TestOptions(seeds=seeds, jobs=2)))
    from distributed import LocalCluster

    with LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None, silence_logs=logging.ERROR
    ) as cluster:
        options = TestOptions(seeds=seeds, executor="dask", scheduler=cluster.scheduler_address, jobs=2)
        rows.append(run("Dask LocalCluster, 2 workers", options, cluster))
    assert len({r["json"] for r in rows}) == 1, "reports differ between executors"
    if args.json is not None:
        args.json.write_text(rows[0]["json"], encoding="utf-8")
    base = rows[0]["rate"]
    lines = [
        BEGIN,
        "## Scene tests: `simrun test` on the Boe-Bot square",
        "",
        f"`python bench/scenetest.py --seeds {args.seeds}`: fixtures/scenes/boebot_square.toml (40 s simulated, "
        f"8 expectations, start jitter per seed) over {args.seeds} seeds, each configuration once, timed from "
        "the scene check to the last result (workers' start-up included). JSON reports byte-identical across "
        "the three. Scaling efficiency: runs/s over (workers x runs/s of -j 1). CPU s per run: user + system "
        "time of every process involved (this one, the workers, the Dask workers) over the runs: what a run "
        "costs whatever else the machine does. Memory: peak RSS of the one process (-j 1), of the largest "
        "worker process (-j 2), and RSS of each Dask worker after the runs. Load: the 1-minute load average "
        "before and after (the machine's other jobs compete for the same CPUs).",
        "",
        "| configuration | runs | wall s | runs/s | scaling efficiency | CPU s per run | memory per worker (MiB) "
        "| load before, after |",
        "|---|---:|---:|---:|---:|---:|---|---|",
    ]
    for k, r in enumerate(rows):
        efficiency = "1.00 (base)" if k == 0 else f"{r['rate'] / (2 * base):.2f}"
        memory = ", ".join(f"{m:.0f}" for m in r["memory"])
        lines.append(
            f"| {r['label']} | {r['runs']} | {r['seconds']:.1f} | {r['rate']:.2f} | {efficiency} | {r['cpu']:.2f} "
            f"| {memory} | {r['load'][0]:.1f}, {r['load'][1]:.1f} |"
        )
    lines += [
        "",
        f"Machine: {platform.machine()}, {os.cpu_count()} CPUs (shared with other jobs while measured), Python "
        f"{platform.python_version()}.",
        END,
    ]
    write_section(args.out, "\n".join(lines), BEGIN, END)
    print("\n".join(lines))


if __name__ == "__main__":
    main()
