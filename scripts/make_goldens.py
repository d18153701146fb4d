"""Regenerate fixtures/golden/*.mbin (format 1.0). Tests read these files and never rewrite them.

Usage: python scripts/make_goldens.py
"""

from __future__ import annotations

from pathlib import Path

from meshtool.convert import ConvertOptions, convert
from meshtool.normalise import NormaliseOptions

ROOT = Path(__file__).resolve().parent.parent / "fixtures"


def main() -> None:
    golden = ROOT / "golden"
    convert(ROOT / "head" / "Head 1.obj", golden / "head.mbin", ConvertOptions(NormaliseOptions(units="cm")))
    convert(
        ROOT / "multi_material" / "crate.obj",
        golden / "crate_quantized.mbin",
        ConvertOptions(NormaliseOptions(), quantize=True),
    )
    convert(ROOT / "features" / "features.obj", golden / "features.mbin", ConvertOptions(NormaliseOptions(up="z")))


if __name__ == "__main__":
    main()
