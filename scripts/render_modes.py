"""Render docs/images/render_<mode>.png and a side-by-side strip of the five render modes (docs/rendering.md).

Usage: MUJOCO_GL=egl python scripts/render_modes.py
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
from PIL import Image

from simrun import load_scene
from simrun.render import MODES, FrameRenderer

ROOT = Path(__file__).resolve().parent.parent


def main() -> None:
    world = load_scene(ROOT / "fixtures" / "scenes" / "head_on_table.toml")
    world.run(0.4)
    out = ROOT / "docs" / "images"
    out.mkdir(parents=True, exist_ok=True)
    tiles = []
    for mode in MODES:
        if mode == "none":
            tile = np.full((180, 240, 3), 32, dtype=np.uint8)  # nothing is drawn, no GL context is made
        else:
            renderer = FrameRenderer(world.model, 240, 180, mode, data=world.data)
            tile = renderer.render(world.data)
            renderer.close()
        buffer = io.BytesIO()
        Image.fromarray(tile).save(buffer, format="PNG")
        (out / f"render_{mode}.png").write_bytes(buffer.getvalue())
        tiles.append(tile)
    strip = io.BytesIO()
    Image.fromarray(np.concatenate(tiles, axis=1)).save(strip, format="PNG")
    (out / "render_modes.png").write_bytes(strip.getvalue())


if __name__ == "__main__":
    main()
