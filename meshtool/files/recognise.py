"""Whether an existing file is one the project wrote: the recognisers the formats registry names.

:func:`meshtool.files.outdir.check_output` replaces an existing output without ``--force`` only when the
recogniser of its row in :data:`meshtool.formats.OUTPUTS` says the file is ours. Each recogniser reads at
most the head of the file it needs (never follows a link, never blocks on a pipe) and answers ``False`` for
anything it cannot read. Formats with room for a generator stamp are recognised by it (``meshtool`` or
``simrun``); the others by their magic number or root element (any file of the kind is replaced).
"""

from __future__ import annotations

import json
import os
import stat
import struct
from pathlib import Path

#: Generators whose files count as the project's outputs (simrun writes through meshtool's writers).
GENERATORS = ("meshtool", "simrun")
_HEAD_LIMIT = 64 << 20  # bytes read to recognise an existing output (a GLB's JSON chunk)
_MARK_WINDOW = 512  # bytes at the start of a text output that hold its generator stamp


def read_head(path: Path, limit: int) -> bytes | None:
    """Up to ``limit`` bytes of a regular file (never follows a link, never blocks on a pipe)."""
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0))
    except OSError:
        return None
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            return None
        chunks, left = [], limit
        while left > 0:
            chunk = os.read(fd, min(left, 1 << 20))
            if not chunk:
                break
            chunks.append(chunk)
            left -= len(chunk)
        return b"".join(chunks)
    except OSError:
        return None
    finally:
        os.close(fd)


def has_magic(path: Path, magic: tuple[bytes, ...]) -> bool:
    """Whether the file starts with one of ``magic``."""
    head = read_head(path, max(len(m) for m in magic)) or b""
    return any(head.startswith(m) for m in magic)


def is_mbin(path: Path, size: int) -> bool:
    """An ``.mbin`` whose metadata names meshtool as its writer."""
    from meshtool.errors import MeshtoolError
    from meshtool.packfile.format import MAGIC
    from meshtool.packfile.read import load

    if read_head(path, len(MAGIC)) != MAGIC:
        return False
    try:
        with load(path, verify=False) as packed:
            return bool(packed.pack_meta.tool.get("name") == "meshtool")
    except MeshtoolError:
        return False


def is_glb(path: Path, size: int) -> bool:
    """A GLB (glTF 2.0 binary container) whose ``asset.generator`` is meshtool or simrun."""
    head = read_head(path, 20)
    if head is None or len(head) < 20 or head[:4] != b"glTF":
        return False
    version, _, json_length, chunk = struct.unpack("<IIII", head[4:20])
    if version != 2 or chunk != 0x4E4F534A or json_length > min(size, _HEAD_LIMIT):
        return False
    body = read_head(path, 20 + json_length)
    try:
        tree = json.loads((body or b"")[20:])
        generator = tree["asset"]["generator"]
    except (ValueError, KeyError, TypeError, RecursionError):  # not a GLB we wrote
        return False
    return isinstance(generator, str) and generator.startswith(GENERATORS)


def is_usd(path: Path, size: int) -> bool:
    """A USD layer (text or crate) whose ``customLayerData.generator`` is meshtool or simrun."""
    head = read_head(path, 16) or b""
    if not (head.startswith(b"#usda ") or head.startswith(b"PXR-USDC")):
        return False
    try:
        from pxr import Sdf

        layer = Sdf.Layer.OpenAsAnonymous(str(path))
        generator = dict(layer.customLayerData).get("generator") if layer is not None else None
    except Exception:  # usd-core raises Tf errors of its own for unreadable layers
        return False
    return isinstance(generator, str) and generator.startswith(GENERATORS)


def is_msh(path: Path, size: int) -> bool:
    """MuJoCo's legacy MSH has no magic or metadata: the four counts must account for the size exactly."""
    head = read_head(path, 16)
    if head is None or len(head) < 16:
        return False
    nv, nn, nt, nf = struct.unpack("<4i", head)
    if min(nv, nn, nt, nf) < 0 or nv == 0:
        return False
    return bool(16 + 4 * (3 * nv + 3 * nn + 2 * nt + 3 * nf) == size)


def _marked(path: Path, marks: tuple[bytes, ...]) -> bool:
    head = read_head(path, _MARK_WINDOW) or b""
    return any(mark in head for mark in marks)


def is_gltf(path: Path, size: int) -> bool:
    """A glTF JSON file whose ``asset.generator`` near the start is meshtool's or simrun's."""
    return _marked(path, tuple(f'"generator": "{g}'.encode() for g in GENERATORS))


def is_html(path: Path, size: int) -> bool:
    """A page whose ``<meta name="generator">`` near the start is meshtool's or simrun's."""
    return _marked(path, tuple(f'<meta name="generator" content="{g}'.encode() for g in GENERATORS))


def is_obj(path: Path, size: int) -> bool:
    """An OBJ whose first line is a comment naming meshtool or simrun as its writer."""
    head = read_head(path, _MARK_WINDOW) or b""
    return head.startswith(tuple(f"# {g}".encode() for g in GENERATORS))


def is_mjcf(path: Path, size: int) -> bool:
    """An XML file whose root element is ``<mujoco>`` (after any declaration and comments)."""
    text = (read_head(path, _MARK_WINDOW) or b"").decode("utf-8", "replace").lstrip("\ufeff \t\r\n")
    while text.startswith("<?") or text.startswith("<!--"):
        end = text.find("?>" if text.startswith("<?") else "-->")
        if end < 0:
            return False
        text = text[end + (2 if text.startswith("<?") else 3) :].lstrip()
    return text.startswith("<mujoco")


def is_mp4(path: Path, size: int) -> bool:
    """An ISO media file: an ``ftyp`` box first."""
    head = read_head(path, 8) or b""
    return head[4:8] == b"ftyp"
