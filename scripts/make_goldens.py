"""Reproduce fixtures/golden/*.mbin byte for byte, or check that they still reproduce.

Usage: python scripts/make_goldens.py [--check]

* Format 1.1 goldens (``*-1.1.mbin``): converted from the fixtures with pinned options by the current
  writer (``meshtool.pipeline``), exactly as ``obj2bin`` writes them.
* Format 1.0 goldens (``head.mbin``, ``crate_quantized.mbin``, ``features.mbin``, ``head_plain_meta.mbin``):
  written by meshtool 0.1.0 at the time (its normaliser has changed since, so their content cannot come from
  today's converter). The script re-assembles each from its stored sections with the writer's 1.0 container
  (header, table, CRC-32 checksums, padding): the result must equal the committed bytes, which shows that
  the writer still writes format 1.0 exactly and that nothing in a 1.0 file lies outside the container
  rules.

With ``--check`` nothing is written; the exit status is 1 when a golden does not reproduce. Tests never
rewrite goldens (tests/test_golden.py pins their SHA-256).
"""

from __future__ import annotations

import sys
from pathlib import Path

from meshtool.packfile import format as fmt
from meshtool.packfile import load
from meshtool.packfile.write import StoredSection, assemble
from meshtool.pipeline import ConvertOptions, convert
from meshtool.repair.normalise import NormaliseOptions

ROOT = Path(__file__).resolve().parent.parent / "fixtures"
GOLDEN = ROOT / "golden"

#: 1.1 goldens: (file, source OBJ, options).
CONVERTED = [
    ("head-1.1.mbin", ROOT / "head" / "Head 1.obj", ConvertOptions(NormaliseOptions(units="cm"))),
    ("crate_quantized-1.1.mbin", ROOT / "multi_material" / "crate.obj", ConvertOptions(quantize=True)),
    ("features-1.1.mbin", ROOT / "features" / "features.obj", ConvertOptions(NormaliseOptions(up="z"))),
]
#: 1.0 goldens, re-assembled from their own sections.
REASSEMBLED = ["head.mbin", "head_plain_meta.mbin", "crate_quantized.mbin", "features.mbin"]


def reassemble(path: Path) -> bytes:
    """The file rebuilt from its stored sections by the writer's container for the file's own version."""
    with load(path, verify=True) as packed:
        data = path.read_bytes()
        sections = [
            StoredSection(
                kind=s.kind.encode(),
                code=fmt.CODES[s.dtype],
                shape=(s.shape[0], s.shape[1] if len(s.shape) == 2 else 0),
                ndim=len(s.shape),
                data=data[s.offset : s.offset + s.length],
                encoding=s.encoding,
                index=s.index,
            )
            for s in packed.sections
        ]
        flags = fmt.FLAG_QUANTIZED if packed.quantized else 0
        return assemble(sections, flags, minor=packed.version[1])


def converted(name: str, src: Path, options: ConvertOptions, scratch: Path) -> bytes:
    out = scratch / name
    convert(src, out, options, force=True)
    return out.read_bytes()


def main(argv: list[str]) -> int:
    import tempfile

    check = "--check" in argv
    failed = []
    with tempfile.TemporaryDirectory() as tmp:
        made = {name: converted(name, src, options, Path(tmp)) for name, src, options in CONVERTED}
    made.update({name: reassemble(GOLDEN / name) for name in REASSEMBLED})
    for name, data in made.items():
        target = GOLDEN / name
        same = target.exists() and target.read_bytes() == data
        if check or name in REASSEMBLED:  # 1.0 files are never rewritten
            print(f"{'ok' if same else 'DIFFERS'}: {target}")
            if not same:
                failed.append(name)
        elif not same:
            target.write_bytes(data)
            print(f"wrote {target} ({len(data)} bytes)")
        else:
            print(f"unchanged: {target}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
