"""Start-up benchmark: meshtool commands whose work is small, against the interpreter and a bare click program.

Usage: python bench/startup.py . [--repeat 7] [--out docs/benchmarks.md]

Each contender is a fresh process (the installed console scripts of this checkout's .venv), run in turn
with the others for --repeat rounds; wall-clock and CPU (user + system of the process) are recorded.
Rows: ``python -c pass``, a bare click program's ``--version``, ``meshtool --version`` and ``--help``,
``meshtool normalize`` of the seed head (``fixtures/head/Head 1.obj --units cm``) and ``obj2bin --hulls
decompose`` of the bowl fixture with its decomposition already cached (a warm-up run fills the cache).
The evidence of what each command imports comes from ``python -X importtime`` (module count, the slowest
imports, and whether trimesh, scipy, mujoco or pxr were imported).

Two more tables (issue 28): ``--help`` of every command of ``meshtool``, ``obj2bin`` and ``simrun`` against the
bare click program (goal <= 2x its CPU), and a small mesh made into a MuJoCo model by meshtool (``obj2bin SRC
--mjcf DIR``, one command; ``obj2bin`` then ``meshtool mjcf``, two) against ``obj2mjcf --obj-dir`` (the
peers' environment, ``--obj2mjcf PATH``), every contender a fresh process, CPU of the process and children.
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

from meshtool.cli.main import COMMANDS

BEGIN, END = "<!-- startup:begin -->", "<!-- startup:end -->"
HELP_BEGIN, HELP_END = "<!-- help:begin -->", "<!-- help:end -->"
MODEL_BEGIN, MODEL_END = "<!-- small-model:begin -->", "<!-- small-model:end -->"
SIMRUN_COMMANDS = ("check", "doctor", "export", "play", "replay", "resim", "snapshot", "test", "view")
#: (name, path: in the checkout, or ``corpus:`` relative to ../shared/corpus)
SMALL = [
    ("bowl (fixture, 336 tri)", "fixtures/bowl/bowl.obj"),
    ("suzanne (corpus, 1k tri)", "corpus:src/alecjacobson__common-3d-test-models/data/suzanne.obj"),
    ("fuze (corpus, 1k tri, textured)", "corpus:src/mikedh__trimesh/models/fuze.obj"),
]
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
                "from meshtool.cli.main import main\ntry: main()\nexcept SystemExit: pass"
            ),
            "meshtool normalize": importtime(
                f"import sys, tempfile; sys.argv = ['meshtool', 'normalize', {str(head)!r}, '-o', tempfile.mkdtemp(), "
                "'--units', 'cm']\nfrom meshtool.cli.main import main\ntry: main()\nexcept SystemExit: pass"
            ),
            "obj2bin cached": importtime(
                f"import sys, tempfile; sys.argv = ['obj2bin', {str(bowl)!r}, '--hulls', 'decompose', '--cache-dir', "
                f"{str(cache)!r}, '-o', tempfile.mkdtemp() + '/b.mbin']\nfrom meshtool.cli.main import obj2bin\n"
                "try: obj2bin()\nexcept SystemExit: pass"
            ),
            "obj2bin cached --no-check": importtime(
                f"import sys, tempfile; sys.argv = ['obj2bin', {str(bowl)!r}, '--hulls', 'decompose', '--cache-dir', "
                f"{str(cache)!r}, '--no-check', '-o', tempfile.mkdtemp() + '/b.mbin']\n"
                "from meshtool.cli.main import obj2bin\ntry: obj2bin()\nexcept SystemExit: pass"
            ),
        }
    write_section(args.out, table(results, evidence, args.repeat), BEGIN, END)
    write_section(args.out, help_table(bin_dir, args.repeat), HELP_BEGIN, HELP_END)
    write_section(args.out, model_table(root, bin_dir, args.obj2mjcf, args.repeat), MODEL_BEGIN, MODEL_END)
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
        "properties and hull quality are computed by `meshtool/hulls/surface.py`; a cached decomposition reads its "
        "finished hulls, so neither CoACD nor qhull runs). *obj2bin* compiles the packed asset in MuJoCo before "
        "writing it (`meshtool/mjcf/loadcheck.py`), which imports mujoco and simrun, unless these bytes passed the "
        "same check before (remembered in the cache beside the hulls, keyed by the bytes, simrun's files and the "
        "MuJoCo version): *obj2bin cached* has both caches warm, *check compiled* forgets the checks before "
        "every run, `--no-check` skips the check. "
        "`tests/test_startup.py` checks the imports of `import meshtool`, `--version` and `--help`.",
        END,
    ]
    return "\n".join(lines)


def help_table(bin_dir: Path, repeat: int) -> str:
    """``--help`` of every command, fresh processes, against the bare click program (goal <= 2x CPU)."""
    meshtool, obj2bin, simrun = (str(bin_dir / n) for n in ("meshtool", "obj2bin", "simrun"))
    contenders = {"bare click --help": command([sys.executable, "-c", CLICK_APP, "--help"])}
    contenders |= {"meshtool --help": command([meshtool, "--help"]), "obj2bin --help": command([obj2bin, "--help"])}
    contenders |= {f"meshtool {c} --help": command([meshtool, c, "--help"]) for c in sorted(COMMANDS)}
    contenders["simrun --help"] = command([simrun, "--help"])
    contenders |= {f"simrun {c} --help": command([simrun, c, "--help"]) for c in SIMRUN_COMMANDS}
    before = load_average()
    results = interleave(contenders, repeat)
    base = results["bare click --help"].cpu_median
    lines = [
        HELP_BEGIN,
        "## Start-up: `--help` of every command",
        "",
        f"`python bench/startup.py . --repeat {repeat}` (part of `make bench`): each a fresh process, interleaved, "
        f"{repeat} rounds; CPU (user + system) min / median, s. {before} before, {load_average()} after. Goal "
        "(issue 28): <= 2x the bare click program's CPU. `tests/test_perf_startup.py` checks that none of these "
        "imports numpy, Pillow, trimesh, scipy, MuJoCo, CoACD or the GLB exporter.",
        "",
        "| command | CPU min / median s | wall median s | CPU / bare click | goal <= 2x |",
        "|---|---|---|---|---|",
    ]
    for name, t in results.items():
        ratio = t.cpu_median / base
        met = "" if name.startswith("bare") else "met" if ratio <= 2 else f"short by {ratio / 2:.2f}x"
        lines.append(f"| {name} | {t.cpu_min:.3f} / {t.cpu_median:.3f} | {t.wall_median:.3f} | {ratio:.2f}x | {met} |")
    return "\n".join([*lines, HELP_END])


def _both(
    first: Callable[[], tuple[float, float]], second: Callable[[], tuple[float, float]]
) -> Callable[[], tuple[float, float]]:
    """Two commands in turn: their walls and CPUs added."""

    def run() -> tuple[float, float]:
        a, b = first(), second()
        return a[0] + b[0], a[1] + b[1]

    return run


def model_table(root: Path, bin_dir: Path, obj2mjcf: str | None, repeat: int) -> str:
    """A small mesh to a MuJoCo model: meshtool's commands against obj2mjcf, fresh processes, CPU."""
    meshtool, obj2bin = str(bin_dir / "meshtool"), str(bin_dir / "obj2bin")
    corpus = root.parent / "shared" / "corpus"
    sources = [(name, corpus / rel[7:] if rel.startswith("corpus:") else root / rel) for name, rel in SMALL]
    failed: dict[str, str] = {}
    rows = []
    before = load_average()
    counter = iter(range(10**6))
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        for name, src in sources:
            if not src.exists():
                print(f"skip {name}: {src} not found", file=sys.stderr)
                continue
            folder = work / src.stem
            folder.mkdir()
            for file in src.parent.glob(f"{src.stem}*"):  # the OBJ, its MTL and texture (fuze*), for --obj-dir
                shutil.copy(file, folder / file.name)

            def one_command(src: Path = src) -> tuple[float, float]:
                return command([obj2bin, str(src), "--mjcf", str(work / f"one{next(counter)}"), "--no-cache"])()

            def two_commands(src: Path = src) -> tuple[float, float]:
                k = next(counter)
                pack = work / f"two{k}.mbin"
                first = command([obj2bin, str(src), "-o", str(pack), "--no-cache", "--no-check"])
                second = command([meshtool, "mjcf", str(pack), "-o", str(work / f"two{k}")])
                return _both(first, second)()

            contenders = {"obj2bin SRC --mjcf DIR": one_command, "obj2bin + meshtool mjcf": two_commands}
            if obj2mjcf:
                peer = [obj2mjcf, "--obj-dir", str(folder), "--overwrite", "--save-mjcf", "--compile-model"]
                contenders["obj2mjcf --save-mjcf --compile-model"] = command(peer)
            for label, run in list(contenders.items()):
                try:
                    run()  # warm the page cache and any compiled-bytecode caches alike
                except RuntimeError:
                    failed[name] = label
                    del contenders[label]
            rows.append((name, interleave(contenders, repeat)))
    lines = [
        MODEL_BEGIN,
        "## A small mesh to a MuJoCo model: meshtool vs obj2mjcf",
        "",
        f"`python bench/startup.py . --repeat {repeat} --obj2mjcf .bench-peers/bin/obj2mjcf` (part of `make "
        f"bench`): every contender a fresh process (CPU: user + system of it and its children), interleaved, "
        f"{repeat} rounds after one warm-up round; {before} before, {load_average()} after. meshtool makes one "
        "convex hull (numpy, `meshtool/hulls/quickhull.py`: no scipy or trimesh import) and compiles the written model "
        "in MuJoCo (`--no-cache`: nothing remembered); obj2mjcf writes the MJCF (`--save-mjcf`) and its meshes "
        "and compiles it (`--compile-model`), no decomposition. Goal (issue 28): no more CPU than obj2mjcf.",
        "",
        "| mesh | contender | CPU min / median s | wall median s | CPU / obj2mjcf | goal <= 1x |",
        "|---|---|---|---|---|---|",
    ]
    for name, results in rows:
        peer = results.get("obj2mjcf --save-mjcf --compile-model")
        for contender, t in results.items():
            ratio = t.cpu_median / peer.cpu_median if peer else float("nan")
            goal = (
                ""
                if contender.startswith("obj2mjcf") or not peer
                else "met"
                if ratio <= 1
                else f"short by {ratio:.2f}x"
            )
            lines.append(
                f"| {name} | {contender} | {t.cpu_min:.3f} / {t.cpu_median:.3f} | {t.wall_median:.3f} | "
                f"{f'{ratio:.2f}x' if peer else '-'} | {goal} |"
            )
    if not obj2mjcf:
        lines.append("\nobj2mjcf was not given (`--obj2mjcf`, which `make bench` passes).")
    for name, label in failed.items():
        lines.append(f"\n{label} failed on {name} (exit status 1), so it has no row there.")
    return "\n".join([*lines, MODEL_END])


if __name__ == "__main__":
    sys.exit(main())
