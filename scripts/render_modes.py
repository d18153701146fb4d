"""Render docs/images/render_<mode>.png and a side-by-side strip of the five render modes (docs/rendering.md).

Usage: python scripts/render_modes.py (headless: simrun picks EGL or OSMesa)

The scene gets a sun and a camera framing the head on the table (the fixture itself stays as it is).
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
from PIL import Image

from simrun import Camera, Light, Pose, load_scene
from simrun.run.render import MODES, FrameRenderer

ROOT = Path(__file__).resolve().parent.parent
#: Tile size, pixels.
WIDTH, HEIGHT = 240, 180


def main() -> None:
    world = load_scene(ROOT / "fixtures" / "scenes" / "head_on_table.toml")
    world.insert(Light(name="sun", pose=Pose((0.5, -0.8, 3.0)), direction=(-0.2, 0.35, -1.0), diffuse=(0.9, 0.9, 0.85)))
    world.insert(Camera(name="view", eye=(0.36, -0.5, 1.02), target=(0.0, 0.0, 0.85), fovy=40.0, main=True))
    world.run(0.4)
    out = ROOT / "docs" / "images"
    out.mkdir(parents=True, exist_ok=True)
    tiles = []
    for mode in MODES:
        if mode == "none":
            tile = np.full((HEIGHT, WIDTH, 3), 32, dtype=np.uint8)  # nothing is drawn, no GL context is made
        else:
            renderer = FrameRenderer(world.model, WIDTH, HEIGHT, mode, data=world.data)
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
