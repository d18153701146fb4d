"""Start-up benchmark: meshtool commands whose work is small, against the interpreter and a bare click program.

Usage: python bench/startup.py . [--repeat 7] [--out docs/benchmarks.md]

Each contender is a fresh process (the installed console scripts of this checkout's .venv), run in turn
with the others for --repeat rounds; wall-clock and CPU (user + system of the process) are recorded.
Rows: ``python -c pass``, a bare click program's ``--version``, ``meshtool --version`` and ``--help``,
``meshtool normalize`` of the seed head (``fixtures/head/Head 1.obj --units cm``) and ``obj2bin --hulls
decompose`` of the bowl fixture with its decomposition already cached (a warm-up run fills the cache).
The evidence of what each command imports comes from ``python -X importtime`` (module count, the slowest
imports, and whether trimesh, scipy, mujoco or pxr were imported).
"""

from __future__ import annotations

import platform
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

from _report import Timing, arguments, command, interleave, load_average, write_section

BEGIN, END = "<!-- startup:begin -->", "<!-- startup:end -->"
HEAVY = ("trimesh", "scipy", "mujoco", "pxr", "coacd", "dask", "PIL", "numpy")
CLICK_APP = (
    "import click\n@click.group()\n@click.version_option('1.0', prog_name='bare')\ndef main():\n    pass\nmain()"
)
GOALS = {
    "meshtool --version": 0.15,
    "meshtool --help": 0.15,
    "meshtool normalize": 0.5,
    "obj2bin cached": 0.5,
    "obj2bin cached --no-check": 0.5,
}


def fresh_out(make: Callable[[Path], list[str]], work: Path) -> Callable[[], tuple[float, float]]:
    """A command contender whose output goes to a new folder each run (nothing is replaced)."""
    counter = iter(range(10**6))

    def run() -> tuple[float, float]:
        return command(make(work / f"run{next(counter)}"))()

    return run


def forget_checks(cache: Path, run: Callable[[], tuple[float, float]]) -> Callable[[], tuple[float, float]]:
    """``run`` after removing the remembered MuJoCo checks (untimed): the check compiles every time."""

    def forgetful() -> tuple[float, float]:
        shutil.rmtree(cache / "checks", ignore_errors=True)
        return run()

    return forgetful


def importtime(code: str) -> tuple[int, list[tuple[str, float]], list[str]]:
    """(module count, the 5 slowest imports with cumulative ms, heavy modules imported) of ``python -c code``."""
    result = subprocess.run(
        [sys.executable, "-X", "importtime", "-c", code], capture_output=True, text=True, check=False
    )
    rows = []
    for line in result.stderr.splitlines():
        if not line.startswith("import time:") or "|" not in line or "cumulative" in line:
            continue
        _, cumulative, name = (part.strip() for part in line.split(":", 1)[1].split("|"))
        rows.append((name, int(cumulative) / 1000))
    top_level = [(n, t) for n, t in rows if "." not in n]
    top = sorted(top_level, key=lambda r: -r[1])[:5]
    heavy = sorted({n.split(".")[0] for n, _ in rows} & set(HEAVY))
    return len(rows), top, heavy


def main() -> int:
    args = arguments(__doc__, 7)
    root = Path(args.corpus).resolve()
    bin_dir = Path(sys.executable).parent
    meshtool, obj2bin = str(bin_dir / "meshtool"), str(bin_dir / "obj2bin")
    head, bowl = root / "fixtures" / "head" / "Head 1.obj", root / "fixtures" / "bowl" / "bowl.obj"
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        cache = work / "hulls-cache"
        warm = [obj2bin, str(bowl), "--hulls", "decompose", "--cache-dir", str(cache), "-o", str(work / "warm.mbin")]
        subprocess.run(warm, check=True, capture_output=True)
        cached = [obj2bin, str(bowl), "--hulls", "decompose", "--cache-dir", str(cache)]
        contenders = {
            "python -c pass": command([sys.executable, "-c", "pass"]),
            "bare click --version": command([sys.executable, "-c", CLICK_APP, "--version"]),
            "meshtool --version": command([meshtool, "--version"]),
            "meshtool --help": command([meshtool, "--help"]),
            "meshtool normalize": fresh_out(
                lambda out: [meshtool, "normalize", str(head), "-o", str(out), "--units", "cm"], work
            ),
            "obj2bin cached": fresh_out(lambda out: [*cached, "-o", f"{out}.mbin"], work),
            "obj2bin cached --no-check": fresh_out(lambda out: [*cached, "--no-check", "-o", f"{out}.mbin"], work),
            "obj2bin cached hulls, check compiled": forget_checks(
                cache, fresh_out(lambda out: [*cached, "-o", f"{out}.mbin"], work)
            ),
        }
        results = interleave(contenders, args.repeat)
        evidence = {
            "meshtool --version": importtime(
                "import sys; sys.argv = ['meshtool', '--version']\n"
                "from meshtool.cli import main\ntry: main()\nexcept SystemExit: pass"
            ),
            "meshtool normalize": importtime(
                f"import sys, tempfile; sys.argv = ['meshtool', 'normalize', {str(head)!r}, '-o', tempfile.mkdtemp(), "
                "'--units', 'cm']\nfrom meshtool.cli import main\ntry: main()\nexcept SystemExit: pass"
            ),
            "obj2bin cached": importtime(
                f"import sys, tempfile; sys.argv = ['obj2bin', {str(bowl)!r}, '--hulls', 'decompose', '--cache-dir', "
                f"{str(cache)!r}, '-o', tempfile.mkdtemp() + '/b.mbin']\nfrom meshtool.cli import obj2bin\n"
                "try: obj2bin()\nexcept SystemExit: pass"
            ),
            "obj2bin cached --no-check": importtime(
                f"import sys, tempfile; sys.argv = ['obj2bin', {str(bowl)!r}, '--hulls', 'decompose', '--cache-dir', "
                f"{str(cache)!r}, '--no-check', '-o', tempfile.mkdtemp() + '/b.mbin']\n"
                "from meshtool.cli import obj2bin\ntry: obj2bin()\nexcept SystemExit: pass"
            ),
        }
    write_section(args.out, table(results, evidence, args.repeat), BEGIN, END)
    for name, t in results.items():
        print(f"{name}: wall {t.wall_min:.3f}/{t.wall_median:.3f} s, cpu {t.cpu_min:.3f}/{t.cpu_median:.3f} s")
    return 0


def table(
    results: dict[str, Timing], evidence: dict[str, tuple[int, list[tuple[str, float]], list[str]]], repeat: int
) -> str:
    base = results["bare click --version"]
    lines = [
        BEGIN,
        "## Start-up: small commands",
        "",
        f"`python bench/startup.py . --repeat {repeat}` (part of `make bench`): each command a fresh process, the "
        f"contenders interleaved, {repeat} rounds; seconds as min / median of wall-clock and of CPU (user + "
        f"system). Machine: {platform.machine()}, CPython {platform.python_version()}; {load_average()} at the "
        "end of the run (the machine is shared: wall times include waiting for a CPU, min is the closest to an "
        "idle machine).",
        "",
        "| command | wall min / median s | CPU min / median s | CPU / bare click | goal (wall, idle) "
        "| met (min wall) |",
        "|---|---|---|---|---|---|",
    ]
    for name, t in results.items():
        goal = GOALS.get(name)
        met = "" if goal is None else ("yes" if t.wall_min <= goal else "no")
        lines.append(
            f"| {name} | {t.wall_min:.3f} / {t.wall_median:.3f} | {t.cpu_min:.3f} / {t.cpu_median:.3f} | "
            f"{t.cpu_median / base.cpu_median:.1f}x | {'' if goal is None else f'<= {goal}'} | {met} |"
        )
    lines += [
        "",
        "`python -X importtime` of the same commands in one process (modules imported, the slowest top-level "
        "imports with their cumulative import time, and which heavy modules were imported at all):",
        "",
        "| command | modules | slowest imports (cumulative ms) | heavy modules imported |",
        "|---|---|---|---|",
    ]
    for name, (count, top, heavy) in evidence.items():
        slow = ", ".join(f"{n} {t:.0f}" for n, t in top)
        lines.append(f"| {name} | {count} | {slow} | {', '.join(heavy) or 'none'} |")
    lines += [
        "",
        "*normalize* imports numpy, Pillow and the readers it uses, never trimesh, scipy, mujoco or pxr (mass "
        "properties and hull quality are computed by `meshtool/surface.py`; a cached decomposition reads its "
        "finished hulls, so neither CoACD nor qhull runs). *obj2bin* compiles the packed asset in MuJoCo before "
        "writing it (`meshtool/loadcheck.py`), which imports mujoco and simrun, unless these bytes passed the "
        "same check before (remembered in the cache beside the hulls, keyed by the bytes, simrun's files and the "
        "MuJoCo version): *obj2bin cached* has both caches warm, *check compiled* forgets the checks before "
        "every run, `--no-check` skips the check. "
        "`tests/test_startup.py` checks the imports of `import meshtool`, `--version` and `--help`.",
        END,
    ]
    return "\n".join(lines)


if __name__ == "__main__":
    sys.exit(main())
