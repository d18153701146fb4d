"""Kill rate per module from mutmut's results (mutants/**/*.py.meta), and the surviving mutants.

Usage: python scripts/mutation_summary.py [MODULE ...]   (default: `[tool.mutmut] only_mutate` in pyproject.toml;
       MODULE: a path such as simrun/world/edit.py, or a file name without .py found under mutants/)
       python scripts/mutation_summary.py --sample K MODULE [OFFSET]   (every K-th mutant name of MODULE, for
       `mutmut run NAME...` when there is no time for all of them; mutmut must have generated the mutants)

Killed: a test failed (or pytest hit an internal error, or the mutant ran past its CPU-time limit: a mutant
that makes the simulation loop forever is caught). The rate is killed / (killed + survived + no tests);
mutants not yet run are counted apart.
"""

from __future__ import annotations

import json
import sys
import tomllib
from collections import Counter
from pathlib import Path

#: Modules mutated only in some functions (``make mutants``' MUTATE names them): the others are not counted.
FUNCTIONS = {"simrun/world/world.py": ("xǁWorldǁstep__", "xǁWorldǁreschedule__")}


def _modules() -> list[str]:
    """The paths ``[tool.mutmut] only_mutate`` of pyproject.toml names (what ``make mutants`` mutates)."""
    config = tomllib.loads(Path("pyproject.toml").read_text(encoding="utf-8"))
    return list(config["tool"]["mutmut"]["only_mutate"])


def _path(module: str) -> str:
    """``module`` as a path relative to the checkout: given, or the one ``mutants/`` holds of that file name."""
    if module.endswith(".py"):
        return module
    found = sorted(Path("mutants").glob(f"**/{Path(module).name}.py.meta"))
    return str(found[0].relative_to("mutants"))[: -len(".meta")] if found else f"simrun/{module}.py"


KILLED = {1, 3, -24, 24, 152, 255, 36, 37, -11, -9}
SURVIVED = {0}
NO_TESTS = {5, 33}


def sample(every: int, module: str, offset: int = 0) -> int:
    """Print every ``every``-th mutant of ``module`` in mutmut's order, from ``offset`` (deterministic)."""
    codes = json.loads((Path("mutants") / f"{_path(module)}.meta").read_text())["exit_code_by_key"]
    print(" ".join(name for k, name in enumerate(codes) if k % every == offset % every))
    return 0


def main() -> int:
    if sys.argv[1:2] == ["--sample"]:
        return sample(int(sys.argv[2]), sys.argv[3], int(sys.argv[4]) if len(sys.argv) > 4 else 0)
    modules = [_path(m) for m in sys.argv[1:]] or _modules()
    print("| module | mutants | killed | survived | no tests | not run | kill rate |")
    print("|---|---|---|---|---|---|---|")
    survivors: list[str] = []
    for module in modules:
        meta = Path("mutants") / f"{module}.meta"
        if not meta.exists():
            print(f"| {module} | - | - | - | - | - | not run |")
            continue
        codes = json.loads(meta.read_text())["exit_code_by_key"]
        if module in FUNCTIONS:
            codes = {k: v for k, v in codes.items() if any(f".{f}" in k for f in FUNCTIONS[module])}
        count = Counter()
        for name, code in codes.items():
            if code is None:
                count["not run"] += 1
            elif code in KILLED:
                count["killed"] += 1
            elif code in SURVIVED:
                count["survived"] += 1
                survivors.append(name)
            elif code in NO_TESTS:
                count["no tests"] += 1
                survivors.append(name)
            else:
                count["other"] += 1
        checked = count["killed"] + count["survived"] + count["no tests"]
        rate = f"{100 * count['killed'] / checked:.1f} %" if checked else "-"
        print(
            f"| {module} | {len(codes)} | {count['killed']} | {count['survived']} | {count['no tests']} "
            f"| {count['not run']} | {rate} |"
        )
    if survivors:
        print("\nsurvivors (`mutmut show NAME` prints the change):")
        for name in survivors:
            print(" ", name)
    return 0


if __name__ == "__main__":
    sys.exit(main())
