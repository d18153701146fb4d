"""The meshes real models load, their consumers as meshtool finds them, and what ``meshtool validate`` says.

Two sets of models (issue 38):

- every MJCF model dm_control and gymnasium ship, installed in the bench environment ``.bench-mjcf/`` that
  ``bench/mjcf_robots.py`` creates (``pip install --no-deps`` of the pinned versions; created here the same
  way when missing). The files a model loads are MuJoCo's own list: the model compiled with
  ``MjModel.from_xml_path`` and each mesh's path (``mesh_pathadr`` into ``paths``). Models MuJoCo refuses and
  include-only fragments are left out (``bench/mjcf_robots.py`` classifies them);
- every URDF under ``../shared/robots``: its ``<mesh filename>`` references, ``package://NAME/`` resolved in
  the folder above the URDF named ``NAME``, others relative to the URDF.

For each mesh file a model loads (MuJoCo's binary ``.msh`` is no meshtool input: counted only):

- *consumer seen*: :func:`meshtool.frame.consumers.find_consumers` (the same index ``obj2bin`` and ``validate``
  use) names this model's file among the mesh's consumers;
- *consumer's frame*: the normaliser keeps the mesh Z-up as it is (``asset.json``'s ``transform.up`` is
  ``z``), the frame every URDF and MJCF consumer uses it in (MuJoCo reads the file's coordinates unrotated);
- the findings of ``meshtool validate``'s per-asset check (:func:`meshtool.validate.task.read_asset` and
  ``judge_asset``, default limits, the physics plugin included), by rule and severity. A file used by several
  models is checked once and counted for each.

Exit status 1 when a file its consumer loads has an error. Writes the section between
``<!-- consumers:begin/end -->`` in docs/corpus.md (``--docs``), else prints it.

Usage: python bench/consumers_check.py [--robots ../shared/robots] [--docs]
"""

from __future__ import annotations

import argparse
import collections
import os
import sys
import time
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import mujoco

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from bench._report import write_section  # noqa: E402
from bench.mjcf_robots import PACKAGES, classify, site_packages  # noqa: E402
from meshtool.formats import mesh_format  # noqa: E402
from meshtool.frame.consumers import INDEX, find_consumers  # noqa: E402
from meshtool.frame.modelroot import find_model_root  # noqa: E402
from meshtool.validate.rules import RULES  # noqa: E402
from meshtool.validate.task import AssetTask, judge_asset, read_asset  # noqa: E402

BEGIN, END = "<!-- consumers:begin -->", "<!-- consumers:end -->"
#: Measured once with the meshtool before issue 38 (commit 7ee4384, its nearby search only), over the same
#: distinct files: ``git worktree add /tmp/old 7ee4384`` and the same per-file loop with ``PYTHONPATH=/tmp/old``.
BEFORE = (
    "Before issue 38 (commit 7ee4384: the mesh's folder, its parent and the parent's subfolders only), over the same",
    "distinct files: dm_control's 173 STL files 172 seen (173 Z-up: STL falls back to Z-up anyway); ../shared/robots'",
    "62 files 27 seen, 56 Z-up: solo's 6 OBJ files, three folders below their URDF (`meshes/obj/with_foot/`",
    "under `robots/solo.urdf`), were turned 90 degrees about X (0 of 6 in the consumer's frame, now 6 of 6).",
)


@dataclass
class Checked:
    """One mesh file's outcome."""

    consumers: set[Path]
    up: str | None
    findings: list[tuple[str, str]]  # (rule, severity)


@dataclass
class Model:
    """One consumer file and the mesh files it loads."""

    name: str
    file: Path
    kind: str
    meshes: list[Path] = field(default_factory=list)
    msh: int = 0


def mjcf_models(site: Path) -> list[Model]:
    """dm_control's and gymnasium's loadable MJCF models and the mesh files MuJoCo loads for each."""
    out = []
    for kind, path, _ in classify(site):
        if kind != "model":
            continue
        try:
            model = mujoco.MjModel.from_xml_path(str(path))
        except ValueError:
            continue  # refused by MuJoCo alone (bench/mjcf_robots.py lists them)
        paths = bytes(model.paths)
        files = []
        for m in range(model.nmesh):
            start = int(model.mesh_pathadr[m])
            if start < 0:
                continue
            files.append(Path(os.path.realpath(paths[start : paths.index(b"\0", start)].decode())))
        name = path.relative_to(site).as_posix()
        entry = Model(name, path, "mjcf")
        for file in sorted(set(files)):
            if mesh_format(file) is None:
                entry.msh += 1
            else:
                entry.meshes.append(file)
        out.append(entry)
    return out


def urdf_models(robots: Path) -> list[Model]:
    """Every URDF under ``robots`` and the mesh files it references (that exist)."""
    out = []
    for urdf in sorted(robots.rglob("*.urdf")):
        tree = ET.parse(urdf)
        files = set()
        for mesh in tree.getroot().iter("mesh"):
            ref = mesh.get("filename", "").strip()
            if ref.startswith("package://"):
                package, _, rest = ref[len("package://") :].partition("/")
                top = next((f for f in urdf.parents if f.name == package), None)
                if top is None:
                    continue
                file = top / rest
            else:
                file = urdf.parent / ref.removeprefix("file://")
            if file.is_file():
                files.add(Path(os.path.realpath(file)))
        out.append(Model(urdf.relative_to(robots).as_posix(), urdf, "urdf", sorted(files)))
    return out


def check(path: Path) -> Checked:
    """validate's per-asset check of one mesh, with the consumers and up rule the normaliser saw."""
    read = read_asset(AssetTask(path, path.name))
    up = read.asset.manifest["transform"].get("up") if read.asset is not None else None
    result = judge_asset(read)
    found = find_consumers(path, find_model_root(path.parent))
    consumers = {Path(os.path.realpath(path.parent / c.file)) for c in found}
    return Checked(consumers, up, [(f.code, f.severity.value) for f in result.findings])


def table(models: list[Model], checked: dict[Path, Checked]) -> tuple[list[str], dict[str, int]]:
    """The Markdown rows, one per model with meshes, and the totals."""
    rows = []
    totals: collections.Counter[str] = collections.Counter()
    for model in models:
        if not model.meshes and not model.msh:
            continue
        seen = sum(1 for m in model.meshes if Path(os.path.realpath(model.file)) in checked[m].consumers)
        framed = sum(1 for m in model.meshes if checked[m].up == "z")
        by_rule: collections.Counter[str] = collections.Counter()
        errors = 0
        for mesh in model.meshes:
            for rule, severity in checked[mesh].findings:
                if severity == "error":
                    errors += 1
                by_rule[f"{rule} {severity[0].upper()}"] += 1
        objs = sum(1 for m in model.meshes if m.suffix.lower() == ".obj")
        obj_framed = sum(1 for m in model.meshes if m.suffix.lower() == ".obj" and checked[m].up == "z")
        rules = ", ".join(f"{k} x{v}" for k, v in sorted(by_rule.items())) or "none"
        rows.append(
            f"| `{model.name}` | {len(model.meshes)} | {model.msh} | {seen} | {framed} | {errors} | "
            f"{sum(v for k, v in by_rule.items() if k.endswith(' W'))} | {rules} |"
        )
        totals.update(
            models=1, meshes=len(model.meshes), msh=model.msh, seen=seen, framed=framed, errors=errors, obj=objs
        )
        totals["obj_framed"] += obj_framed
    return rows, dict(totals)


def section(groups: list[tuple[str, list[Model]]], checked: dict[Path, Checked], seconds: float) -> str:
    versions = ", ".join(f"{name} {version}" for name, version in PACKAGES.items())
    lines = [
        BEGIN,
        "## Consumers of dm_control's and ../shared/robots' meshes",
        "",
        "Generated by `python bench/consumers_check.py --docs` (issue 38; MuJoCo "
        f"{mujoco.__version__}, {versions} in `.bench-mjcf/`); do not edit. Per model: the mesh files its",
        "consumer loads (MuJoCo's compiled list for MJCF, the `<mesh filename>`s for URDF), `.msh` files (MuJoCo's",
        "binary format, no meshtool input), how many of the meshes meshtool finds this model's file using",
        "(*seen*), how many the normaliser keeps in the consumer's frame (Z-up as the file is), and the findings of",
        "`meshtool validate`'s check of each file, by rule (E error, W warning, I info). Rule names:",
        "docs/validate-rules.md.",
        "",
    ]
    for title, models in groups:
        rows, totals = table(models, checked)
        empty = sum(1 for m in models if not m.meshes and not m.msh)
        lines += [
            f"### {title}",
            "",
            "| model | meshes | .msh | seen | consumer's frame | errors | warnings | findings by rule |",
            "|---|---|---|---|---|---|---|---|",
            *rows,
            f"| **{totals.get('models', 0)} models** | {totals.get('meshes', 0)} | {totals.get('msh', 0)} | "
            f"{totals.get('seen', 0)} | {totals.get('framed', 0)} | {totals.get('errors', 0)} | | |",
            "",
            f"{len(models)} models read, {empty} of them load no mesh file (not listed); a file several models load",
            f"counts for each. OBJ meshes among them: {totals.get('obj', 0)}, in their consumer's frame: "
            f"{totals.get('obj_framed', 0)}.",
            "",
        ]
    distinct = len(checked)
    lines += [
        f"{distinct} distinct mesh files checked in {seconds:.0f} s (one process, the physics plugin included).",
        "",
        *BEFORE,
        END,
    ]
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--robots", type=Path, default=ROOT.parent / "shared" / "robots")
    parser.add_argument("--docs", action="store_true", help="write the section into docs/corpus.md")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "corpus.md")
    args = parser.parse_args()
    site = site_packages()
    groups = [("MJCF models of dm_control and gymnasium", mjcf_models(site))]
    if args.robots.is_dir():
        groups.append((f"URDF robots of {args.robots.name}/", urdf_models(args.robots)))
    started = time.perf_counter()
    INDEX.clear()
    checked: dict[Path, Checked] = {}
    for _, models in groups:
        for model in models:
            for mesh in model.meshes:
                if mesh not in checked:
                    checked[mesh] = check(mesh)
    text = section(groups, checked, time.perf_counter() - started)
    if args.docs:
        write_section(args.out, text, BEGIN, END)
    else:
        print(text)
    bad = [(m, r) for m, c in checked.items() for r, s in c.findings if s == "error" and r in RULES]
    for mesh, rule in bad:
        print(f"error {rule}: {mesh}", file=sys.stderr)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
