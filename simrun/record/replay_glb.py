"""Animated glTF of a recording: the world's visual geoms, one node per body, one animation of the body poses.

Layout: the scene's one root node, ``simrun_world``, turns MuJoCo's Z-up world into glTF's Y-up (-90
degrees about X; metres throughout). Under it, one node per body (the world body only when it has geoms),
named like the body (``boebot``, ``boebot/left_wheel``, with ``extras.simrun_body`` holding the name as well), at the
body's world pose at the first frame (MuJoCo's ``xpos``/``xquat``: the body frame, not the inertial one).
Under each body node, one node per visual geom (named like the geom) at the geom's pose in the body frame,
with a mesh with normals, texture coordinates where its material has a texture, and a material: the geom's
colour (the material's when the geom keeps MuJoCo's default colour), the material's 2D texture as PNG
(tiled as MuJoCo tiles it, see :mod:`simrun.export.tessellate`), blended when translucent. Collision geoms
(group 3 and above) and fully transparent geoms are left out, as MuJoCo's viewer leaves them.

The animation ``recording`` has a translation and a rotation channel (LINEAR; glTF interpolates
rotations spherically, the shorter way) per moving body, keyed at the frames
:func:`simrun.record.replay_tracks.animation_keys` keeps, in the recording's seconds. Static bodies have no
channel. Numbers are float32 (poses exact to about 1e-7 m on metre-scale worlds; a key whose time float32
cannot tell from the previous key's, which takes recordings longer than about 1e5 s, is dropped).
"""

from __future__ import annotations

import io
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np
from PIL import Image

from meshtool.export.gltf_write import Z_UP_TO_Y_UP, GltfBuilder
from simrun.errors import SimrunError
from simrun.export.glb import COLLISION_GROUP
from simrun.export.tessellate import Surface, geom_surface
from simrun.outfile import GENERATOR
from simrun.record.replay_tracks import I64, Tracks
from simrun.world.world import World

#: MuJoCo's default geom colour: a geom with a material and this colour shows the material's colour.
DEFAULT_RGBA = (0.5, 0.5, 0.5, 1.0)
#: Name of the root node (Z-up to Y-up).
ROOT = "simrun_world"


@dataclass(frozen=True)
class GeomLook:
    """How a geom is drawn: colour (RGBA 0..1), the 2D texture id (-1: none) and its tiling."""

    rgba: tuple[float, ...]
    texture: int
    repeat: tuple[float, float]
    uniform: bool


def geom_look(model: mujoco.MjModel, g: int) -> GeomLook:
    """The colour and texture MuJoCo draws geom ``g`` with."""
    rgba = tuple(float(c) for c in np.clip(model.geom_rgba[g], 0.0, 1.0))
    mat = int(model.geom_matid[g])
    if mat < 0:
        return GeomLook(rgba, -1, (1.0, 1.0), False)
    if np.allclose(rgba, DEFAULT_RGBA):
        rgba = tuple(float(c) for c in np.clip(model.mat_rgba[mat], 0.0, 1.0))
    texture = int(model.mat_texid[mat][int(mujoco.mjtTextureRole.mjTEXROLE_RGB)])
    if texture < 0 or int(model.tex_type[texture]) != int(mujoco.mjtTexture.mjTEXTURE_2D):
        texture = -1  # cube and skybox textures have no 2D image to map
    repeat = (float(model.mat_texrepeat[mat][0]), float(model.mat_texrepeat[mat][1]))
    return GeomLook(rgba, texture, repeat, bool(model.mat_texuniform[mat]))


def texture_png(model: mujoco.MjModel, texture: int) -> bytes:
    """A 2D texture's pixels (rows top to bottom, as glTF reads them) as PNG bytes."""
    width, height, channels = (
        int(v) for v in (model.tex_width[texture], model.tex_height[texture], model.tex_nchannel[texture])
    )
    start = int(model.tex_adr[texture])
    pixels = np.asarray(model.tex_data[start : start + width * height * channels], dtype=np.uint8)
    mode = {1: "L", 3: "RGB", 4: "RGBA"}.get(channels)
    if mode is None:
        raise SimrunError(f"texture {model.tex(texture).name!r} has {channels} channels; glTF takes 1, 3 or 4")
    shape = (height, width) if channels == 1 else (height, width, channels)
    image = Image.fromarray(pixels.reshape(shape), mode=mode)
    if mode == "L":
        image = image.convert("RGB")
    buffer = io.BytesIO()
    image.save(buffer, format="PNG")
    return buffer.getvalue()


def _xyzw(wxyz: Any) -> list[float]:
    w, x, y, z = (float(v) for v in wxyz)
    return [x, y, z, w]


def _root_rotation() -> list[float]:
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(Z_UP_TO_Y_UP[:3, :3]).ravel())
    return _xyzw(quat)


class _Meshes:
    """glTF meshes and materials, each made once per distinct shape and look."""

    def __init__(self, gltf: GltfBuilder, model: mujoco.MjModel) -> None:
        self.gltf, self.model = gltf, model
        self.meshes: dict[tuple[Any, ...], int] = {}
        self.materials: dict[GeomLook, int] = {}
        self.textures: dict[int, int] = {}

    def material(self, look: GeomLook, plane: bool) -> int:
        if look not in self.materials:
            texture = None
            if look.texture >= 0:
                if look.texture not in self.textures:
                    self.textures[look.texture] = self.gltf.texture(texture_png(self.model, look.texture))
                texture = self.textures[look.texture]
            name = self.model.tex(look.texture).name if look.texture >= 0 else "rgba"
            self.materials[look] = self.gltf.material(
                f"{name}_{len(self.materials)}", list(look.rgba), texture, look.rgba[3] < 1.0, plane
            )
        return self.materials[look]

    def mesh(self, g: int, name: str) -> int | None:
        model = self.model
        look = geom_look(model, g)
        kind = int(model.geom_type[g])
        shape: tuple[Any, ...]
        if kind == int(mujoco.mjtGeom.mjGEOM_MESH):
            shape = ("mesh", int(model.geom_dataid[g]))
        else:
            shape = (kind, *(float(v) for v in model.geom_size[g]))
        textured = look.texture >= 0
        key = (*shape, look, textured)
        if key in self.meshes:
            return self.meshes[key]
        surface = geom_surface(model, g, np.array(look.repeat), look.uniform)
        if surface is None:
            return None
        if textured and surface.uvs is None:
            look = GeomLook(look.rgba, -1, look.repeat, look.uniform)  # a mesh without texture coordinates
            textured = False
        material = self.material(look, kind == int(mujoco.mjtGeom.mjGEOM_PLANE))
        self.meshes[key] = self.gltf.mesh(name, self._attributes(surface, textured), self._indices(surface), material)
        return self.meshes[key]

    def _attributes(self, surface: Surface, textured: bool) -> dict[str, int]:
        gltf = self.gltf
        attributes = {
            "POSITION": gltf.accessor(surface.positions, bounds=True),
            "NORMAL": gltf.accessor(surface.normals),
        }
        if textured and surface.uvs is not None:
            attributes["TEXCOORD_0"] = gltf.accessor(surface.uvs)
        return attributes

    def _indices(self, surface: Surface) -> int:
        return self.gltf.indices(surface.triangles, len(surface.positions))


def recording_gltf(world: World, tracks: Tracks, keys: dict[int, I64], name: str = "recording") -> GltfBuilder:
    """The animated glTF of ``tracks`` (from :func:`simrun.record.replay_tracks.read_tracks`) keyed at ``keys``.

    Args:
        world: The compiled world the recording was replayed in.
        tracks: Every body's pose per frame.
        keys: Keyframe indices per moving body (:func:`simrun.record.replay_tracks.animation_keys`).
        name: The animation's name.

    Raises:
        SimrunError: The world has no visual geom to show.
    """
    model = world.model
    gltf = GltfBuilder(GENERATOR)
    meshes = _Meshes(gltf, model)
    children: dict[int, list[int]] = {}
    for g in range(model.ngeom):
        if int(model.geom_group[g]) >= COLLISION_GROUP or float(model.geom_rgba[g][3]) <= 0.0:
            continue
        geom_name = model.geom(g).name or f"geom{g}"
        mesh = meshes.mesh(g, geom_name)
        if mesh is None:
            continue
        node = gltf.node(
            {
                "name": geom_name,
                "mesh": mesh,
                "translation": [float(v) for v in model.geom_pos[g]],
                "rotation": _xyzw(model.geom_quat[g]),
            }
        )
        children.setdefault(int(model.geom_bodyid[g]), []).append(node)
    if not children:
        raise SimrunError("the world has no visual geoms to export")
    body_nodes: dict[int, int] = {}
    for b in range(model.nbody):
        if b == 0 and b not in children:
            continue  # the world body is the root node's frame; a node only when it has geoms of its own
        body_name = model.body(b).name or f"body{b}"
        item: dict[str, Any] = {
            "name": body_name,
            "translation": [float(v) for v in tracks.positions[0, b]],
            "rotation": _xyzw(tracks.quats[0, b]),
        }
        if b in children:
            item["children"] = children[b]
        item["extras"] = {"simrun_body": body_name}
        body_nodes[b] = gltf.node(item)
    root = gltf.node({"name": ROOT, "rotation": _root_rotation(), "children": list(body_nodes.values())})
    gltf.scene("recording", [root])
    channels = []
    inputs: dict[bytes, int] = {}
    for b, frames in sorted(keys.items()):
        if b not in body_nodes:
            continue
        frames = _distinct_in_float32(tracks.times, frames)
        signature = frames.tobytes()
        if signature not in inputs:
            inputs[signature] = gltf.accessor(tracks.times[frames], bounds=True, target=None)
        translation = gltf.accessor(tracks.positions[frames, b], target=None)
        rotation = gltf.rotations(tracks.quats[frames, b][:, [1, 2, 3, 0]])
        channels += [(body_nodes[b], "translation", inputs[signature], translation)]
        channels += [(body_nodes[b], "rotation", inputs[signature], rotation)]
    gltf.animation(name, channels)
    return gltf


def _distinct_in_float32(times: Any, frames: I64) -> I64:
    """``frames`` less those whose time rounds to the same float32 as an earlier kept one.

    glTF stores key times as float32 and needs them strictly increasing; past about 1e5 s, float32 cannot
    tell frames 1 ms apart (``--fps`` then keeps the animation valid and small).
    """
    stored = np.asarray(times, dtype=np.float64)[frames].astype(np.float32)
    keep = np.concatenate([[True], np.diff(np.maximum.accumulate(stored)) > 0])
    return np.asarray(frames[keep], dtype=np.int64)
