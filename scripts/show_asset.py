"""Print a short summary of a normalised asset folder (used by `make demo`).

Usage: python scripts/show_asset.py OUT/NAME
"""

from __future__ import annotations

import json
import sys
from pathlib import Path


def main(folder: Path) -> int:
    manifest = json.loads((folder / "asset.json").read_text())
    stats = manifest["stats"]
    print(f"asset {manifest['name']} in {folder}:")
    for path in sorted(folder.iterdir()):
        print(f"  {path.name:24s} {path.stat().st_size:8d} bytes")
    t = manifest["transform"]
    print(f"  transform: units {t['units']} (x{t['unit_scale']}), scale {t['scale']}, up {t['up']} -> metres, Z-up")
    ext = stats["bbox"]["extent"]
    size = f"{ext[0]:.4g} x {ext[1]:.4g} x {ext[2]:.4g} m"
    print(f"  size: {size}, {stats['vertices']} vertices, {stats['triangles']} triangles")
    for r in manifest["resolutions"]:
        print(f"  {r['kind']} {r['ref']!r} -> {r['found']!r} ({r['rule']})")
    for f in manifest["findings"]:
        print(f"  {f['severity']}: {f['message']} [{f['code']}]")
    return 0


if __name__ == "__main__":
    sys.exit(main(Path(sys.argv[1])))
