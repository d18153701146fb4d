"""Regenerate fixtures/validate/: one asset per ``meshtool validate`` rule, plus clean assets.

Every folder ``fixtures/validate/<rule-id>_<name>/`` holds one asset that must trigger exactly that rule
(tests/test_validate_rules.py), ``clean*/`` ones must trigger none. Shapes are metres, Z-up (``up`` is
given in the OBJ header comment for readers; the validator reads OBJ as Y-up, so files are written Y-up).

Usage: python scripts/make_validate_fixtures.py (also run by make_fixtures.py)
"""

from __future__ import annotations

import io
import shutil
import struct
from pathlib import Path

import numpy as np
from PIL import Image

from meshtool.hulls.compute import HullOptions, compute_hulls
from meshtool.packfile import pack, parse
from meshtool.pipeline import ConvertOptions, convert
from meshtool.repair.normalise import prepare

ROOT = Path(__file__).resolve().parent.parent / "fixtures" / "validate"


def box(size=(0.2, 0.15, 0.1), centre=(0.0, 0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """A closed box, faces counter-clockwise seen from outside (Z-up coordinates)."""
    s, c = np.asarray(size) / 2, np.asarray(centre)
    v = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float) * s + c
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    faces = [f for a, b, cc, d in quads for f in ((a, b, cc), (a, cc, d))]
    return v, np.array(faces)


def prism(polygon: list[tuple[float, float]], caps: list[tuple[int, int, int]], height: float):
    """A closed prism of a counter-clockwise polygon; ``caps`` triangulates it (indices into polygon)."""
    n = len(polygon)
    v = np.array([(x, y, 0.0) for x, y in polygon] + [(x, y, height) for x, y in polygon])
    faces = [(c, b, a) for a, b, c in caps] + [(a + n, b + n, c + n) for a, b, c in caps]
    for k in range(n):
        j = (k + 1) % n
        faces += [(k, j, j + n), (k, j + n, k + n)]
    return v, np.array(faces)


def icosphere(radius: float, subdivisions: int):
    import trimesh

    m = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    return np.asarray(m.vertices), np.asarray(m.faces)


def obj_text(v, faces, header="", extra="", nan_vertex=None, usemtl=None, mtllib=None, uv=False) -> str:
    """OBJ text; Z-up coordinates written Y-up (x, z, -y) as the OBJ convention expects."""
    lines = [f"# meshtool validate fixture{': ' + header if header else ''}"]
    if mtllib:
        lines.append(f"mtllib {mtllib}")
    for k, (x, y, z) in enumerate(v):
        if k == nan_vertex:
            lines.append("v nan 0 0")
        else:
            lines.append(f"v {x:.6g} {z:.6g} {-y + 0.0:.6g}")
    if uv:
        lines += ["vt 0 0", "vt 1 0", "vt 1 1"]
    if usemtl:
        lines.append(f"usemtl {usemtl}")
    lines += extra.splitlines()
    for a, b, c in faces:
        if uv:
            lines.append(f"f {a + 1}/1 {b + 1}/2 {c + 1}/3")
        else:
            lines.append(f"f {a + 1} {b + 1} {c + 1}")
    return "\n".join(lines) + "\n"


def png(size: int = 8) -> bytes:
    y, x = np.mgrid[0:size, 0:size]
    rgb = np.stack([x * 255 // (size - 1), y * 255 // (size - 1), np.full_like(x, 128)], axis=2).astype(np.uint8)
    buf = io.BytesIO()
    Image.fromarray(rgb, "RGB").save(buf, format="PNG")
    return buf.getvalue()


def jpeg() -> bytes:
    buf = io.BytesIO()
    Image.open(io.BytesIO(png())).save(buf, format="JPEG", quality=90)
    return buf.getvalue()


def put(rel: str, data: str | bytes) -> Path:
    path = ROOT / rel
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(data.encode("utf-8") if isinstance(data, str) else data)
    return path


def textured_box(folder: str, map_line: str, files: dict[str, bytes], name: str = "box") -> None:
    """A box with one material whose map_Kd line is ``map_line``, plus ``files`` (relative paths)."""
    v, f = box()
    put(f"{folder}/{name}.obj", obj_text(v, f, mtllib=f"{name}.mtl", usemtl="paint", uv=True))
    put(f"{folder}/{name}.mtl", f"newmtl paint\nKd 0.8 0.8 0.8\n{map_line}\n")
    for rel, data in files.items():
        put(f"{folder}/{rel}", data)


def packed(folder: str, obj_rel: str, hulls: HullOptions, name: str = "box") -> Path:
    out = ROOT / folder / f"{name}.mbin"
    convert(ROOT / obj_rel, out, ConvertOptions(hulls=hulls))
    return out


def main() -> None:
    shutil.rmtree(ROOT, ignore_errors=True)
    ROOT.mkdir(parents=True)
    v, f = box()

    # clean: a textured box and its pack beside it (not stale, one convex hull)
    textured_box("clean", "map_Kd box.png", {"box.png": png()})
    packed("clean", "clean/box.obj", HullOptions(mode="convex"))

    # source
    put("S001_obj_unreadable/box.obj", obj_text(v, f).replace("f 1 2 4\n", "f 1 2 40\n"))
    put("S002_mtl_missing/box.obj", obj_text(v, f, mtllib="gone.mtl"))
    textured_box("S003_texture_missing", "map_Kd missing.png", {})
    vb, fb = box()
    put("S004_material_undefined/box.obj", obj_text(vb, fb, mtllib="box.mtl", usemtl="steel"))
    put("S004_material_undefined/box.mtl", "newmtl paint\nKd 0.8 0.2 0.2\n")
    textured_box("S005_texture_format", "map_Kd box.jpg", {"box.jpg": jpeg()})
    textured_box("S006_path_absolute", r"map_Kd C:\Users\designer\Desktop\crate\box.png", {"box.png": png()})
    textured_box("S007_path_foreign", r"map_Kd textures\box.png", {"textures/box.png": png()})
    textured_box("S008_path_outside", "map_Kd ../outside.png", {})
    put("outside.png", png())  # exists, but outside the S008 asset's folder
    put("S009_name_unsafe/my box.obj", obj_text(v, f))
    put("S010_encoding/box.obj", b"\xef\xbb\xbf" + obj_text(v, f).encode("utf-8"))
    put("S011_syntax/box.obj", obj_text(v, f, extra="frobnicate 1 2 3"))
    # S014: two MJCF models use the box at different scales (each scale is a plausible size)
    put("S014_consumer_frames_differ/box.obj", obj_text(v, f))
    for model, scale in (("small", "1 1 1"), ("large", "2 2 2")):
        mjcf = f'<mujoco model="{model}"><asset><mesh name="box" file="box.obj" scale="{scale}"/></asset>'
        body = '<worldbody><geom type="mesh" mesh="box"/></worldbody></mujoco>\n'
        put(f"S014_consumer_frames_differ/{model}.xml", mjcf + body)

    # geometry
    put("G001_non_finite/box.obj", obj_text(v, f, nan_vertex=7))
    put("G002_no_faces/points.obj", obj_text(v, np.zeros((0, 3), int)))
    put("G003_degenerate_faces/box.obj", obj_text(v, np.vstack([f, [[0, 1, 1]]])))
    put("G004_duplicate_faces/box.obj", obj_text(v, np.vstack([f, f[:1]])))
    flipped = f.copy()
    flipped[0:2] = flipped[0:2, ::-1]  # one side of the box wound the other way
    put("G005_winding_inconsistent/box.obj", obj_text(v, flipped))
    put("G006_inside_out/box.obj", obj_text(v, f[:, ::-1]))
    put("G007_open_mesh/box.obj", obj_text(v, f[2:]))  # the bottom side missing
    va, fa = box((0.1, 0.1, 0.1), (0.0, 0.0, 0.0))
    vb2, fb2 = box((0.1, 0.1, 0.1), (0.1, 0.1, 0.0))  # shares one vertical edge with the first box
    both = np.vstack([va, vb2])
    merged_faces = np.vstack([fa, fb2 + 8])
    put("G008_non_manifold/boxes.obj", obj_text(both, merged_faces))
    square = np.array([[0, 0, 0], [0.2, 0, 0], [0.2, 0.2, 0], [0, 0.2, 0]], dtype=float)
    sheet = np.array([[0, 1, 2], [0, 2, 3], [1, 0, 3], [1, 3, 2]])  # both sides: closed, no volume
    put("G009_coplanar/sheet.obj", obj_text(square, sheet))
    vt, ft = box((0.05, 0.05, 0.0000003))  # 0.3 um foil: 7.5e-13 m^3
    put("G010_tiny_volume/foil.obj", obj_text(vt, ft))
    vs, fs = icosphere(0.05, 2)  # 162 vertices; the rule test sets limits.max-vertices = 100
    put("G011_vertex_count/ball.obj", obj_text(vs, fs))

    # scale
    vu, fu = box((12.0, 9.0, 6.0))
    put("U001_scale_implausible/container.obj", obj_text(vu, fu))

    # collision
    parts = []
    for k in range(40):  # 40 separate 1 cm cubes: 40 hulls in "objects" mode
        vk, fk = box((0.01, 0.01, 0.01), (0.02 * (k % 8), 0.02 * (k // 8), 0.0))
        parts.append((vk, fk))
    lines = ["# meshtool validate fixture: 40 parts"]
    for vk, _ in parts:
        lines += [f"v {x:.6g} {z:.6g} {-y + 0.0:.6g}" for x, y, z in vk]
    for k, (_, fk) in enumerate(parts):
        lines.append(f"o cube{k}")
        lines += [f"f {a + 1 + 8 * k} {b + 1 + 8 * k} {c + 1 + 8 * k}" for a, b, c in fk]
    put("_sources/cubes.obj", "\n".join(lines) + "\n")
    packed("C001_hull_count", "_sources/cubes.obj", HullOptions(mode="objects"), "cubes")
    put("_sources/ball.obj", obj_text(vs, fs))
    packed("C002_hull_vertices", "_sources/ball.obj", HullOptions(mode="convex", max_hull_vertices=200), "ball")
    ell = [(0, 0), (0.3, 0), (0.3, 0.03), (0.03, 0.03), (0.03, 0.3), (0, 0.3)]
    vl, fl = prism(ell, [(3, 4, 5), (3, 5, 0), (3, 0, 1), (3, 1, 2)], 0.03)
    put("C003_hull_fit/bracket.obj", obj_text(vl, fl))
    put("_sources/box.obj", obj_text(v, f))
    packed("C004_no_hulls", "_sources/box.obj", HullOptions(mode="none"))

    # physics
    asset = prepare(ROOT / "clean/box.obj")
    name = next(iter(asset.textures))
    asset.textures[name] = asset.files[name] = b"\x89PNG\r\n\x1a\n" + b"\x00" * 64  # a PNG signature, no image
    hulls = compute_hulls(asset.mesh, HullOptions()).hulls
    put("P001_mujoco_compile/box.mbin", pack(asset, False, ConvertOptions().fingerprint(), hulls, None))
    ve, fe = icosphere(0.05, 3)
    ve = ve * [1.0, 1.0, 2.0]  # an egg: it rocks for a while; the rule test sets limits.settle-time = 1
    put("P002_drop_unsettled/egg.obj", obj_text(ve, fe))
    vm, fm = box((2.0, 1.5, 1.0))
    put("P004_mass_implausible/block.obj", obj_text(vm, fm))
    vr, fr = box((2.0, 0.004, 0.004))
    put("P005_inertia_implausible/wire.obj", obj_text(vr, fr))

    # packs
    clean = (ROOT / "clean/box.mbin").read_bytes()
    corrupt = bytearray(clean)
    corrupt[parse(clean).sections[0].offset + 1] ^= 0xFF  # inside the first section: its CRC-32 fails
    put("K001_pack_corrupt/box.mbin", bytes(corrupt))
    wrong = bytearray(clean)
    wrong[8:10] = struct.pack("<H", 9)
    put("K002_pack_version/box.mbin", bytes(wrong))
    put("K003_pack_stale/box.obj", obj_text(*box((0.25, 0.15, 0.1))))
    convert(ROOT / "_sources/box.obj", ROOT / "K003_pack_stale/box.mbin", ConvertOptions())  # from the old box


if __name__ == "__main__":
    main()
