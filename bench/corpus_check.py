"""Convert every asset of a corpus manifest and write the outcome to docs/corpus.md.

Usage: python bench/corpus_check.py ../shared/corpus [--out docs/corpus.md] [--keep DIR] [--only SUBSTRING]

For each asset, in-process through the library with default options (``--up auto``, units as given):

1. normalise (``meshtool normalize``): status, findings, triangle count against the manifest's
   ``triangles_after_triangulation`` (a difference must be explained by a finding), idempotency (normalising
   the output again gives byte-identical OBJ, MTL and PNG files), textures kept against the textures the
   MTLs reference that exist on disk;
2. pack (``obj2bin``, one convex hull) and write the MJCF (``meshtool mjcf``), then compile the written
   ``NAME.xml`` with MuJoCo from its folder alone;
3. the up axis ``auto`` chose and its evidence.

The corpus keeps only the OBJ/MTL/texture files, not the MJCF/URDF/SDF files that use them (the manifest's
``units.evidence`` names each such file and the ``scale`` it applies). For every asset with such evidence a
second run rebuilds that situation in a scratch folder: the asset's files at their repository paths, and
at each named path a stand-in MJCF that references the OBJ with the recorded ``scale`` (nothing else of the
real file is known). That run uses ``--units auto``; it measures whether the orientation a consumer fixes
(MJCF, URDF and SDF are Z-up: the mesh must be kept, not rotated) is kept, and whether the unit agrees with
the manifest's ``units`` fields. The as-shipped run's unit suggestion (``scale-suspicious``) is compared too.

A crash (an exception that is not a ``MeshtoolError``) fails the script.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import sys
import tempfile
import time
import traceback
from pathlib import Path
from typing import Any

import mujoco

from meshtool import MeshtoolError, NormaliseOptions, Severity, normalise, write_asset
from meshtool.changes import changes_data
from meshtool.hulls.compute import HullOptions
from meshtool.mjcf.asset_model import build_mjcf
from meshtool.packfile import load
from meshtool.pipeline import ConvertOptions, convert

EXPLAINS_COUNT = {"degenerate-faces", "face-too-small", "part-padded"}
UNITS = ("m", "cm", "mm", "in", "ft")
Row = dict[str, Any]


def compile_mjcf(src: Path, work: Path, name: str) -> str:
    """Pack ``src`` with one convex hull, write its MJCF folder and compile the XML: 'ok' or the error."""
    packed_path = work / f"{name}.mbin"
    try:
        convert(src, packed_path, ConvertOptions(NormaliseOptions(name=name), hulls=HullOptions(cache_dir=None)))
        with load(packed_path) as packed:
            files = build_mjcf(packed, name)
    except MeshtoolError as exc:
        return f"not written: {exc.one_line()}"
    folder = work / f"{name}_mjcf"
    folder.mkdir()
    for file_name, data in files.items():
        (folder / file_name).write_bytes(data)
    xml = next(n for n in files if n.endswith(".xml"))
    try:
        mujoco.MjModel.from_xml_path(str(folder / xml))
    except ValueError as exc:
        return str(exc).splitlines()[0].removeprefix("Error: ")
    return "ok"


def expected_unit(asset: dict[str, Any]) -> str | None:
    """The unit the manifest's ``units`` fields give (``x0.1`` for a scale that is no unit), or ``None``."""
    units = asset["units"]
    guess = units.get("guess")
    if guess in UNITS:
        return str(guess)
    if guess and str(guess).split(" ")[0] in UNITS:
        return str(guess).split(" ")[0]
    if guess and str(guess).startswith("scaled x"):
        return "x" + str(guess).split(" ")[1][1:]
    if units["evidence"] and all(e["scale"] is None for e in units["evidence"]):
        return "m"
    return None


def suggested_unit(findings: list[Any]) -> str:
    """The unit the default run suggests: the one a ``scale-suspicious`` finding names, else metres."""
    for f in findings:
        if f.code == "scale-suspicious":
            match = re.search(r"--units (\w+)", f.message)
            if match:
                return match.group(1)
    return "m"


def evidence_unit(transform: dict[str, Any]) -> str | None:
    """The unit ``--units auto`` took from a consumer (``x0.1`` for a scale that is no unit)."""
    text = transform.get("units_evidence")
    if not text:
        return None
    first = str(text).split(" from ")[0]
    if first in UNITS:
        return first
    match = re.match(r"a scale of (\S+)", first)
    return f"x{match.group(1)}" if match else first


def textures_present(asset: dict[str, Any]) -> int:
    """Texture files the asset's MTLs reference that exist on disk (the manifest's ``texture`` files)."""
    return sum(1 for f in asset["files"] if f["role"] == "texture")


def run_asset(asset: dict[str, Any], corpus: Path, out_root: Path, work: Path) -> Row:
    src = corpus / asset["obj"]
    expected = asset["stats"].get("triangles_after_triangulation")
    row: Row = {"id": asset["id"], "expected": expected, "present": textures_present(asset)}
    start = time.perf_counter()
    try:
        result = normalise(src, NormaliseOptions(name=asset["id"]))
        folder = write_asset(result, out_root, src)
    except MeshtoolError as exc:
        row.update(status="rejected", detail=exc.one_line())
    except Exception as exc:
        row.update(status="crash", detail=f"{type(exc).__name__}: {exc}")
        traceback.print_exc()
    else:
        warn = sorted({f.code for f in result.findings if f.severity is not Severity.INFO})
        changed = sorted({f.code for f in result.findings if f.severity is Severity.INFO and changes_data(f)})
        triangles = result.stats["triangles"]
        transform = result.manifest["transform"]
        row.update(
            status="ok-with-findings" if warn else "ok",
            triangles=triangles,
            detail=", ".join(warn + [f"({c})" for c in changed]),
            up=transform["up"],
            up_rule=transform["up_rule"],
            up_evidence=transform["up_evidence"],
            suggested=suggested_unit(result.findings),
            kept=sum(1 for s in result.manifest["sources"] if s["role"] == "texture"),
            texture_notes=[f.one_line() for f in result.findings if f.code.startswith(("texture-", "reference-"))],
        )
        again = normalise(folder / f"{result.name}.obj", NormaliseOptions(name=result.name))
        row["idempotent"] = all(again.files.get(n) == data for n, data in result.files.items() if n != "asset.json")
        codes = {f.code for f in result.findings}
        if expected is not None and triangles != expected and not (codes & EXPLAINS_COUNT):
            row["mismatch"] = True
        row["mujoco"] = compile_mjcf(src, work, result.name)
    row["seconds"] = round(time.perf_counter() - start, 3)
    return row


def run_with_consumers(asset: dict[str, Any], corpus: Path, work: Path) -> Row | None:
    """Rebuild the asset with stand-in consumer files at the manifest's paths; normalise with --units auto."""
    evidence = asset["units"]["evidence"]
    if not evidence:
        return None
    tree = work / f"{asset['id']}_tree"
    for f in asset["files"]:
        target = tree / f["repo_path"]
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(corpus / f["corpus_path"], target)
    obj = tree / asset["source"]["path"]
    by_file: dict[str, list[str | None]] = {}
    for e in evidence:
        by_file.setdefault(e["file"], []).append(e["scale"])
    for file, scales in by_file.items():
        consumer = tree / file
        consumer.parent.mkdir(parents=True, exist_ok=True)
        rel = os.path.relpath(obj, consumer.parent)
        meshes = "".join(
            f'<mesh name="m{k}" file="{rel}"' + (f' scale="{s}"' if s else "") + "/>" for k, s in enumerate(scales)
        )
        consumer.write_text(f'<mujoco model="stand-in"><asset>{meshes}</asset></mujoco>\n')
    row: Row = {
        "id": asset["id"],
        "consumers": ", ".join(f"{f} ({' / '.join(map(str, s))})" for f, s in by_file.items()),
    }
    try:
        result = normalise(obj, NormaliseOptions(name=asset["id"], units="auto"))
    except MeshtoolError as exc:
        row.update(status="rejected", detail=exc.one_line())
        return row
    transform = result.manifest["transform"]
    row.update(
        status="ok",
        up=transform["up"],
        up_rule=transform["up_rule"],
        unit=evidence_unit(transform) or transform["units"],
        applied=f"{transform['units']} x{transform['scale']:g}",
        note=transform["units_evidence"],
    )
    return row


def check(corpus: Path, keep: Path | None, only: str | None) -> tuple[list[Row], list[Row], dict[str, Any]]:
    manifest = json.loads((corpus / "manifest.json").read_text())
    assets = [a for a in manifest["assets"] if only is None or only in a["id"]]
    out_root = keep or Path(tempfile.mkdtemp(prefix="corpus-"))
    rows: list[Row] = []
    consumer_rows: list[Row] = []
    with tempfile.TemporaryDirectory(prefix="corpus-work-") as scratch:
        work = Path(scratch)
        for asset in assets:
            row = run_asset(asset, corpus, out_root, work)
            row["expected_unit"] = expected_unit(asset)
            rows.append(row)
            with_consumer = run_with_consumers(asset, corpus, work)
            if with_consumer is not None:
                with_consumer["expected_unit"] = row["expected_unit"]
                with_consumer["shipped_up"] = f"{row.get('up', '-')} ({row.get('up_rule', '-')})"
                with_consumer["shipped_unit"] = row.get("suggested", "-")
                consumer_rows.append(with_consumer)
            print(f"{row['id']}: {row['status']} {row.get('mujoco', '')}", file=sys.stderr)
    return rows, consumer_rows, totals(rows, consumer_rows)


def totals(rows: list[Row], consumer_rows: list[Row]) -> dict[str, Any]:
    converted = [r for r in rows if r["status"] in ("ok", "ok-with-findings")]
    with_unit = [r for r in consumer_rows if r.get("expected_unit") is not None]
    return {
        "assets": len(rows),
        "converted": len(converted),
        "ok": sum(r["status"] == "ok" for r in rows),
        "ok-with-findings": sum(r["status"] == "ok-with-findings" for r in rows),
        "rejected": sum(r["status"] == "rejected" for r in rows),
        "crash": sum(r["status"] == "crash" for r in rows),
        "count-mismatch": sum(bool(r.get("mismatch")) for r in rows),
        "idempotent": sum(bool(r.get("idempotent")) for r in rows),
        "mjcf-compiles": sum(r.get("mujoco") == "ok" for r in converted),
        "consumer-assets": len(consumer_rows),
        "orientation-kept (stand-in consumer)": sum(r.get("up") == "z" for r in consumer_rows),
        "orientation-kept (as shipped)": sum(r["shipped_up"].startswith("z") for r in consumer_rows),
        "unit-fields": len(with_unit),
        "unit-agrees (stand-in consumer, --units auto)": sum(r.get("unit") == r["expected_unit"] for r in with_unit),
        "unit-agrees (as shipped, suggestion)": sum(r["shipped_unit"] == r["expected_unit"] for r in with_unit),
        "textures-present": sum(r["present"] for r in rows),
        "textures-kept": sum(min(r.get("kept", 0), r["present"]) for r in rows),
    }


def exceptions(rows: list[Row], consumer_rows: list[Row]) -> list[str]:
    """One bullet per kind of exception, with the assets and the reason."""
    out = []
    rejected = [r for r in rows if r["status"] == "rejected"]
    if rejected:
        out.append(
            f"- {len(rejected)} rejected, each with a one-line error naming file and line (corrupt or empty input "
            f"the test suites of tinyobjloader/trimesh ship on purpose): {', '.join(r['id'] for r in rejected)}."
        )
    shipped: dict[str, list[str]] = {}
    for r in consumer_rows:
        shipped.setdefault(r["shipped_up"], []).append(r["id"])
    kept = sum(len(ids) for up, ids in shipped.items() if up.startswith("z"))
    out.append(
        f"- Orientation as shipped: {kept} of {len(consumer_rows)} meshes that a consumer file uses come out "
        "unrotated without that file. The corpus holds only the meshes, so the evidence `--up auto` uses for "
        "them (the consumer file beside the mesh or up to its model root) is not there; what it decided "
        "instead: " + "; ".join(f"{up}: {len(ids)}" for up, ids in sorted(shipped.items())) + ". With the "
        "consumer file at its path (stand-in), every one is kept."
    )
    for r in consumer_rows:
        if r.get("expected_unit") is not None and r.get("unit") != r["expected_unit"]:
            out.append(
                f"- Units of {r['id']}: `--units auto` read {r.get('unit')} ({r.get('note')}), the manifest says "
                f"{r['expected_unit']}: the consumer files disagree ({r['consumers']}); meshtool takes the first "
                "file in the nearest folder, the manifest's guess the one with a scale."
            )
    wrong = [r for r in consumer_rows if r.get("expected_unit") is not None and r["shipped_unit"] != r["expected_unit"]]
    out.append(
        f"- Units as shipped: the size-based suggestion matches the manifest for "
        f"{len([r for r in consumer_rows if r.get('expected_unit') is not None]) - len(wrong)} of "
        f"{len([r for r in consumer_rows if r.get('expected_unit') is not None])}; without a consumer file the "
        f"only evidence is the size (wrong for {', '.join(r['id'] for r in wrong) or 'none'})."
    )
    lost = [r for r in rows if r.get("kept", 0) < r["present"]]
    out.append(
        "- Textures present on disk but not kept: " + (", ".join(r["id"] for r in lost) if lost else "none") + "."
    )
    failed = [r for r in rows if r["status"] in ("ok", "ok-with-findings") and r.get("mujoco") != "ok"]
    out.append("- Written MJCF that MuJoCo refuses: " + (", ".join(r["id"] for r in failed) or "none") + ".")
    return out


def _cell(value: object) -> str:
    return str(value).replace("|", "\\|").replace("\n", " ")


def render(rows: list[Row], consumer_rows: list[Row], total: dict[str, Any], corpus: Path) -> str:
    converted = [r for r in rows if r["status"] in ("ok", "ok-with-findings")]
    lines = [
        "# Corpus check",
        "",
        f"Generated by `python bench/corpus_check.py ../shared/corpus` (MuJoCo {mujoco.__version__}); do not edit.",
        f"Every asset of `{corpus.name}/manifest.json` converted with default options (`--up auto`).",
        "See the script's docstring for what each column measures; *stand-in consumer*: the corpus does not",
        "ship the MJCF/URDF/SDF files that use its meshes, so the check writes, at each path the manifest's",
        "`units.evidence` names, a stand-in MJCF referencing the OBJ with the recorded `scale`, and converts",
        "with `--units auto`.",
        "",
        "| totals | count |",
        "|---|---|",
        *[f"| {k} | {v} |" for k, v in total.items()],
        "",
        "## Exceptions and why",
        "",
        *exceptions(rows, consumer_rows),
        "",
        "## MuJoCo compiles the written MJCF",
        "",
        f"{total['mjcf-compiles']} of {total['converted']} converted assets (obj2bin with one convex hull, then",
        "`meshtool mjcf`, then `mujoco.MjModel.from_xml_path` on the written XML). Exceptions:",
        "",
        "| asset | MuJoCo says |",
        "|---|---|",
        *[f"| {r['id']} | {_cell(r.get('mujoco'))} |" for r in converted if r.get("mujoco") != "ok"],
        "",
        "## Orientation where a consumer file fixes it",
        "",
        "MJCF, URDF and SDF are Z-up and use mesh coordinates unrotated, so each of these meshes must be kept as",
        "it is (`up z`). *as shipped*: the corpus folder alone (no consumer file present); *stand-in consumer*:",
        "with the consumer file at its path.",
        "",
        "| asset | consumer (scale) | as shipped: up (rule) | stand-in consumer: up (rule) |",
        "|---|---|---|---|",
        *[
            f"| {r['id']} | {_cell(r['consumers'])} | {r['shipped_up']} | "
            f"{r.get('up', '-')} ({r.get('up_rule', '-')}) |"
            for r in consumer_rows
        ],
        "",
        "## Units against the manifest's `units` fields",
        "",
        "*expected*: the manifest's `units.guess` (a unit, or `xN` for a consumer scale that is no unit), or `m`",
        "when every consumer file gives no scale. *as shipped*: the unit the default run suggests (the",
        "`scale-suspicious` finding, else m); *auto*: what `--units auto` read from the stand-in consumer.",
        "",
        "| asset | expected | as shipped | auto | applied | evidence |",
        "|---|---|---|---|---|---|",
        *[
            f"| {r['id']} | {r['expected_unit']} | {r['shipped_unit']} | {r.get('unit', '-')}"
            f"{'' if r.get('unit') == r['expected_unit'] else ' DIFFERS'} | {r.get('applied', '-')} | "
            f"{_cell(r.get('note'))} |"
            for r in consumer_rows
            if r.get("expected_unit") is not None
        ],
        "",
        "## What `--up auto` decided for the other assets",
        "",
        "| asset | up | rule | evidence |",
        "|---|---|---|---|",
    ]
    consumer_ids = {r["id"] for r in consumer_rows}
    lines += [
        f"| {r['id']} | {r['up']} | {r['up_rule']} | {_cell(r['up_evidence'])} |"
        for r in converted
        if r["id"] not in consumer_ids
    ]
    lines += [
        "",
        "## Textures kept against textures present on disk",
        "",
        f"{total['textures-kept']} of {total['textures-present']} texture files that an MTL references and that",
        "exist on disk are in the output. References to files that do not exist are listed per asset",
        "(`texture-missing`) in the table below.",
        "",
        "| asset | present | kept | notes |",
        "|---|---|---|---|",
        *[
            f"| {r['id']} | {r['present']} | {r.get('kept', 0)} | {_cell('; '.join(r.get('texture_notes', [])))} |"
            for r in rows
            if r["present"] or r.get("kept") or r.get("texture_notes")
        ],
        "",
        "## Every asset",
        "",
        "*ok*: converted without warnings; *ok-with-findings*: the warning codes listed, then (in parentheses)",
        "info codes that changed or dropped data; *rejected*: refused with the one-line reason shown.",
        "",
        "| asset | status | triangles (manifest) | MJCF compiles | idempotent | up (rule) | seconds "
        "| findings / reason |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        tri = f"{r.get('triangles', '-')} ({r['expected']})" + (" MISMATCH" if r.get("mismatch") else "")
        same = {True: "yes", False: "NO"}.get(r.get("idempotent"), "-")  # type: ignore[arg-type]
        up = f"{r['up']} ({r['up_rule']})" if "up" in r else "-"
        lines.append(
            f"| {r['id']} | {r['status']} | {tri} | {_cell(r.get('mujoco', '-'))} | {same} | {up} | {r['seconds']} | "
            f"{_cell(r.get('detail', ''))} |"
        )
    return "\n".join(lines) + "\n"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("corpus", type=Path)
    parser.add_argument("--out", type=Path, default=Path("docs/corpus.md"))
    parser.add_argument("--keep", type=Path, default=None, help="write the normalised assets here")
    parser.add_argument("--only", default=None, help="only assets whose id contains this text")
    args = parser.parse_args()
    rows, consumer_rows, total = check(args.corpus, args.keep, args.only)
    old = args.out.read_text() if args.out.exists() else ""  # keep bench/formats_check.py's, consumers_check.py's
    kept = [m.group(0) for m in re.finditer(r"<!-- (\w+):begin -->.*?<!-- \1:end -->", old, re.S)]
    args.out.write_text(render(rows, consumer_rows, total, args.corpus) + "".join(f"\n{k}\n" for k in kept))
    print(" ".join(f"{k}={v}" for k, v in total.items()))
    return 1 if total["crash"] or total["count-mismatch"] or total["idempotent"] != total["converted"] else 0


if __name__ == "__main__":
    sys.exit(main())
