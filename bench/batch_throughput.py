"""Benchmark (issue 38): assets/s of ``obj2bin DIR`` and ``meshtool validate DIR`` on one batch layer.

Both commands run as the installed console scripts of this checkout's ``.venv/bin`` (a fresh process per run,
start-up included) over folders of 1, 100 and 1,000 assets with three executors: ``-j 1``, ``-j 2`` and
``--executor dask --scheduler ADDRESS`` on a ``dask.distributed`` LocalCluster of 2 single-threaded worker
processes that this script starts once, before the first run, and warms with one untimed run of each command.

Assets: sampled with replacement (``random.Random(--seed)``) from the OBJ assets of ``../shared/corpus`` that
MuJoCo loads raw, with no missing texture, at least 12 triangles and at most ``--max-bytes`` of files (the
manifest's ``size_bytes``; default 50 KB, the 22 cheapest, so that 1,000 assets fit in minutes); each sample is
copied with its MTL and textures into its own folder ``aNNNN/`` of a temporary folder, its OBJ ending with its
own comment line (no two copies alike). The folder of N assets is the first N samples. Without the corpus the
assets are the project's fixtures (each fixture's folder copied). Nothing is written into the checkout except,
with ``--docs``, the marked section of docs/benchmarks.md.

Measured per (command, N, executor): wall seconds; CPU seconds (user + system) of the command and the children
it reaped (``os.wait4``), and for Dask also of the cluster: the scheduler (a thread of this process,
``RUSAGE_SELF``) and the worker processes (psutil, their children included). Rounds: ``--repeat`` (sizes
below the largest) or ``--repeat-largest`` (the largest size), the executors in a rotating order each round,
medians reported. Every run's output must be the same: the packs' folder (sha256 of every relative path and
its bytes) and validate's JSON report are compared across executors and rounds; any difference fails the run.

Before measuring, ``python -m compileall -q meshtool simrun`` writes the project's ``.pyc`` files and the
children run without ``PYTHONDONTWRITEBYTECODE`` (the workplace sets it), so no run compiles the project.
``--snapshot`` measures HEAD's meshtool/ and simrun/ (``git archive`` into the temporary folder, first on the
commands', the workers' and this process's path) instead of a working tree that other work may be editing.

Usage: python bench/batch_throughput.py [CORPUS] [--sizes 1,100,1000] [--repeat 3] [--repeat-largest 1]
       [--max-bytes 50000] [--seed 38] [--snapshot] [--docs] [--out docs/benchmarks.md]
"""

from __future__ import annotations

import argparse
import contextlib
import hashlib
import importlib
import json
import logging
import os
import platform
import random
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from _report import Timing, write_section

ROOT = Path(__file__).resolve().parent.parent
BEGIN, END = "<!-- batch-throughput:begin -->", "<!-- batch-throughput:end -->"
EXECUTORS = ("-j 1", "-j 2", "dask")
COMMANDS = ("obj2bin", "validate")
#: Self-contained fixtures used when the corpus is missing (each OBJ's folder is copied whole).
FIXTURE_ASSETS = (
    "fixtures/bowl/bowl.obj",
    "fixtures/head/Head 1.obj",
    "fixtures/multi_material/crate.obj",
    "fixtures/features/features.obj",
    "fixtures/crlf_ngon/shapes.obj",
    "fixtures/realworld/meshlab_tr/fuze.obj",
)
MIN_TRIANGLES = 12
#: The default ``--max-bytes``: the 22 cheapest corpus assets (12 to 968 triangles); with 1 MB (61 assets,
#: up to 20k triangles) an asset costs several times the CPU (obj2bin about 90 ms instead of 10 ms).
SMALL_BYTES = 50_000


# ------------------------------------------------------------------------------------ the asset folders


@dataclass(frozen=True)
class Asset:
    """One source asset: its name, its files (the OBJ first), and its triangle count (0: not known)."""

    name: str
    files: tuple[Path, ...]
    triangles: int

    @property
    def size(self) -> int:
        """Bytes of all its files."""
        return sum(p.stat().st_size for p in self.files)


def corpus_pool(corpus: Path, max_bytes: int) -> list[Asset]:
    """The corpus assets the folders are sampled from, sorted by id (see the module docstring)."""
    manifest = json.loads((corpus / "manifest.json").read_text(encoding="utf-8"))
    pool = []
    for entry in manifest["assets"]:
        if (
            entry.get("derived")
            or entry.get("missing_textures")
            or not entry["baseline"]["mujoco_4.0.0_raw_load"]["ok"]
            or entry["stats"]["triangles_after_triangulation"] < MIN_TRIANGLES
            or entry["size_bytes"] > max_bytes
        ):
            continue
        files = sorted((corpus / f["corpus_path"] for f in entry["files"]), key=lambda p: p.suffix.lower() != ".obj")
        pool.append(Asset(entry["id"], tuple(files), entry["stats"]["triangles_after_triangulation"]))
    return sorted(pool, key=lambda a: a.name)


def fixture_pool() -> list[Asset]:
    """The fixtures' assets (each OBJ with every file of its folder)."""
    pool = []
    for rel in FIXTURE_ASSETS:
        obj = ROOT / rel
        others = sorted(p for p in obj.parent.iterdir() if p.is_file() and p != obj)
        pool.append(Asset(rel, (obj, *others), 0))
    return pool


def samples(pool: list[Asset], count: int, seed: int) -> list[Asset]:
    """``count`` assets drawn with replacement from ``pool`` (the same list for the same seed)."""
    rng = random.Random(seed)
    return [rng.choice(pool) for _ in range(count)]


def build_folder(folder: Path, assets: list[Asset]) -> None:
    """Copy asset k into ``folder/aKKKK/`` (file names kept); its OBJ ends with the comment ``# copy K``."""
    for k, asset in enumerate(assets):
        target = folder / f"a{k:04d}"
        target.mkdir(parents=True)
        obj, *others = asset.files
        data = obj.read_bytes()
        (target / obj.name).write_bytes(data + (b"" if data.endswith(b"\n") else b"\n") + b"# copy %d\n" % k)
        for path in others:
            shutil.copyfile(path, target / path.name)


def tree_hash(folder: Path) -> str:
    """sha256 over every file under ``folder``: its relative path and its bytes, in sorted order."""
    digest = hashlib.sha256()
    for path in sorted(p for p in folder.rglob("*") if p.is_file()):
        digest.update(path.relative_to(folder).as_posix().encode() + b"\0")
        digest.update(hashlib.sha256(path.read_bytes()).digest())
    return digest.hexdigest()


# ------------------------------------------------------------------------------------ measuring


def compile_project(code: Path) -> int:
    """Write the ``.pyc`` files of ``code``'s meshtool and simrun (``compileall``); the number of ``.pyc`` files."""
    subprocess.run([sys.executable, "-m", "compileall", "-q", "meshtool", "simrun"], cwd=code, check=True)
    return sum(1 for base in ("meshtool", "simrun") for _ in (code / base).rglob("__pycache__/*.pyc"))


def git(*args: str) -> str:
    """The output of ``git -C ROOT ARGS`` (stripped)."""
    return subprocess.run(["git", "-C", str(ROOT), *args], capture_output=True, text=True, check=True).stdout.strip()


def snapshot(into: Path) -> str:
    """Export HEAD's meshtool/ and simrun/ into ``into`` (``git archive``); HEAD's short hash."""
    commit = git("rev-parse", "--short=12", "HEAD")
    into.mkdir(parents=True)
    tar = subprocess.run(
        ["git", "-C", str(ROOT), "archive", commit, "meshtool", "simrun"], capture_output=True, check=True
    )
    subprocess.run(["tar", "-x", "-C", str(into)], input=tar.stdout, check=True)
    return commit


def child_environment() -> dict[str, str]:
    """The children's environment: this one without ``PYTHONDONTWRITEBYTECODE``, with ``MUJOCO_GL`` (egl)."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env.setdefault("MUJOCO_GL", "egl")
    return env


def _self_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


class ClusterCPU:
    """CPU seconds of a LocalCluster: this process (its scheduler thread) and its worker processes (psutil)."""

    def __init__(self) -> None:
        self._psutil: Any = None  # without psutil the workers' CPU is not counted (the report says so)
        with contextlib.suppress(ImportError):  # psutil ships no type stubs: imported as Any
            self._psutil = importlib.import_module("psutil")

    @property
    def counts_workers(self) -> bool:
        """Whether the worker processes' CPU is counted (psutil is installed)."""
        return self._psutil is not None

    def snapshot(self) -> tuple[float, dict[int, float]]:
        """(CPU of this process, {pid: CPU of that descendant and its reaped children}) now, seconds."""
        workers: dict[int, float] = {}
        if self._psutil is not None:
            for proc in self._psutil.Process().children(recursive=True):
                try:
                    t = proc.cpu_times()
                except self._psutil.Error:  # gone meanwhile
                    continue
                workers[proc.pid] = t.user + t.system + t.children_user + t.children_system
        return _self_cpu(), workers

    @staticmethod
    def spent(before: tuple[float, dict[int, float]], after: tuple[float, dict[int, float]]) -> float:
        """CPU seconds between two snapshots (a process that appeared counts whole)."""
        own = after[0] - before[0]
        return own + sum(cpu - before[1].get(pid, 0.0) for pid, cpu in after[1].items())


@dataclass
class Run:
    """One measured run: wall and CPU seconds, the 1-minute load average before it, the output's hash."""

    wall: float
    cpu: float
    load: float
    digest: str


@dataclass
class Cell:
    """Every run of one (command, N, executor)."""

    runs: list[Run] = field(default_factory=list)

    def timing(self) -> Timing:
        """The runs as a :class:`_report.Timing` (wall and CPU lists)."""
        t = Timing()
        for r in self.runs:
            t.add(r.wall, r.cpu)
        return t


def run_command(argv: list[str], cwd: Path, env: dict[str, str], ok: tuple[int, ...]) -> tuple[float, float]:
    """Run ``argv``: (wall s, user + system CPU s of it and the children it reaped); raise on another status."""
    start = time.perf_counter()
    proc = subprocess.Popen(argv, cwd=cwd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    assert proc.stderr is not None
    err = proc.stderr.read()  # read to the end (a full pipe would block the command), then reap it
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - start
    proc.returncode = code = os.waitstatus_to_exitcode(status)
    proc.stderr.close()
    if code not in ok:
        tail = err.decode(errors="replace")[-3000:]
        raise RuntimeError(f"{' '.join(argv)} exited {code}:\n{tail}")
    return wall, usage.ru_utime + usage.ru_stime


def executor_args(executor: str, scheduler: str) -> list[str]:
    """The command-line options of ``executor`` (``-j 1``, ``-j 2`` or ``dask``)."""
    if executor == "dask":
        return ["--executor", "dask", "--scheduler", scheduler]
    return executor.split()


@dataclass
class Bench:
    """The measuring context: the console scripts, the work folder, the cluster's address and CPU meter."""

    bin: Path
    work: Path
    scheduler: str
    meter: ClusterCPU
    env: dict[str, str]
    counter: Iterator[int] = field(default_factory=lambda: iter(range(10**9)))

    def once(self, command: str, folder: str, n: int, executor: str) -> Run:
        """One run of ``command`` over ``work/folder`` (N assets) with ``executor``; its output checked and hashed."""
        k = next(self.counter)
        where = executor_args(executor, self.scheduler)
        # absolute paths: a Dask worker resolves a relative one against its own working folder, not the command's
        src = str(self.work / folder)
        if command == "obj2bin":
            out = f"packs-{k}"
            argv = [str(self.bin / "obj2bin"), src, "-o", str(self.work / out), "--no-cache", *where]
            ok: tuple[int, ...] = (0,)
        else:
            out = f"report-{k}.json"
            # exit 1: the corpus's own errors (a missing MTL) found; the report tells it from a crash
            argv = [str(self.bin / "meshtool"), "validate", src, "--no-cache", "--format", "json"]
            argv += ["-o", str(self.work / out)]
            argv += where
            ok = (0, 1)
        load = os.getloadavg()[0]
        before = self.meter.snapshot() if executor == "dask" else None
        wall, cpu = run_command(argv, self.work, self.env, ok)
        if before is not None:
            cpu += self.meter.spent(before, self.meter.snapshot())
        path = self.work / out
        if command == "obj2bin":
            packs = sum(1 for _ in path.rglob("*.mbin"))
            if packs != n:
                raise RuntimeError(f"obj2bin {executor} wrote {packs} packs for {n} assets")
            digest = tree_hash(path)
            shutil.rmtree(path)
        else:
            if not path.exists():
                raise RuntimeError(f"meshtool validate {executor} wrote no report: it failed")
            data = path.read_bytes()
            assets = json.loads(data)["summary"]["assets"]
            if assets != n:
                raise RuntimeError(f"meshtool validate {executor} reported {assets} assets for {n}")
            digest = hashlib.sha256(data).hexdigest()
            path.unlink()
        return Run(wall, cpu, load, digest)


def measure(bench: Bench, sizes: list[int], rounds: Callable[[int], int]) -> dict[tuple[str, int, str], Cell]:
    """Every (command, N, executor) over ``rounds(N)`` rounds, executors rotating; outputs compared."""
    cells: dict[tuple[str, int, str], Cell] = {}
    for n in sizes:
        folder = f"n{n}"
        for r in range(rounds(n)):
            order = EXECUTORS[r % 3 :] + EXECUTORS[: r % 3]
            for command in COMMANDS:
                for executor in order:
                    run = bench.once(command, folder, n, executor)
                    cells.setdefault((command, n, executor), Cell()).runs.append(run)
                    print(
                        f"{command} N={n} {executor}: wall {run.wall:.2f} s, CPU {run.cpu:.2f} s, "
                        f"load {run.load:.2f}, {run.digest[:12]}",
                        flush=True,
                    )
    return cells


def identical(cells: dict[tuple[str, int, str], Cell], sizes: list[int]) -> dict[tuple[str, int], str]:
    """{(command, N): the one output hash of every executor and round}; raises when they differ."""
    same: dict[tuple[str, int], str] = {}
    for command in COMMANDS:
        for n in sizes:
            found = {ex: {r.digest for r in cells[(command, n, ex)].runs} for ex in EXECUTORS}
            digests = set().union(*found.values())
            if len(digests) != 1:
                shown = ", ".join(
                    f"{ex}: {sorted(d)[0][:12]}" + (" ..." if len(d) > 1 else "") for ex, d in found.items()
                )
                raise SystemExit(f"{command} N={n}: the outputs differ between executors or rounds ({shown})")
            same[(command, n)] = digests.pop()
    return same


# ------------------------------------------------------------------------------------ the report


def uptime() -> str:
    """``uptime``'s line (load averages), or the load averages when it cannot run."""
    try:
        return subprocess.run(["uptime"], capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        one, five, fifteen = os.getloadavg()
        return f"load average: {one:.2f}, {five:.2f}, {fifteen:.2f}"


def table(cells: dict[tuple[str, int, str], Cell], sizes: list[int]) -> list[str]:
    """The Markdown rows: one per (command, N, executor), ratios against ``-j 1`` of the same command and N."""
    lines = [
        "| command | N | executor | rounds | wall s (median) | CPU s (median) | assets/s (wall) | assets per CPU s "
        "| assets/s vs -j 1 | CPU vs -j 1 | load (1 min) |",
        "|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---|",
    ]
    for command in COMMANDS:
        for n in sizes:
            base = cells[(command, n, "-j 1")].timing()
            for executor in EXECUTORS:
                cell = cells[(command, n, executor)]
                t = cell.timing()
                loads = ", ".join(f"{r.load:.1f}" for r in cell.runs)
                lines.append(
                    f"| {command} | {n:,} | {executor} | {len(cell.runs)} | {t.wall_median:.2f} | {t.cpu_median:.2f} "
                    f"| {n / t.wall_median:.1f} | {n / t.cpu_median:.1f} | {base.wall_median / t.wall_median:.2f}x "
                    f"| {t.cpu_median / base.cpu_median:.2f} | {loads} |"
                )
    return lines


def _folder_words(n: int, folder: dict[str, int]) -> str:
    """``N = 100: 40 distinct sources, 12.3 MB, 300,000 triangles`` (triangles when known)."""
    distinct = folder["distinct"]
    words = f"N = {n:,}: {distinct} distinct source{'s' if distinct > 1 else ''}, {folder['bytes'] / 1e6:.2f} MB"
    return words + (f", {folder['triangles']:,} triangles" if folder["triangles"] else "")


def section(
    cells: dict[tuple[str, int, str], Cell],
    sizes: list[int],
    same: dict[tuple[str, int], str],
    info: dict[str, Any],
) -> str:
    """The docs/benchmarks.md section (between the batch-throughput markers)."""
    folders = "; ".join(_folder_words(n, info["folders"][n]) for n in sizes)
    hashes = "; ".join(f"{command} N = {n:,}: `{same[(command, n)][:16]}`" for command in COMMANDS for n in sizes)
    cpu_note = (
        "for Dask also the cluster's CPU: the scheduler (a thread of the bench process) and the 2 worker "
        "processes (psutil)"
        if info["workers_counted"]
        else "for Dask also the scheduler (a thread of the bench process); psutil is missing, so the worker "
        "processes' CPU is NOT counted"
    )
    lines = [
        BEGIN,
        "## Batch throughput: `obj2bin DIR` and `meshtool validate DIR`, -j 1, -j 2 and Dask (issue 38)",
        "",
        f"`{info['command']}`{info['nice']} (`make bench-batch`): each command a fresh process of `.venv/bin` "
        "(start-up included), `--no-cache`, over a temporary folder of N assets; `obj2bin DIR -o OUT`, "
        "`meshtool validate DIR --format json -o REPORT` (every rule, the MuJoCo drop test included; exit 1 for the "
        "corpus's own errors is expected). Executors: `-j 1`, `-j 2`, and `--executor dask --scheduler ADDRESS` on "
        "a LocalCluster of 2 single-threaded worker processes started once by the bench "
        f"({info['cluster_start']:.1f} s, not in any row) and warmed by one untimed run of each command. "
        f"Assets: {info['source']}. {folders}. "
        "The executors take turns in a rotating order every round; medians. CPU: user + system of the command "
        f"and its reaped worker processes (`os.wait4`), {cpu_note}. Ratios against -j 1 of the same command and N "
        "(assets/s vs -j 1: the speed-up; CPU vs -j 1 above 1: what the workers cost beyond the work, their start-up "
        "included).",
        "",
        *table(cells, sizes),
        "",
        f"Outputs byte-identical across the three executors and every round: {hashes} (sha256 of the packs' "
        "folder, every relative path and its bytes; of validate's JSON report).",
        "",
        f"Code: {info['version']}. Machine: {platform.machine()}, {os.cpu_count()} CPUs, Python "
        f"{platform.python_version()}; "
        f"{info['pyc']} `.pyc` files of meshtool and simrun compiled before measuring (children run without "
        f"PYTHONDONTWRITEBYTECODE). Before: `{info['uptime_before']}`; after: `{info['uptime_after']}`; "
        f"{info['elapsed'] / 60:.1f} min in all. " + info["load_note"],
        END,
    ]
    return "\n".join(lines)


# ------------------------------------------------------------------------------------ main


def arguments() -> argparse.Namespace:
    """The command line (see the module docstring)."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("corpus", type=Path, nargs="?", default=ROOT.parent / "shared" / "corpus")
    parser.add_argument("--sizes", default="1,100,1000", help="asset counts, comma-separated")
    parser.add_argument("--repeat", type=int, default=3, help="rounds of every size but the largest")
    parser.add_argument("--repeat-largest", type=int, default=1, help="rounds of the largest size")
    parser.add_argument(
        "--max-bytes",
        type=int,
        default=SMALL_BYTES,
        help="largest corpus asset sampled, bytes of its files (default: the cheapest assets, so that 1,000 "
        "assets x 6 contenders take minutes on a shared 2-CPU machine; 1000000 takes several times the CPU)",
    )
    parser.add_argument("--seed", type=int, default=38, help="seed of the sampling")
    parser.add_argument(
        "--snapshot",
        action="store_true",
        help="measure HEAD's meshtool and simrun (git archive into the temporary folder, first on PYTHONPATH), "
        "not the working tree (which other work may be editing)",
    )
    parser.add_argument("--docs", action="store_true", help="write the section into --out")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "benchmarks.md")
    return parser.parse_args()


def main() -> None:
    args = arguments()
    sizes = sorted({int(s) for s in args.sizes.split(",") if s.strip()})
    if not sizes or sizes[0] < 1:
        raise SystemExit("--sizes: positive asset counts, e.g. 1,100,1000")
    started = time.perf_counter()
    if (args.corpus / "manifest.json").exists():
        pool = corpus_pool(args.corpus, args.max_bytes)
        source = (
            f"sampled with replacement (seed {args.seed}) from the {len(pool)} OBJ assets of `{args.corpus.name}/` "
            f"that MuJoCo loads raw, with no missing texture, >= {MIN_TRIANGLES} triangles and <= "
            f"{args.max_bytes / 1e3:,g} KB of files (OBJ, MTL, textures), each copied with its MTL and textures "
            "into its own folder, its OBJ with its own comment line"
        )
        if args.max_bytes <= SMALL_BYTES:
            source += (
                f" (small assets, {min(a.triangles for a in pool)} to {max(a.triangles for a in pool):,} triangles: "
                "the cheapest of the corpus, so that 1,000 assets with every contender fit in about 15 minutes "
                "on a shared 2-CPU machine; the per-asset cost of larger meshes is higher, `--max-bytes 1000000` "
                "measures them)"
            )
    else:
        print(f"{args.corpus} not found: the assets are the project's fixtures", file=sys.stderr)
        pool = fixture_pool()
        source = f"sampled with replacement (seed {args.seed}) from {len(pool)} fixtures ({args.corpus} not found)"
    if not pool:
        raise SystemExit("no asset to sample from")
    drawn = samples(pool, max(sizes), args.seed)
    bin_dir = ROOT / ".venv" / "bin"
    if not (bin_dir / "obj2bin").exists():
        bin_dir = Path(sys.executable).parent
    uptime_before = uptime()
    print(uptime_before, flush=True)
    with tempfile.TemporaryDirectory(prefix="bench-batch-") as tmp:
        work = Path(tmp)
        if args.snapshot:
            code = work / "code"
            version = f"HEAD {snapshot(code)} (`--snapshot`: its meshtool/ and simrun/ exported, not the working tree)"
        else:
            code = ROOT
            dirty = git("status", "--porcelain", "--", "meshtool", "simrun")
            version = f"the working tree at {git('rev-parse', '--short=12', 'HEAD')}" + (
                " with uncommitted changes in meshtool/ or simrun/" if dirty else ""
            )
        # The commands, the cluster's workers (they inherit this environment) and its scheduler (this process,
        # which unpickles the tasks) all import meshtool and simrun from ``code``, compiled once.
        sys.path.insert(0, str(code))
        os.environ["PYTHONPATH"] = os.pathsep.join(p for p in (str(code), os.environ.get("PYTHONPATH")) if p)
        os.environ.pop("PYTHONDONTWRITEBYTECODE", None)
        os.environ.setdefault("MUJOCO_GL", "egl")
        pyc = compile_project(code)
        distributed: Any = importlib.import_module("distributed")  # untyped: as Any

        folders: dict[int, dict[str, int]] = {}
        for n in sizes:
            build_folder(work / f"n{n}", drawn[:n])
            chosen = drawn[:n]
            folders[n] = {
                "assets": n,
                "distinct": len({a.name for a in chosen}),
                "bytes": sum(a.size for a in chosen),
                "triangles": sum(a.triangles for a in chosen),
            }
        start = time.perf_counter()
        with distributed.LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None, silence_logs=logging.ERROR
        ) as cluster:
            cluster_start = time.perf_counter() - start
            bench = Bench(bin_dir, work, cluster.scheduler_address, ClusterCPU(), child_environment())
            for command in COMMANDS:  # warm-up, untimed: imports on the workers, the file cache
                for executor in EXECUTORS:
                    bench.once(command, f"n{sizes[0]}", sizes[0], executor)
            largest = max(sizes)
            cells = measure(bench, sizes, lambda n: args.repeat_largest if n == largest else args.repeat)
            workers_counted = bench.meter.counts_workers
    same = identical(cells, sizes)
    for (command, n), digest in same.items():
        print(f"{command} N={n}: outputs byte-identical across {', '.join(EXECUTORS)} (sha256 {digest[:16]})")
    uptime_after = uptime()
    loads = [r.load for cell in cells.values() for r in cell.runs]
    idle = max(loads) < 0.5
    load_note = (
        "The machine was idle (1-minute load below 0.5 before every run)."
        if idle
        else f"The machine was not idle (1-minute load {min(loads):.1f} to {max(loads):.1f} before the runs, "
        "shared with other jobs): wall-clock times and the -j 2 / Dask speed-ups are lower than on an idle "
        "machine; CPU per asset is the steadier measure."
    )
    nice = os.nice(0)
    argv = " ".join(a if " " not in a else repr(a) for a in sys.argv[1:])
    info: dict[str, Any] = {
        "command": f"python bench/batch_throughput.py {argv}".strip(),
        "nice": f" at niceness {nice}" if nice else "",
        "cluster_start": cluster_start,
        "source": source,
        "folders": folders,
        "workers_counted": workers_counted,
        "pyc": pyc,
        "version": version,
        "uptime_before": uptime_before,
        "uptime_after": uptime_after,
        "elapsed": time.perf_counter() - started,
        "load_note": load_note,
    }
    text = section(cells, sizes, same, info)
    print(text)
    if args.docs:
        write_section(args.out, text, BEGIN, END)
        print(f"wrote the section into {args.out}")


if __name__ == "__main__":
    main()
