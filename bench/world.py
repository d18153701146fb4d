"""World-building benchmark: 50 textured .mbin meshes through simrun vs the same world as MJCF + OBJ files.

Usage: python bench/world.py ../shared/corpus [--repeat 5] [--out docs/benchmarks.md]

The asset is the corpus's textured fuze (1,000 triangles, a 1024 x 1024 texture), normalised and packed,
then copied to 50 distinct files per format. Contenders run interleaved, --repeat rounds, each round on
fresh file copies so that no cold contender profits from a cache (MuJoCo caches meshes by file name):

* MuJoCo: ``MjModel.from_xml_path`` of an MJCF naming 50 OBJ meshes and 50 PNG textures (the baseline);
* simrun cold: ``World`` with 50 ``MeshEntity`` (arrays and PNG bytes into the spec from memory; identical
  images are decoded once) built and compiled, no model cache;
* simrun second load: the same world built again from the same files with the compiled-model cache
  (simrun/model_cache.py) filled by the first load: the model comes from its MJB entry.

A second pair uses 50 *different* textures (one pixel changed per copy), where every image must be decoded
on a cold load by both. Wall-clock and process CPU time (all threads) are reported as min / median.
"""

from __future__ import annotations

import io
import platform
import sys
import tempfile
import time
from pathlib import Path

import mujoco
import numpy as np
from _report import Timing, arguments, interleave, load_average, write_section
from PIL import Image

from meshtool import NormaliseOptions, normalise, normalise_to
from meshtool.convert import ConvertOptions, convert
from meshtool.hulls import HullOptions, compute_hulls
from meshtool.packfile import pack
from simrun import MeshEntity, Pose, World
from simrun.model_cache import ModelCache

COUNT = 50
BEGIN, END = "<!-- world:begin -->", "<!-- world:end -->"
FUZE = "src/mikedh__trimesh/models/fuze.obj"


def prepare(src: Path, work: Path) -> tuple[Path, Path]:
    """One normalised OBJ folder and one .mbin of the asset."""
    folder, _ = normalise_to(src, work / "obj", NormaliseOptions())
    mbin = work / "asset.mbin"
    convert(src, mbin, ConvertOptions(NormaliseOptions()))
    return folder, mbin


def distinct_assets(src: Path, work: Path) -> tuple[list[bytes], list[bytes]]:
    """50 .mbin files' bytes and 50 PNGs, each texture one pixel different from the others."""
    asset = normalise(src, NormaliseOptions())
    hulls = compute_hulls(asset.mesh, HullOptions())
    (name, png) = next(iter(asset.textures.items()))
    image = np.array(Image.open(io.BytesIO(png)))
    mbins, pngs = [], []
    for k in range(COUNT):
        pixels = image.copy()
        pixels[0, k] = (pixels[0, k].astype(np.int32) + 1 + k) % 256
        out = io.BytesIO()
        Image.fromarray(pixels).save(out, format="PNG")
        pngs.append(out.getvalue())
        asset.textures[name] = pngs[-1]
        mbins.append(pack(asset, hulls=hulls.hulls))
    return mbins, pngs


def simrun_world(files: list[bytes], run: Path, cache: ModelCache | None) -> World:
    world = World(base_dir=run)
    world.model_cache = cache
    for k in range(COUNT):
        world.insert(MeshEntity(name=f"m{k}", asset=f"a{k}.mbin", pose=Pose((0.3 * (k % 10), 0.3 * (k // 10), 0.2))))
    world.compile()
    return world


def write_mbins(files: list[bytes], run: Path) -> None:
    run.mkdir(parents=True, exist_ok=True)
    for k, data in enumerate(files):
        (run / f"a{k}.mbin").write_bytes(data)


def write_mjcf(obj: bytes, pngs: list[bytes], run: Path) -> Path:
    run.mkdir(parents=True, exist_ok=True)
    assets, bodies = [], []
    for k in range(COUNT):
        (run / f"m{k}.obj").write_bytes(obj)
        (run / f"t{k}.png").write_bytes(pngs[k])
        assets.append(
            f'<mesh name="m{k}" file="m{k}.obj"/><texture name="t{k}" type="2d" file="t{k}.png"/>'
            f'<material name="mat{k}" texture="t{k}"/>'
        )
        bodies.append(
            f'<body pos="{0.3 * (k % 10)} {0.3 * (k // 10)} 0.2"><geom type="mesh" mesh="m{k}" material="mat{k}"/>'
            "</body>"
        )
    xml = run / "world.xml"
    xml.write_text(f"<mujoco><asset>{''.join(assets)}</asset><worldbody>{''.join(bodies)}</worldbody></mujoco>")
    return xml


class Rounds:
    """Contenders that prepare fresh files outside the timed part; each returns (wall, CPU)."""

    def __init__(self, work: Path, mbins: list[bytes], obj: bytes, pngs: list[bytes], tag: str) -> None:
        self.work, self.mbins, self.obj, self.pngs, self.tag = work, mbins, obj, pngs, tag
        self.round = 0
        self.cache = ModelCache(work / f"cache-{tag}")
        self.warm = work / f"warm-{tag}"
        write_mbins(mbins, self.warm)
        simrun_world(mbins, self.warm, self.cache)  # fills the model cache

    def _timed(self, fn: object) -> tuple[float, float]:
        cpu, wall = time.process_time(), time.perf_counter()
        fn()  # type: ignore[operator]
        return time.perf_counter() - wall, time.process_time() - cpu

    def mjcf(self) -> tuple[float, float]:
        self.round += 1
        xml = write_mjcf(self.obj, self.pngs, self.work / f"{self.tag}-m{self.round}")
        return self._timed(lambda: mujoco.MjModel.from_xml_path(str(xml)))

    def cold(self) -> tuple[float, float]:
        run = self.work / f"{self.tag}-s{self.round}"
        write_mbins(self.mbins, run)
        return self._timed(lambda: simrun_world(self.mbins, run, None))

    def second(self) -> tuple[float, float]:
        before = self.cache.hits
        result = self._timed(lambda: simrun_world(self.mbins, self.warm, self.cache))
        assert self.cache.hits == before + 1, "the second load did not come from the model cache"
        return result


def main() -> int:
    args = arguments(__doc__, 5)
    src = args.corpus / FUZE
    if not src.exists():
        print(f"skip: {src} not found", file=sys.stderr)
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        folder, mbin = prepare(src, work)
        obj = next(folder.glob("*.obj"))
        png = next(folder.glob("*.png")).read_bytes()
        same = Rounds(work, [mbin.read_bytes()] * COUNT, obj.read_bytes(), [png] * COUNT, "same")
        mbins, pngs = distinct_assets(src, work)
        different = Rounds(work, mbins, obj.read_bytes(), pngs, "distinct")
        results = interleave(
            {
                "mjcf": same.mjcf,
                "cold": same.cold,
                "second": same.second,
                "mjcf distinct": different.mjcf,
                "cold distinct": different.cold,
                "second distinct": different.second,
            },
            args.repeat,
        )
    write_section(args.out, table(results, args.repeat), BEGIN, END)
    for name, t in results.items():
        print(f"{name}: wall {t.wall_min:.4f}/{t.wall_median:.4f} s, cpu {t.cpu_min:.4f}/{t.cpu_median:.4f} s")
    return 0


def table(r: dict[str, Timing], repeat: int) -> str:
    def row(label: str, key: str, base: str) -> str:
        t, b = r[key], r[base]
        return (
            f"| {label} | {t.wall_min:.4f} / {t.wall_median:.4f} | {t.cpu_min:.4f} / {t.cpu_median:.4f} | "
            f"{b.wall_median / t.wall_median:.1f}x | {b.cpu_median / t.cpu_median:.1f}x |"
        )

    return "\n".join(
        [
            BEGIN,
            "## World building: 50 textured meshes",
            "",
            f"`python bench/world.py ../shared/corpus --repeat {repeat}` (part of `make bench`): contenders "
            f"interleaved, {repeat} rounds, fresh file copies for every cold load (no MuJoCo mesh cache). Seconds "
            "as min / median of wall-clock and of process CPU (all threads); speed-ups are MuJoCo's median over "
            f"the row's median. Machine: {platform.machine()}, CPython {platform.python_version()}, MuJoCo "
            f"{mujoco.__version__}, numpy {np.__version__}; {load_average()} at the end of the run.",
            "",
            "| world (50 fuze meshes, 1,000 triangles, 1024 x 1024 texture each) | wall min / median s | "
            "CPU min / median s | speed-up (wall) | speed-up (CPU) |",
            "|---|---|---|---|---|",
            row("MuJoCo: MJCF with 50 OBJ meshes + 50 PNG textures (the same image)", "mjcf", "mjcf"),
            row("simrun cold: 50 MeshEntity from .mbin, no model cache", "cold", "mjcf"),
            row("simrun second load: the same scene again, compiled-model cache", "second", "mjcf"),
            row("MuJoCo: MJCF, 50 different textures", "mjcf distinct", "mjcf distinct"),
            row("simrun cold, 50 different textures", "cold distinct", "mjcf distinct"),
            row("simrun second load, 50 different textures", "second distinct", "mjcf distinct"),
            "",
            "Goals (issue 17): cold >= 5x MuJoCo, second load >= 50x. simrun hands MuJoCo each distinct image "
            "once (the 50 copies of one texture are decoded once; MuJoCo's MJCF loader decodes every file); with "
            "50 different images both decode all of them, about 2.4 ms each, which bounds the cold ratio. The "
            "second load reads the model MuJoCo compiled the first time (MJB), after checking the XXH3 hash of "
            "every file the world read; `tests/test_model_cache.py` checks that a cached model is byte for byte "
            "the compiled one and that any change of a file, an entity or an option recompiles.",
            END,
        ]
    )


if __name__ == "__main__":
    sys.exit(main())
