"""Write fixtures/followups/: small inputs for the follow-up tests (normal maps in exports, obj2bin's MuJoCo check).

Run from the repository root: ``python scripts/make_followup_fixtures.py``. Deterministic.
"""

from __future__ import annotations

import io
import shutil
from pathlib import Path

import numpy as np
from PIL import Image

ROOT = Path(__file__).resolve().parent.parent / "fixtures" / "followups"


def write(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(text.encode("utf-8"))


def save_png(path: Path, pixels: np.ndarray) -> None:
    buf = io.BytesIO()
    Image.fromarray(pixels.astype(np.uint8), "RGB").save(buf, format="PNG")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(buf.getvalue())


def blender_normal() -> None:
    """A 0.4 x 0.2 m panel (Z-up, one quad with UVs) whose normal map Blender wrote as ``map_Bump -bm 0.8``."""
    d = ROOT / "blender_normal"
    write(
        d / "panel.obj",
        "# Blender 4.1.1\n# www.blender.org\nmtllib panel.mtl\no Panel\n"
        "v 0 0 0\nv 0.4 0 0\nv 0.4 0.2 0\nv 0 0.2 0\n"
        "vn 0 0 1\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
        "usemtl Panel\ns 0\nf 1/1/1 2/2/1 3/3/1 4/4/1\n",
    )
    write(
        d / "panel.mtl",
        "# Blender 4.1.1 MTL File: 'None'\n# www.blender.org\n\nnewmtl Panel\nNs 250.000000\nKa 1.000 1.000 1.000\n"
        "Kd 0.800000 0.800000 0.800000\nKs 0.500000 0.500000 0.500000\nKe 0.000000 0.000000 0.000000\n"
        "Ni 1.450000\nd 1.000000\nillum 2\nmap_Kd panel_color.png\nmap_Bump -bm 0.800000 panel_normal.png\n",
    )
    y, x = np.mgrid[0:16, 0:16]
    save_png(d / "panel_color.png", np.stack([40 + 12 * x, 90 + 8 * y, np.full_like(x, 160)], axis=-1))
    # ridges along v: unit normals tilted about +-30 degrees in x, encoded c = (n + 1) / 2
    angle = np.where((x // 4) % 2 == 0, 0.5, -0.5)
    n = np.stack([np.sin(angle), np.zeros_like(angle), np.cos(angle)], axis=-1)
    save_png(d / "panel_normal.png", np.rint((n + 1.0) * 127.5))


def micro_cube() -> None:
    """A cube of 1 micrometre (metres, Z-up): converts, but MuJoCo refuses its collision hull (volume 1e-18 m^3)."""
    d = ROOT / "micro_cube"
    s = 1e-6
    lines = [
        "# a 1 um cube in metres",
        *(f"v {x * s:g} {y * s:g} {z * s:g}" for x in (0, 1) for y in (0, 1) for z in (0, 1)),
    ]
    lines += [
        f"f {' '.join(map(str, q))}"
        for q in ((1, 2, 4, 3), (5, 7, 8, 6), (1, 5, 6, 2), (3, 4, 8, 7), (1, 3, 7, 5), (2, 6, 8, 4))
    ]
    write(d / "micro.obj", "\n".join(lines) + "\n")


def main() -> None:
    shutil.rmtree(ROOT, ignore_errors=True)
    blender_normal()
    micro_cube()


if __name__ == "__main__":
    main()
