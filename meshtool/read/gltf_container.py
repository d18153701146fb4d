"""The glTF 2.0 container: the GLB header and chunks, the JSON document, and ``data:`` URIs.

Split out of :mod:`meshtool.read.gltf`, which reads the document this module hands it.
"""

from __future__ import annotations

import base64
import json
import struct
from typing import Any
from urllib.parse import unquote

from meshtool.errors import FormatError
from meshtool.files.nesting import DocumentLimitError, bounded

GLB_MAGIC = b"glTF"
JSON_CHUNK = 0x4E4F534A
BIN_CHUNK = 0x004E4942


def read_container(data: bytes, path: str) -> tuple[dict[str, Any], bytes | None, int]:
    """The JSON document and, for GLB, the binary chunk and the file offset of its first byte (else 0)."""
    glb_bin, bin_offset = None, 0
    if data[:4] == GLB_MAGIC:
        if len(data) < 20:
            raise FormatError("GLB shorter than its 12-byte header and first chunk", path=path, offset=0)
        version, length = struct.unpack_from("<II", data, 4)
        if version != 2:
            raise FormatError(f"GLB version {version}: only glTF 2.0 is supported", path=path, offset=4)
        if length > len(data):
            raise FormatError(
                f"GLB truncated: the header says {length} bytes, the file has {len(data)}", path=path, offset=8
            )
        offset, chunks = 12, []
        while offset + 8 <= length:
            size, kind = struct.unpack_from("<II", data, offset)
            if offset + 8 + size > length:
                raise FormatError(f"GLB chunk of {size} bytes runs past the end", path=path, offset=offset)
            chunks.append((kind, data[offset + 8 : offset + 8 + size], offset))
            offset += 8 + size + (-size % 4)
        if not chunks or chunks[0][0] != JSON_CHUNK:
            raise FormatError("GLB without a JSON chunk first", path=path, offset=12)
        text = chunks[0][1]
        binary = next((c for c in chunks[1:] if c[0] == BIN_CHUNK), None)
        if binary is not None:
            glb_bin, bin_offset = binary[1], binary[2] + 8
    else:
        text = data
    try:
        doc = bounded(lambda: json.loads(text.decode("utf-8-sig")))
    except DocumentLimitError as exc:
        raise FormatError(f"glTF JSON cannot be read: {exc}", path=path) from None
    except ValueError as exc:  # not UTF-8, not JSON, an integer of more than 4300 digits
        line = getattr(exc, "lineno", None)
        raise FormatError(f"glTF JSON cannot be read: {str(exc).splitlines()[0][:100]}", path=path, line=line) from None
    if not isinstance(doc, dict):
        raise FormatError("glTF JSON is not an object", path=path, line=1)
    asset = doc.get("asset")
    version = str(asset.get("version", "")) if isinstance(asset, dict) else ""
    if not version.startswith("2."):
        raise FormatError(
            f"glTF version {version or '(none)'}: only glTF 2.0 is supported", path=path, hint="convert it to glTF 2.0"
        )
    return doc, glb_bin, bin_offset


def data_uri(uri: str, path: str, what: str) -> bytes:
    """The bytes of a ``data:`` URI (base64 or percent-encoded)."""
    head, _, payload = uri.partition(",")
    try:
        return (
            base64.b64decode(payload, validate=True) if head.endswith(";base64") else unquote(payload).encode("latin-1")
        )
    except (ValueError, UnicodeEncodeError):
        raise FormatError(f"{what}: malformed data URI", path=path, hint="the file is damaged") from None
