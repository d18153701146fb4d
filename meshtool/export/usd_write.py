"""The project's one USD writer: stage set-up, prim names, meshes, materials, textures, colliders, the stamp.

Every USD stage meshtool and simrun write is built here (the formats registry's ``usd`` row): a packed asset
(:func:`meshtool.packfile.usd.export_usd`), a world (:func:`simrun.export.usd.export_world_usd`, which adds
the rigid bodies, joints and drives it reads from MuJoCo) and an animated recording
(:func:`simrun.record.replay_usd.export_recording_usd`, time samples on the world's stage) decorate one
:class:`UsdBuilder`. usd-core (``pxr``) writes the layer; the builder holds what every writer shares:

- the stage: Z-up (``upAxis = "Z"``), metres (``metersPerUnit = 1``), the frame meshtool and MuJoCo use, so
  vertex data goes in as it is; one root ``Xform`` is the default prim;
- prim names: :func:`prim_name` is the one sanitising rule (``[A-Za-z0-9_]``, never a leading digit) and
  :meth:`UsdBuilder.child` the one unique rule (:func:`meshtool.packfile.view.unique_name`: ``name``,
  ``name_2``, ``name_3``... among the parent's children);
- ``UsdGeom.Mesh`` prims with normals, ``primvars:st`` and their extent; UsdPreviewSurface materials reading
  PNG textures; colliders (``UsdPhysics.CollisionAPI``, optionally ``MeshCollisionAPI`` with a
  ``convexHull`` approximation); poses as double-precision translate and orient ops;
- the generator stamp in ``customLayerData`` (how :func:`meshtool.files.outdir.check_output` knows the file is
  ours to replace) and the bytes, ready for an atomic write (:meth:`UsdBuilder.save`).

The output is deterministic: the same calls give the same bytes (``.usda`` text, or the ``.usdc`` crate for
``.usdc`` and ``.usd``).
"""

from __future__ import annotations

import re
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from meshtool.errors import OutputError
from meshtool.files.outdir import GENERATOR, stamp_usd, write_file
from meshtool.files.resolve import read_cache
from meshtool.formats import check_suffix
from meshtool.packfile.view import unique_name

_UNSAFE = re.compile(r"[^A-Za-z0-9_]+")


def prim_name(name: str, fallback: str) -> str:
    """A valid USD prim name for ``name``: runs of characters outside ``[A-Za-z0-9_]`` become one ``_``.

    Leading and trailing ``_`` are dropped (``fallback`` when nothing is left) and a name starting with a
    digit gets a ``_`` in front (``3d head`` is ``_3d_head``). Idempotent.
    """
    text = _UNSAFE.sub("_", name.strip()).strip("_") or fallback
    return f"_{text}" if text[:1].isdigit() else text


class UsdBuilder:
    """One stage being built for ``out``; :meth:`finish` gives its bytes, :meth:`save` writes them.

    Args:
        out: The file the stage is for; its suffix (``.usda``, ``.usdc`` or ``.usd``) picks the encoding.
        root: The root prim's name (sanitised by :func:`prim_name`), the stage's default prim.
        generator: Recorded as ``customLayerData["generator"]`` (simrun passes its own).

    Attributes:
        stage: The ``Usd.Stage`` (decorators author on it directly what the builder has no method for).
        root: The root prim's path (``/NAME``).

    Raises:
        OutputError: ``out`` does not end in a USD suffix.
    """

    def __init__(self, out: Path, root: str, generator: str = GENERATOR) -> None:
        from pxr import Usd, UsdGeom

        wrong = check_suffix(out, "usd")
        if wrong is not None:
            raise OutputError(wrong, path=str(out))
        self.out = out
        self.generator = generator
        self._children: dict[str, set[str]] = {}
        self._groups: dict[tuple[str, str], str] = {}
        self._tmp = tempfile.TemporaryDirectory(prefix="meshtool-usd-")
        self._scratch = Path(self._tmp.name) / f"stage{out.suffix.lower()}"
        self.stage: Any = Usd.Stage.CreateNew(str(self._scratch))
        UsdGeom.SetStageUpAxis(self.stage, UsdGeom.Tokens.z)
        UsdGeom.SetStageMetersPerUnit(self.stage, 1.0)
        self.root = self.child("", root, "root")
        self.stage.SetDefaultPrim(UsdGeom.Xform.Define(self.stage, self.root).GetPrim())

    def __enter__(self) -> UsdBuilder:
        return self

    def __exit__(self, *exc: object) -> None:
        self._tmp.cleanup()

    def child(self, parent: str, name: str, fallback: str = "prim") -> str:
        """A new prim path under ``parent`` (``""`` for the pseudo-root): ``name`` sanitised, made unique.

        Defines nothing; each call claims a new name (``a``, then ``a_2``...).
        """
        taken = self._children.setdefault(parent, set())
        claimed = unique_name(prim_name(name, fallback), taken)
        taken.add(claimed)
        return f"{parent}/{claimed}"

    def group(self, parent: str, name: str) -> str:
        """The ``UsdGeom.Scope`` ``name`` under ``parent`` (``Geom``, ``joints``...), defined on first use.

        Later calls with the same arguments return the same path; its name is claimed like :meth:`child`'s.
        """
        key = (parent, name)
        if key not in self._groups:
            from pxr import UsdGeom

            self._groups[key] = self.child(parent, name)
            UsdGeom.Scope.Define(self.stage, self._groups[key])
        return self._groups[key]

    def xform(self, path: str) -> Any:
        """A ``UsdGeom.Xform`` at ``path``."""
        from pxr import UsdGeom

        return UsdGeom.Xform.Define(self.stage, path)

    def place(self, prim: Any, position: npt.ArrayLike, quaternion: npt.ArrayLike) -> None:
        """Translate (double3, metres, in the parent's frame) and orient (quatd, ``w x y z``) ops on ``prim``.

        The orientation is double precision: a float quaternion near the identity turns into a rotation off by
        up to 1e-5 rad when USD composes the transform.
        """
        from pxr import Gf, UsdGeom

        xform = UsdGeom.Xformable(prim)
        xform.AddTranslateOp().Set(Gf.Vec3d(*(float(v) for v in np.asarray(position, dtype=float))))
        w, x, y, z = (float(v) for v in np.asarray(quaternion, dtype=float))
        xform.AddOrientOp(UsdGeom.XformOp.PrecisionDouble).Set(Gf.Quatd(w, x, y, z))

    def sample_pose(self, prim: Any, code: float, position: npt.ArrayLike, quaternion: npt.ArrayLike) -> None:
        """A time sample at time code ``code`` on the translate and orient ops :meth:`place` put on ``prim``.

        ``position`` is metres in the parent's frame, ``quaternion`` ``w x y z``; USD interpolates translations
        linearly and orientations spherically between samples.
        """
        from pxr import Gf, UsdGeom

        translate, orient = UsdGeom.Xformable(prim).GetOrderedXformOps()[:2]
        translate.Set(Gf.Vec3d(*(float(v) for v in np.asarray(position, dtype=float))), code)
        orient.Set(Gf.Quatd(*(float(v) for v in np.asarray(quaternion, dtype=float))), code)

    def mesh(
        self,
        path: str,
        positions: npt.ArrayLike,
        faces: npt.ArrayLike,
        normals: npt.ArrayLike | None = None,
        uvs: npt.ArrayLike | None = None,
    ) -> Any:
        """A triangle ``UsdGeom.Mesh`` (no subdivision) with its extent.

        Args:
            path: The prim path (from :meth:`child`).
            positions: (n, 3) metres in the prim's frame, stored as float32.
            faces: (m, 3) indices into ``positions``, counter-clockwise seen from outside.
            normals: (n, 3) per-vertex normals, or ``None``.
            uvs: (n, 2) texture coordinates (``v = 0`` at the image bottom, USD's and OBJ's convention) as the
                ``st`` primvar, or ``None``.
        """
        from pxr import Gf, Sdf, UsdGeom, Vt

        points = np.asarray(positions, dtype=np.float32).reshape(-1, 3)
        triangles = np.asarray(faces).reshape(-1, 3)
        mesh = UsdGeom.Mesh.Define(self.stage, path)
        mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(points))
        mesh.CreateFaceVertexCountsAttr(Vt.IntArray([3] * len(triangles)))
        mesh.CreateFaceVertexIndicesAttr(Vt.IntArray(triangles.astype(np.int32).ravel().tolist()))
        mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
        if normals is not None:
            mesh.CreateNormalsAttr(Vt.Vec3fArray.FromNumpy(np.asarray(normals, dtype=np.float32).reshape(-1, 3)))
            mesh.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
        if uvs is not None:
            st = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar(
                "st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.vertex
            )
            st.Set(Vt.Vec2fArray.FromNumpy(np.asarray(uvs, dtype=np.float32).reshape(-1, 2)))
        if len(points):
            lo, hi = points.min(axis=0), points.max(axis=0)
            mesh.CreateExtentAttr([Gf.Vec3f(*lo.tolist()), Gf.Vec3f(*hi.tolist())])
        return mesh

    def display_colour(self, prim: Any, rgb: npt.ArrayLike) -> None:
        """``primvars:displayColor`` of a gprim: one linear RGB colour, 0..1."""
        from pxr import Gf, UsdGeom, Vt

        r, g, b = (float(v) for v in np.asarray(rgb, dtype=float)[:3])
        UsdGeom.Gprim(prim).CreateDisplayColorAttr(Vt.Vec3fArray([Gf.Vec3f(r, g, b)]))

    def purpose(self, prim: Any, guide: bool) -> None:
        """Purpose ``guide`` (collision-only geometry, hidden by renderers) or ``render``."""
        from pxr import UsdGeom

        UsdGeom.Imageable(prim).CreatePurposeAttr(UsdGeom.Tokens.guide if guide else UsdGeom.Tokens.render)

    def collider(self, prim: Any, convex_hull: bool) -> None:
        """``UsdPhysics.CollisionAPI`` on ``prim``; a mesh collides as its convex hull when ``convex_hull``."""
        from pxr import UsdPhysics

        UsdPhysics.CollisionAPI.Apply(prim.GetPrim())
        if convex_hull:
            api = UsdPhysics.MeshCollisionAPI.Apply(prim.GetPrim())
            api.CreateApproximationAttr(UsdPhysics.Tokens.convexHull)

    def physics_scene(self, gravity: npt.ArrayLike) -> None:
        """``/PhysicsScene`` (beside the root): ``gravity`` ((3,) m/s², world frame) as direction and magnitude."""
        from pxr import Gf, UsdPhysics

        scene = UsdPhysics.Scene.Define(self.stage, self.child("", "PhysicsScene"))
        vector = np.asarray(gravity, dtype=float)
        magnitude = float(np.linalg.norm(vector))
        if magnitude > 0:
            scene.CreateGravityDirectionAttr(Gf.Vec3f(*(vector / magnitude).tolist()))
        scene.CreateGravityMagnitudeAttr(magnitude)

    def material(
        self,
        path: str,
        diffuse: tuple[float, float, float],
        opacity: float,
        roughness: float,
        colour_map: str | None = None,
        normal_map: str | None = None,
        normal_scale: float = 1.0,
    ) -> Any:
        """A UsdPreviewSurface material at ``path``: diffuse colour or texture, normal map, opacity, roughness.

        The colour map (a PNG file name, relative to the stage) is read with ``sourceColorSpace = sRGB``, the
        normal map with ``raw`` and mapped from 0..1 to -1..1 (``scale (2s, 2s, 2, 1)``, ``bias (-s, -s,
        -1, 0)``, ``s`` its strength) into the surface's ``normal`` input, as the UsdPreviewSurface
        specification asks for tangent-space normal maps. Both are read at the primvar ``st``.
        """
        from pxr import Sdf, UsdShade

        material = UsdShade.Material.Define(self.stage, path)
        shader = UsdShade.Shader.Define(self.stage, f"{path}/PreviewSurface")
        shader.CreateIdAttr("UsdPreviewSurface")
        colour = shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f)
        colour.Set(diffuse)
        shader.CreateInput("opacity", Sdf.ValueTypeNames.Float).Set(float(opacity))
        shader.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(float(roughness))
        if colour_map is not None or normal_map is not None:
            reader = UsdShade.Shader.Define(self.stage, f"{path}/stReader")
            reader.CreateIdAttr("UsdPrimvarReader_float2")
            reader.CreateInput("varname", Sdf.ValueTypeNames.String).Set("st")  # UsdPreviewSurface: a string
            if colour_map is not None:
                image = self._uv_texture(f"{path}/DiffuseTexture", colour_map, "sRGB", reader)
                colour.ConnectToSource(image.ConnectableAPI(), "rgb")
            if normal_map is not None:
                image = self._uv_texture(f"{path}/NormalTexture", normal_map, "raw", reader)
                s = float(normal_scale)
                image.CreateInput("scale", Sdf.ValueTypeNames.Float4).Set((2.0 * s, 2.0 * s, 2.0, 1.0))
                image.CreateInput("bias", Sdf.ValueTypeNames.Float4).Set((-s, -s, -1.0, 0.0))
                normal = shader.CreateInput("normal", Sdf.ValueTypeNames.Normal3f)
                normal.ConnectToSource(image.ConnectableAPI(), "rgb")
        material.CreateSurfaceOutput().ConnectToSource(shader.ConnectableAPI(), "surface")
        return material

    def _uv_texture(self, path: str, file: str, colorspace: str, reader: Any) -> Any:
        """A ``UsdUVTexture`` reading ``file`` at the primvar ``st`` with ``sourceColorSpace = colorspace``."""
        from pxr import Sdf, UsdShade

        image = UsdShade.Shader.Define(self.stage, path)
        image.CreateIdAttr("UsdUVTexture")
        image.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(file)
        image.CreateInput("sourceColorSpace", Sdf.ValueTypeNames.Token).Set(colorspace)
        image.CreateInput("st", Sdf.ValueTypeNames.Float2).ConnectToSource(reader.ConnectableAPI(), "result")
        image.CreateOutput("rgb", Sdf.ValueTypeNames.Float3)
        return image

    def bind(self, prim: Any, material: Any) -> None:
        """Bind ``material`` to ``prim`` (``UsdShade.MaterialBindingAPI``)."""
        from pxr import UsdShade

        UsdShade.MaterialBindingAPI.Apply(prim.GetPrim()).Bind(material)

    def timeline(self, per_second: float, start: float, end: float) -> None:
        """Time codes for an animation: ``per_second`` codes (and frames) a second, from ``start`` to ``end``."""
        self.stage.SetTimeCodesPerSecond(per_second)
        self.stage.SetFramesPerSecond(per_second)
        self.stage.SetStartTimeCode(start)
        self.stage.SetEndTimeCode(end)

    def finish(self) -> bytes:
        """Stamp the generator, save the layer and return the file's bytes (the builder is spent).

        Raises:
            OutputError: usd-core did not write the layer.
        """
        layer = self.stage.GetRootLayer()
        stamp_usd(layer, self.generator)
        layer.Save()
        try:
            saved = read_cache(self._scratch)
        finally:
            self._tmp.cleanup()
        if saved is None:
            raise OutputError("usd-core did not write the stage", path=str(self.out))
        return saved

    def save(self) -> None:
        """:meth:`finish` and write the bytes to ``out`` atomically (:func:`meshtool.files.outdir.write_file`).

        Raises:
            OutputError: The layer or the file could not be written.
        """
        write_file(self.out, self.finish())
