"""Texture colour spaces: colour maps are marked sRGB in their PNG, data maps carry no colour-space tag.

A PNG without colour-space chunks is read as linear by MuJoCo (``colorspace="auto"``, the default of
``<texture>``), which washes out every colour texture; a PNG with an ``sRGB`` chunk is decoded as sRGB.
So the normaliser writes the tag into the file itself: every consumer of the output (meshtool's MJCF
writer, simrun, a hand-written MJCF, glTF tools) then reads it right without an attribute of its own.

* colour maps (:data:`meshtool.read.obj.mtl.COLOR_MAPS`: ``map_Kd``, ``map_Ka``, ``map_Ks``, ``map_Ke``,
  ``decal``): an ``sRGB`` chunk (perceptual intent) right after ``IHDR``; ``gAMA``, ``cHRM`` and ``iCCP``
  are dropped (``sRGB`` supersedes them);
* data maps (normal, bump, displacement, alpha, roughness...): ``sRGB``, ``gAMA``, ``cHRM`` and ``iCCP``
  dropped, so they read as linear.

A PNG used both ways (one file as a colour map of one material and a data map of another) is marked sRGB.
The pixels are never touched. Both operations are idempotent.
"""

from __future__ import annotations

import struct
import zlib

from meshtool.read.obj.mtl import Material, texture_colorspace

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_COLOUR_CHUNKS = {b"sRGB", b"gAMA", b"cHRM", b"iCCP"}


def _chunks(png: bytes) -> list[tuple[bytes, bytes]] | None:
    """(type, data) of every chunk, or ``None`` when ``png`` is not a well-formed PNG."""
    if not png.startswith(PNG_SIGNATURE):
        return None
    out: list[tuple[bytes, bytes]] = []
    at = len(PNG_SIGNATURE)
    while at + 12 <= len(png):
        (length,) = struct.unpack(">I", png[at : at + 4])
        kind = png[at + 4 : at + 8]
        end = at + 12 + length
        if end > len(png):
            return None
        out.append((kind, png[at + 8 : at + 8 + length]))
        at = end
        if kind == b"IEND":
            break
    return out if out and out[0][0] == b"IHDR" else None


def _join(chunks: list[tuple[bytes, bytes]]) -> bytes:
    parts = [PNG_SIGNATURE]
    for kind, data in chunks:
        parts.append(struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data)))
    return b"".join(parts)


def tag_colorspace(png: bytes, colorspace: str) -> bytes:
    """``png`` with its colour-space chunks set for ``colorspace`` (``sRGB`` or ``linear``).

    Args:
        png: PNG file bytes.
        colorspace: ``sRGB`` (an ``sRGB`` chunk is written) or ``linear`` (no colour-space chunk).

    Returns:
        The PNG bytes (unchanged when they are not a well-formed PNG or already tagged so).
    """
    chunks = _chunks(png)
    if chunks is None:
        return png
    kept = [c for c in chunks if c[0] not in _COLOUR_CHUNKS]
    if colorspace == "sRGB":
        kept.insert(1, (b"sRGB", b"\x00"))
    out = _join(kept)
    return png if out == png else out


def tag_textures(materials: list[Material], files: dict[str, bytes]) -> None:
    """Tag every PNG that ``materials`` use in ``files`` (in place) for the roles it plays.

    Args:
        materials: Output materials; their map files are keys of ``files``.
        files: Output file name to bytes.
    """
    roles: dict[str, str] = {}
    for material in materials:
        for key, texture in material.maps.items():
            if texture.file in files and roles.get(texture.file) != "sRGB":
                roles[texture.file] = texture_colorspace(key)
    for name, colorspace in sorted(roles.items()):
        files[name] = tag_colorspace(files[name], colorspace)
