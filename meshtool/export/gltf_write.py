"""The project's one glTF 2.0 writer: buffers, accessors, meshes, materials, textures, nodes, animations.

Every GLB and ``.gltf`` meshtool and simrun write is built here (the formats registry's ``glb`` and
``gltf`` rows): a packed asset (:func:`meshtool.packfile.export.to_glb`), a world
(:func:`simrun.export.glb.world_to_glb`) and an animated recording (:func:`simrun.record.replay_glb.recording_gltf`)
decorate one :class:`GltfBuilder`. The output is deterministic (same calls, same bytes), every buffer view
is 4-byte aligned and carries the ``target`` a mesh primitive reads it as, every accessor used as a position
or animation input carries its ``min``/``max`` (the Khronos validator requires them), and a ``.gltf`` holds
its buffer and images as ``data:`` URIs, so either form is one self-contained file.

Frames: glTF 2.0 is Y-up, metres (section 3.4 "Coordinate System and Units"); meshtool and MuJoCo are Z-up,
metres. Vertex data is written as it is (Z-up) under a node turned by :data:`Z_UP_TO_Y_UP`.
"""

from __future__ import annotations

import base64
import json
import struct
from typing import Any

import numpy as np
import numpy.typing as npt

from meshtool import __version__

#: meshtool's ``asset.generator`` (simrun passes its own).
GENERATOR = f"meshtool {__version__}"
FLOAT, UINT16, UINT32 = 5126, 5123, 5125
ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963
_TYPES = {1: "SCALAR", 2: "VEC2", 3: "VEC3", 4: "VEC4"}
#: Z-up (meshtool, MuJoCo) to Y-up (glTF 2.0): -90 degrees about X, as a 4x4 matrix.
Z_UP_TO_Y_UP = np.array([[1.0, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 0], [0, 0, 0, 1]])
#: The same turn as a glTF node ``rotation`` (x, y, z, w): -90 degrees about X.
Z_UP_TO_Y_UP_ROTATION = [-float(np.sqrt(0.5)), 0.0, 0.0, float(np.sqrt(0.5))]


def unit_quaternions(quats: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """Rotations (n, 4) or (4,) (x, y, z, w) made valid glTF: unit length and every component in [-1, 1].

    glTF 2.0 requires node and animation rotations to be unit quaternions, each component in [-1, 1] (the
    Khronos validator refuses ``1.0000000000000002``, which a rotation matrix turned into a quaternion can give).
    Rows further than 1e-12 from unit length are divided by their length (a zero or non-finite row becomes the
    identity), then every component is clamped to [-1, 1].
    """
    q = np.array(quats, dtype=np.float64)
    rows = q.reshape(-1, 4)
    norms = np.linalg.norm(rows, axis=1)
    bad = ~np.isfinite(norms) | (norms == 0.0)
    rows[bad] = (0.0, 0.0, 0.0, 1.0)
    norms[bad] = 1.0
    off = np.abs(norms - 1.0) > 1e-12
    rows[off] /= norms[off, None]
    np.clip(rows, -1.0, 1.0, out=rows)
    return rows.reshape(q.shape)


def column_major(matrix: npt.ArrayLike) -> list[float]:
    """A 4x4 matrix as a glTF node ``matrix`` (16 numbers, column by column)."""
    return [float(v) for v in np.asarray(matrix, dtype=np.float64).reshape(4, 4).T.ravel()]


class GltfBuilder:
    """Collects glTF objects; :meth:`glb` or :meth:`gltf` serialises them.

    Index methods return the new object's index in its glTF array.
    """

    def __init__(self, generator: str = GENERATOR) -> None:
        self.json: dict[str, Any] = {"asset": {"version": "2.0", "generator": generator}}
        self._blob = bytearray()
        self._images: dict[bytes, int] = {}
        self._samplers: dict[tuple[int, int], int] = {}

    def _add(self, key: str, item: dict[str, Any]) -> int:
        items = self.json.setdefault(key, [])
        items.append(item)
        return len(items) - 1

    def _view(self, data: bytes, target: int | None = None) -> int:
        while len(self._blob) % 4:
            self._blob.append(0)
        view: dict[str, Any] = {"buffer": 0, "byteOffset": len(self._blob), "byteLength": len(data)}
        if target is not None:
            view["target"] = target
        self._blob += data
        return self._add("bufferViews", view)

    def accessor(self, values: npt.ArrayLike, bounds: bool = False, target: int | None = ARRAY_BUFFER) -> int:
        """A float accessor of (n,) or (n, k) values (stored as float32); ``bounds`` adds min and max."""
        array = np.ascontiguousarray(np.asarray(values, dtype=np.float32))
        width = 1 if array.ndim == 1 else array.shape[1]
        item: dict[str, Any] = {
            "bufferView": self._view(array.tobytes(), target),
            "componentType": FLOAT,
            "count": int(array.shape[0]),
            "type": _TYPES[width],
        }
        if bounds:
            flat = array.reshape(len(array), width)
            item["min"] = [float(v) for v in flat.min(axis=0)]
            item["max"] = [float(v) for v in flat.max(axis=0)]
        return self._add("accessors", item)

    def indices(self, triangles: npt.ArrayLike, vertex_count: int) -> int:
        """An index accessor (uint16 when the vertices allow it, else uint32)."""
        small = vertex_count <= 65535
        array = np.ascontiguousarray(np.asarray(triangles).ravel().astype(np.uint16 if small else np.uint32))
        return self._add(
            "accessors",
            {
                "bufferView": self._view(array.tobytes(), ELEMENT_ARRAY_BUFFER),
                "componentType": UINT16 if small else UINT32,
                "count": int(array.size),
                "type": "SCALAR",
            },
        )

    def image(self, png: bytes) -> int:
        """A PNG image (the same bytes are stored once)."""
        if png not in self._images:
            self._images[png] = self._add("images", {"bufferView": self._view(png), "mimeType": "image/png"})
        return self._images[png]

    def texture(self, png: bytes, repeat: bool = True) -> int:
        """A texture of a PNG with linear mipmapped filtering, repeating (or clamped) at the edges."""
        wrap = 10497 if repeat else 33071
        key = (wrap, wrap)
        if key not in self._samplers:
            self._samplers[key] = self._add(
                "samplers", {"magFilter": 9729, "minFilter": 9987, "wrapS": wrap, "wrapT": wrap}
            )
        return self._add("textures", {"sampler": self._samplers[key], "source": self.image(png)})

    def material(
        self,
        name: str,
        rgba: list[float],
        texture: int | None,
        blend: bool,
        double_sided: bool,
        normal: int | None = None,
        normal_scale: float = 1.0,
    ) -> int:
        """A metallic-roughness material (not metallic, fully rough) of base colour ``rgba`` and ``texture``.

        ``normal`` is a tangent-space normal texture (its primitives need ``NORMAL`` and ``TANGENT``), with
        ``normal_scale`` its strength (glTF's default 1 is not written).
        """
        pbr: dict[str, Any] = {"baseColorFactor": rgba, "metallicFactor": 0.0, "roughnessFactor": 1.0}
        if texture is not None:
            pbr["baseColorTexture"] = {"index": texture}
        item: dict[str, Any] = {"name": name, "pbrMetallicRoughness": pbr}
        if normal is not None:
            item["normalTexture"] = {"index": normal}
            if normal_scale != 1.0:
                item["normalTexture"]["scale"] = normal_scale
        if blend:
            item["alphaMode"] = "BLEND"
        if double_sided:
            item["doubleSided"] = True
        return self._add("materials", item)

    def mesh(self, name: str, attributes: dict[str, int], indices: int, material: int) -> int:
        """A mesh of one indexed triangle primitive."""
        primitive = {"attributes": attributes, "indices": indices, "material": material, "mode": 4}
        return self._add("meshes", {"name": name, "primitives": [primitive]})

    def node(self, item: dict[str, Any]) -> int:
        """A node (``name``, ``translation``, ``rotation`` as x, y, z, w, ``mesh``, ``children``...).

        The rotation is written as :func:`unit_quaternions` makes it.
        """
        if "rotation" in item:
            item = {**item, "rotation": [float(v) for v in unit_quaternions(item["rotation"])]}
        return self._add("nodes", item)

    def rotations(self, quats: npt.ArrayLike) -> int:
        """An animation output accessor of (n, 4) rotations (x, y, z, w), made valid by :func:`unit_quaternions`.

        Stored as float32, clamped again after the conversion (a float32 rounding can pass 1 too).
        """
        values = np.clip(unit_quaternions(quats).astype(np.float32), -1.0, 1.0)
        return self.accessor(values, target=None)

    def scene(self, name: str, nodes: list[int]) -> None:
        """The default scene (scene 0); :meth:`extra_scene` adds others."""
        self.json["scenes"] = [{"name": name, "nodes": nodes}]
        self.json["scene"] = 0

    def extra_scene(self, name: str, nodes: list[int]) -> None:
        """Another scene after the default one (viewers open the default; tools that know scenes can switch)."""
        self.json["scenes"].append({"name": name, "nodes": nodes})

    def animation(self, name: str, channels: list[tuple[int, str, int, int]]) -> None:
        """One animation of LINEAR channels (node, ``translation``/``rotation``, input accessor, output accessor)."""
        samplers, items = [], []
        for node, path, times, values in channels:
            samplers.append({"input": times, "output": values, "interpolation": "LINEAR"})
            items.append({"sampler": len(samplers) - 1, "target": {"node": node, "path": path}})
        if items:
            self._add("animations", {"name": name, "channels": items, "samplers": samplers})

    def _finish(self, uri: str | None) -> dict[str, Any]:
        while len(self._blob) % 4:
            self._blob.append(0)
        tree = dict(self.json)
        buffer: dict[str, Any] = {"byteLength": len(self._blob)}
        if uri is not None:
            buffer["uri"] = uri
        tree["buffers"] = [buffer]
        return tree

    def glb(self) -> bytes:
        """The binary container: header, JSON chunk (space-padded) and BIN chunk."""
        tree = self._finish(None)
        text = json.dumps(tree, separators=(",", ":")).encode("utf-8")
        text += b" " * (-len(text) % 4)
        blob = bytes(self._blob)
        total = 12 + 8 + len(text) + 8 + len(blob)
        return (
            struct.pack("<4sII", b"glTF", 2, total)
            + struct.pack("<I4s", len(text), b"JSON")
            + text
            + struct.pack("<I4s", len(blob), b"BIN\0")
            + blob
        )

    def gltf(self) -> bytes:
        """A single ``.gltf`` JSON file with the buffer (images included) as a base64 ``data:`` URI."""
        uri = "data:application/octet-stream;base64," + base64.b64encode(bytes(self._blob)).decode("ascii")
        tree = self._finish(uri)
        return (json.dumps(tree, indent=1) + "\n").encode("utf-8")
