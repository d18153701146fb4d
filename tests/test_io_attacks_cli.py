"""Issue 21, file-reading attacks through the installed command lines (``meshtool normalize``, ``obj2bin``).

Each attack must end with exit 0 (with a warning naming the problem) or exit 1 with exactly one ``error:``
line, never exit 3, a traceback or a hang. The commands run as subprocesses, like a user runs them.
"""

import io
import json
import os
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest
from PIL import Image

BIN = Path(sys.executable).parent
COMMANDS = {
    "normalize": lambda src, out: [BIN / "meshtool", "normalize", src, "-o", out / "out"],
    "obj2bin": lambda src, out: [BIN / "obj2bin", src, "-o", out / "y.mbin"],
}
OBJ = (
    b"mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nvt 0 0\nvt 1 0\nvt 0 1\n"
    b"usemtl x\nf 1/1 3/3 2/2\nf 1/1 2/2 4/3\nf 1/1 4/3 3/2\nf 2/1 3/2 4/3\n"
)
MTL = b"newmtl x\nKd 1 0 0\nmap_Kd tex.png\n"


def png(size: tuple[int, int] = (8, 8)) -> bytes:
    buf = io.BytesIO()
    Image.new("RGB", size, (10, 200, 30)).save(buf, format="PNG")
    return buf.getvalue()


def asset(root: Path, obj: bytes = OBJ, mtl: bytes = MTL, tex: bytes | None = None, tex_name: str = "tex.png") -> Path:
    root.mkdir(parents=True)
    (root / "box.obj").write_bytes(obj)
    (root / "m.mtl").write_bytes(mtl)
    (root / tex_name).write_bytes(png() if tex is None else tex)
    return root / "box.obj"


def fifo_in_place(path: Path) -> None:
    path.unlink()
    os.mkfifo(path)


def fifo_obj(root: Path) -> Path:
    obj = asset(root)
    fifo_in_place(obj)
    return obj


def fifo_mtl(root: Path) -> Path:
    obj = asset(root)
    fifo_in_place(root / "m.mtl")
    return obj


def fifo_texture(root: Path) -> Path:
    obj = asset(root)
    fifo_in_place(root / "tex.png")
    return obj


def sparse_obj(root: Path) -> Path:
    obj = asset(root)
    os.truncate(obj, 3 << 30)
    return obj


def sparse_png_tail(root: Path) -> Path:
    obj = asset(root)
    with open(root / "tex.png", "r+b") as handle:
        handle.truncate(len(png()) + (20 << 20))  # 20 MiB of zeros after the image end
    return obj


def truncated_jpeg(root: Path) -> Path:
    buf = io.BytesIO()
    Image.new("RGB", (64, 64), (200, 10, 10)).save(buf, format="JPEG")
    data = bytearray(buf.getvalue())
    sof = data.index(b"\xff\xc0")
    data[sof + 5 : sof + 9] = (9000).to_bytes(2, "big") * 2  # claims 9000 x 9000
    return asset(root, mtl=MTL.replace(b"tex.png", b"tex.jpg"), tex=bytes(data), tex_name="tex.jpg")


def long_reference(root: Path) -> Path:
    long = b"x" * 300
    return asset(
        root,
        obj=OBJ.replace(b"mtllib m.mtl", b"mtllib m.mtl " + long + b".mtl"),
        mtl=MTL + b"map_Ks " + long + b".png\n",
    )


def long_obj_name(root: Path) -> Path:
    root.mkdir()
    return root / ("y" * 300 + ".obj")


def non_utf8_names(root: Path) -> Path:
    obj = asset(
        root, obj=OBJ.replace(b"mtllib m.mtl", b"mtllib m\xff.mtl"), mtl=MTL.replace(b"tex.png", b"tex\xe9.png")
    )
    os.rename(os.fsencode(root / "m.mtl"), os.fsencode(root) + b"/m\xff.mtl")
    os.rename(os.fsencode(root / "tex.png"), os.fsencode(root) + b"/tex\xe9.png")
    odd = Path(os.fsdecode(os.fsencode(root) + b"/b\xfe.obj"))
    os.rename(obj, odd)
    return odd


def nul_after_64k(root: Path) -> Path:
    return asset(root, obj=OBJ + b"# padding line\n" * 5000 + b"v 1 2 3\x00\n")


def link_out(root: Path) -> Path:
    obj = asset(root)
    (root.parent / "secret.png").write_bytes(png((4, 4)))
    (root / "tex.png").unlink()
    os.symlink(root.parent / "secret.png", root / "tex.png")
    return obj


# name -> (make, expected exit code, words the error/warning line must contain)
ATTACKS: dict[str, tuple[Callable[[Path], Path], int, str]] = {
    "fifo-obj": (fifo_obj, 1, "is a FIFO (named pipe), not a regular file"),
    "fifo-mtl": (fifo_mtl, 0, "[mtl-not-a-file]"),
    "fifo-texture": (fifo_texture, 0, "[texture-not-a-file]"),
    "sparse-3gb-obj": (sparse_obj, 1, "is 3 GiB, over the 1 GiB limit"),
    "png-with-sparse-tail": (sparse_png_tail, 0, "[texture-trailing-data]"),
    "truncated-jpeg": (truncated_jpeg, 0, "truncated JPEG"),
    "long-reference": (long_reference, 0, "[texture-missing]"),
    "long-obj-name": (long_obj_name, 1, "the file name is too long"),
    "non-utf8-names": (non_utf8_names, 0, ""),
    "nul-after-64k": (nul_after_64k, 1, "binary data, not a text file (byte 0x00 at byte offset"),
    "symlink-out": (link_out, 0, "[reference-outside-root]"),
}


@pytest.mark.parametrize("command", sorted(COMMANDS))
@pytest.mark.parametrize("attack", sorted(ATTACKS))
def test_attack_gives_one_clean_line(tmp_path, attack, command):
    make, code, words = ATTACKS[attack]
    src = make(tmp_path / "asset")
    env = {k: v for k, v in os.environ.items() if k != "MESHTOOL_DEBUG"} | {"MESHTOOL_VERBOSE": "1"}
    proc = subprocess.run(
        [os.fspath(a) for a in COMMANDS[command](src, tmp_path)], capture_output=True, timeout=120, env=env, check=False
    )
    stderr = proc.stderr.decode("utf-8")  # always valid UTF-8, also for non-UTF-8 file names
    assert "Traceback" not in stderr and "internal error" not in stderr, stderr
    assert proc.returncode == code, stderr
    errors = [line for line in stderr.splitlines() if line.startswith("error:")]
    if code == 1:
        assert len(errors) == 1, stderr
        assert words in errors[0]
    else:
        assert errors == []
        assert words in stderr
    if code == 0 and command == "normalize":
        (manifest,) = (tmp_path / "out").glob("*/asset.json")
        json.loads(manifest.read_bytes().decode("utf-8"))  # strict UTF-8, no lone surrogates
    if attack == "png-with-sparse-tail" and command == "normalize":
        (tex,) = (tmp_path / "out").glob("*/*.png")
        data = tex.read_bytes()  # the image (tagged sRGB as a colour map), not 20 MiB of zeros
        assert len(data) < 2 * len(png()) and data.endswith(png()[-12:])  # ends with its IEND chunk
        assert Image.open(io.BytesIO(data)).convert("RGB").tobytes() == Image.open(io.BytesIO(png())).tobytes()
    if attack == "truncated-jpeg" and command == "normalize":
        assert list((tmp_path / "out").glob("*/*.png")) == []  # no 9000 x 9000 grey texture
    if attack == "non-utf8-names" and command == "normalize":
        (manifest,) = (tmp_path / "out").glob("*/asset.json")
        sources = {s["role"]: s["path"] for s in json.loads(manifest.read_text("utf-8"))["sources"]}
        assert sources == {"obj": "b\\xfe.obj", "mtl": "m\\xff.mtl", "texture": "tex\\xe9.png"}
