"""Assets of a world, loaded once and added to the spec from memory (no temporary files).

``.mbin`` meshes become MjSpec meshes from their arrays, handed to MuJoCo as in-memory ``.msh`` files (its
binary mesh format: positions, normals, texture coordinates and faces cast once into one buffer, read by
MuJoCo's C++ with no per-element conversion; :func:`msh_bytes`), their PNG textures become MjSpec textures
from decoded pixels, and their materials MjSpec materials. One asset used by many entities is read and
added once.

A mesh file (OBJ, STL, PLY, glTF/GLB, COLLADA) where an ``.mbin`` can go is packed on the fly as ``obj2bin``
does with its defaults (metres, ``--up auto``, one convex hull; :func:`meshtool.pipeline.pack_file`) and the
pack kept in the user cache folder (``simrun/packs``, one :mod:`meshtool.files.cachefile` envelope per file) until
the mesh, its MTLs or textures change.
"""

from __future__ import annotations

import hashlib
import io
import os
import stat
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt
import xxhash
from PIL import Image

import meshtool
from meshtool.files import cachefile
from meshtool.files.safeopen import printable
from meshtool.formats import suffix
from meshtool.hulls import surface
from meshtool.packfile import PackedMesh, parse
from meshtool.packfile.read import load_descriptor
from meshtool.packfile.view import asset_view, unique_name
from meshtool.repair.pnginfo import png_end
from simrun.errors import EntityError
from simrun.safeio import FileReadError, check_regular, open_regular, read_regular

#: Largest texture or height-field image file read, bytes.
MAX_IMAGE_BYTES = 64 * 1024 * 1024
#: Most pixels of a decoded texture or height-field image (8192 x 8192).
MAX_IMAGE_PIXELS = 8192 * 8192
#: Entry kind of a mesh file's pack in the :mod:`meshtool.files.cachefile` envelope.
PACK_KIND = "simrun-mesh-pack"
#: Largest cached pack read, bytes (the limit on an ``.mbin`` read whole).
MAX_PACK_BYTES = 1024**3


@dataclass(slots=True)
class MeshAsset:
    """Names of what one ``.mbin`` added to the spec, and the volumes of its hulls (m^3, scaled).

    The volumes are computed when first read (:attr:`hull_volumes`): only an entity given a mass needs them.
    """

    name: str
    visual: list[tuple[str, str | None]]  # (mesh name, material name) per submesh
    hulls: list[str]
    #: (vertices (n, 3) m unscaled, faces (k, 3)) per hull, and the scale, for :attr:`hull_volumes`.
    hull_arrays: list[tuple[npt.NDArray[Any], npt.NDArray[Any]]]
    scale: float
    whole: str  # name for the whole mesh in one piece (added by :meth:`AssetLibrary.whole` when needed)
    _volumes: list[float] | None = None

    @property
    def hull_volumes(self) -> list[float]:
        """Each hull's enclosed volume times ``scale**3``, m^3 (computed once)."""
        if self._volumes is None:
            self._volumes = [surface.volume(v, f) * self.scale**3 for v, f in self.hull_arrays]
        return self._volumes


@dataclass(slots=True)
class AssetLibrary:
    """Per-build registry of assets added to one spec; the decoded files are kept across builds."""

    spec: mujoco.MjSpec
    files: dict[Path, PackedMesh] = field(default_factory=dict)
    images: dict[Path, bytes] = field(default_factory=dict)
    #: Other files builds read, by real path: what an import read (a URDF robot's URDF, meshes, MTL, textures).
    sources: set[Path] = field(default_factory=set)
    added_meshes: dict[tuple[Path, float], MeshAsset] = field(default_factory=dict)
    #: The names of ``added_meshes``' assets (kept beside it: a set rebuilt per added file made N files O(N^2)).
    mesh_names: set[str] = field(default_factory=set)
    added_textures: dict[Path, str] = field(default_factory=dict)
    added_whole: set[str] = field(default_factory=set)
    #: In-memory files (MuJoCo's virtual file system) handed to the spec: PNG textures by file name.
    vfs: dict[str, bytes] = field(default_factory=dict)
    #: 2D textures by content (XXH3-128 of the PNG): identical images are added, and decoded by MuJoCo, once.
    by_content: dict[bytes, tuple[str, str]] = field(default_factory=dict)

    #: Each asset path as given, resolved (symlinks, ``..``) once: many entities name one file.
    resolved: dict[Path, Path] = field(default_factory=dict)

    #: Each folder of those paths (its text, as ``str(path.parent)`` spells it), resolved once (:meth:`real`).
    resolved_dirs: dict[str, Path] = field(default_factory=dict)

    def real(self, path: Path) -> Path:
        """``path`` resolved (as ``Path.resolve``), once per path.

        A file that is not a symbolic link resolves to its resolved folder joined with its name, so each
        folder is resolved once and each file costs one ``lstat`` (many entities name distinct files of one
        folder); a link, a missing file or a name such as ``..`` is resolved in full.
        """
        key = self.resolved.get(path)
        if key is None:
            key = self.resolved[path] = self._resolve(path)
        return key

    def _resolve(self, path: Path) -> Path:
        """:meth:`real` of a path not seen before.

        Worked on the path's text (``str`` of a ``Path`` is normalised: no empty, ``.`` or trailing parts),
        with ``os.path.realpath`` for the folder: ``Path.resolve`` is that plus a ``stat`` that only detects a
        symlink loop, and the folder of a file whose ``lstat`` succeeded has none (the kernel walked it).
        """
        text = os.fspath(path)
        folder_text, slash, name = text.rpartition("/")
        if name in ("", ".", "..") or os.sep != "/":  # (another system's separators and drives: resolve())
            return path.resolve()
        try:
            if stat.S_ISLNK(os.lstat(text).st_mode):
                return path.resolve()
        except (OSError, ValueError):  # missing, unreadable folder, a NUL in the name: as resolve() has it
            return path.resolve()
        if not slash:
            folder_text = "."
        elif not folder_text:
            folder_text = "/"  # a file of the root folder (one leading slash: Path keeps "//" alone)
        folder = self.resolved_dirs.get(folder_text)
        if folder is None:
            folder = self.resolved_dirs[folder_text] = Path(os.path.realpath(folder_text))
        return folder / name

    def register(self, path: Path, packed: PackedMesh) -> None:
        """Use ``packed`` (already in memory) as the content of ``path``; nothing is read from disk."""
        self.files[self.real(path)] = packed

    def packed(self, path: Path) -> PackedMesh:
        """The loaded ``.mbin``, or the pack of a mesh file (read, or packed, once)."""
        return self._packed(self.real(path))

    def _packed(self, key: Path) -> PackedMesh:
        """:meth:`packed` of the resolved path ``key``."""
        found = self.files.get(key)
        if found is not None:
            return found
        try:
            if is_mesh_file(key):
                check_regular(key, "mesh asset")  # never hand a FIFO or device to the reader
                found = self._pack(key)
            else:  # opened once, refused here when not a regular file; the reader reads that descriptor
                with open_regular(key, "mesh asset") as file:
                    found = load_descriptor(file.fileno(), key)
        except FileReadError as exc:
            raise EntityError(str(exc)) from None
        except meshtool.MeshtoolError as exc:
            raise EntityError(f"cannot load mesh asset: {exc.one_line()}") from None
        self.files[key] = found
        return found

    def _pack(self, src: Path) -> PackedMesh:
        """The pack of the mesh file ``src`` (resolved): from the cache when it is current, else made and cached."""
        from meshtool.pipeline import ConvertOptions, is_current, pack_file

        options = ConvertOptions(check=False)  # the world's compile checks it
        folder = pack_cache()
        key = f"{meshtool.__version__}\0{src}"
        entry = folder / f"{hashlib.sha256(key.encode('utf-8', 'surrogateescape')).hexdigest()}.pack"
        found = cachefile.read_entry(entry, PACK_KIND, key, MAX_PACK_BYTES)
        if found.payload is not None:
            try:
                cached = parse(found.payload, src.name)
            except meshtool.MeshtoolError:
                cached = None
            if cached is not None and is_current(cached.pack_meta, src, options):
                self.sources.update(_pack_sources(cached, src))
                return cached
        made = pack_file(src, options)
        cachefile.write_entry(entry, PACK_KIND, key, made.data)  # a read-only cache costs time, nothing else
        self.sources.update(made.inputs)
        return parse(made.data, src.name)

    def mesh(self, path: Path, scale: float) -> MeshAsset:
        """Add an ``.mbin``'s (or a mesh file's) meshes, textures and materials (once per file and scale)."""
        real = self.real(path)
        key = (real, scale)
        known = self.added_meshes.get(key)
        if known is not None:
            return known
        view = asset_view(self._packed(real))  # parts, materials and textures as every consumer reads a pack
        stem = printable(path.stem)  # MuJoCo names are UTF-8: a non-UTF-8 file name's bytes become \xNN
        base = unique_name(f"{stem}@{scale:g}" if scale != 1.0 else stem, self.mesh_names)
        textures = []
        for k, texture in enumerate(view.textures):
            png = png_without_tail(texture.data, f"{printable(path.name)}: texture {k}")
            textures.append(self.add_texture(f"{base}/tex{k}", png))
        materials = []
        for k, m in enumerate(view.materials):
            mat = self.spec.add_material(name=f"{base}/mat{k}", rgba=list(m.rgba))
            if m.colour_map is not None:
                mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = textures[m.colour_map]
            materials.append(mat.name)
        visual = []
        for part in view.parts:
            mesh = self.spec.add_mesh(
                name=f"{base}/visual{part.index}",
                file=self.add_mesh_file(part.positions, part.faces, part.normals, part.uvs),
                scale=[scale] * 3,
                inertia=mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL,
            )
            visual.append((mesh.name, materials[part.material] if materials else None))
        hulls = []
        for k, (v, f) in enumerate(view.hulls):
            hull = self.spec.add_mesh(
                name=f"{base}/hull{k}",
                file=self.add_mesh_file(v, f),
                scale=[scale] * 3,
                inertia=mujoco.mjtMeshInertia.mjMESH_INERTIA_CONVEX,
            )
            hulls.append(hull.name)
        asset = MeshAsset(base, visual, hulls, list(view.hulls), scale, f"{base}/whole")
        self.added_meshes[key] = asset
        self.mesh_names.add(base)
        return asset

    def whole(self, path: Path, scale: float) -> str:
        """The whole mesh of an added ``.mbin`` as one MjSpec mesh (for ``collision="convex"``), added once."""
        asset = self.mesh(path, scale)
        if asset.whole not in self.added_whole:
            p = self.packed(path)
            whole = self.spec.add_mesh(name=asset.whole)
            whole.file = self.add_mesh_file(p.positions, p.indices)
            whole.scale = [scale] * 3
            whole.inertia = mujoco.mjtMeshInertia.mjMESH_INERTIA_CONVEX
            self.added_whole.add(asset.whole)
        return asset.whole

    def add_mesh_file(
        self,
        positions: npt.ArrayLike,
        faces: npt.ArrayLike,
        normals: npt.ArrayLike | None = None,
        uvs: npt.ArrayLike | None = None,
    ) -> str:
        """Mesh arrays as a MuJoCo ``.msh`` file in the spec's virtual file system; returns its file name.

        MuJoCo's Python bindings convert ``uservert``/``userface``/... element by element (about 90 ns per
        number, 17 ms for a 69k-triangle mesh); an in-memory ``.msh`` is read by MuJoCo's C++ with one copy.
        The arrays are written once into the file's bytes, cast to MuJoCo's float32/int32 (no other copy).
        The name is the content's XXH3-128: MuJoCo caches meshes by file name, so one name is always one
        mesh, and the same arrays added again (another build or world, another scale or inertia mode: MuJoCo
        applies those after its cache) are MuJoCo's cache hit.

        Args:
            positions: (n, 3) vertices, metres (unscaled: the spec mesh's ``scale`` applies).
            faces: (m, 3) vertex indices, counter-clockwise.
            normals: (n, 3) per-vertex normals, or ``None`` (MuJoCo computes them).
            uvs: (n, 2) texture coordinates in the OBJ/``.mbin`` convention (``v = 0`` at the image bottom),
                or ``None``; stored as MuJoCo's ``1 - v``.
        """
        data = msh_bytes(positions, faces, normals, uvs)
        name = f"{xxhash.xxh3_128_hexdigest(data)}{suffix('msh')}"
        self.vfs[name] = data
        return name

    def texture_material(self, file: str, base_dir: Path) -> str:
        """A material showing the PNG ``file`` (relative to ``base_dir``), added once."""
        path = self.real(base_dir / file)
        if path not in self.added_textures:
            name = f"texture:{printable(path.stem)}"
            tex = self.add_texture(name, self.read_image(path, file))
            mat = self.spec.add_material(name=f"{name}/material")
            mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = tex
            self.added_textures[path] = mat.name
        return self.added_textures[path]

    def read_image(self, path: Path, shown: str) -> bytes:
        """The bytes of a PNG file, read once and checked to decode."""
        if path not in self.images:
            data = png_without_tail(read_image_file(path, shown), f"texture {shown!r}")
            _decode(data)
            self.images[path] = data
        return self.images[path]

    def add_texture(self, name: str, png: bytes, kind: Any = None) -> str:
        """A texture from PNG bytes held in the spec's virtual file system (no file is written).

        Returns:
            The texture's name: ``name``, or for a 2D image already added (the same bytes) that texture's
            name, so that MuJoCo decodes each distinct image once.
        """
        two_d = kind is None or kind == mujoco.mjtTexture.mjTEXTURE_2D
        key = xxhash.xxh3_128_digest(png) if two_d else b""
        known = self.by_content.get(key) if two_d else None
        if known is not None and self.vfs[known[1]] == png:
            return known[0]
        file = f"{len(self.vfs)}_{''.join(c if c.isalnum() else '_' for c in name)}{suffix('png')}"
        self.vfs[file] = png
        self.spec.add_texture(name=name, type=kind if kind is not None else mujoco.mjtTexture.mjTEXTURE_2D, file=file)
        if two_d:
            self.by_content.setdefault(key, (name, file))
        return name


def msh_bytes(
    positions: npt.ArrayLike,
    faces: npt.ArrayLike,
    normals: npt.ArrayLike | None = None,
    uvs: npt.ArrayLike | None = None,
) -> bytes:
    """MuJoCo's binary ``.msh`` of mesh arrays (shapes as :meth:`AssetLibrary.add_mesh_file`).

    Layout (little-endian): int32 counts ``nvert, nnormal, ntexcoord, nface``, then float32 positions
    (3 nvert), normals (3 nnormal), texture coordinates (2 ntexcoord, ``v`` flipped to MuJoCo's top-origin
    convention) and int32 faces (3 nface). Arrays already float32/int32 are not converted; the pieces are
    joined once (about 3.5 us for a 1k-triangle mesh, where assigning into one buffer through views took 11).
    """
    v = np.asarray(positions).reshape(-1, 3)
    f = np.asarray(faces).reshape(-1, 3)
    pieces = [b"", v.astype(_F4, copy=False).tobytes(), b"", b"", f.astype(_I4, copy=False).tobytes()]
    n_normals = n_uvs = 0
    if normals is not None:
        n = np.asarray(normals).reshape(-1, 3)
        n_normals = n.shape[0]
        pieces[2] = n.astype(_F4, copy=False).tobytes()
    if uvs is not None:
        t = np.asarray(uvs).reshape(-1, 2)
        n_uvs = t.shape[0]
        texcoords = np.empty((n_uvs, 2), _F4)
        texcoords[:, 0] = t[:, 0]
        np.subtract(np.float32(1.0), t[:, 1], out=texcoords[:, 1], casting="unsafe")
        pieces[3] = texcoords.tobytes()
    pieces[0] = np.array([v.shape[0], n_normals, n_uvs, f.shape[0]], _I4).tobytes()
    return b"".join(pieces)


_F4 = np.dtype("<f4")
_I4 = np.dtype("<i4")


def is_mesh_file(path: Path) -> bool:
    """Whether ``path`` names a mesh file meshtool packs (OBJ, STL, PLY, glTF/GLB, COLLADA), by its suffix."""
    from meshtool.read import MESH_SUFFIXES

    return path.suffix.lower() in MESH_SUFFIXES


def pack_cache() -> Path:
    """The folder of packed mesh files: ``simrun/packs`` in the user cache folder (``XDG_CACHE_HOME``)."""
    import platformdirs

    return Path(platformdirs.user_cache_dir("simrun")) / "packs"


def _pack_sources(packed: PackedMesh, src: Path) -> list[Path]:
    """The files a cached pack of ``src`` was made from (the mesh, its MTLs and textures), as its metadata says."""
    return [p for p in packed.pack_meta.source_files([src.parent]) if p.is_file()]


def read_image_file(path: Path, shown: str) -> bytes:
    """The bytes of an image file (a regular file of at most :data:`MAX_IMAGE_BYTES`).

    Raises:
        EntityError: It cannot be read, is not a regular file (a FIFO, device...) or is too large.
    """
    try:
        return read_regular(path, f"image {shown!r}", MAX_IMAGE_BYTES)
    except FileReadError as exc:
        raise EntityError(str(exc)) from None


def png_without_tail(data: bytes, shown: str) -> bytes:
    """``data`` when it is not a PNG or ends with its ``IEND`` chunk; refused when bytes follow ``IEND``.

    Textures are handed to MuJoCo and copied into exports byte for byte: bytes after the image (a PNG
    followed by 20 MB of zeros) would be copied too. meshtool cuts them when it converts a texture
    (``texture-trailing-data``); simrun, which has no findings channel, refuses the file.

    Raises:
        EntityError: Bytes follow the PNG's ``IEND`` chunk (the message gives their count and offset).
    """
    end = png_end(data)
    if end is not None and end < len(data):
        raise EntityError(
            f"{shown}: {len(data) - end} bytes after the end of the PNG image (from byte {end}); "
            "re-save the image without them (meshtool normalize cuts them)"
        )
    return data


def open_image(data: bytes, shown: str = "texture") -> Image.Image:
    """A decoded image, refusing images over :data:`MAX_IMAGE_PIXELS` before decoding their pixels.

    Raises:
        EntityError: Not a readable image, or too many pixels.
    """
    try:
        image = Image.open(io.BytesIO(data))
        if image.width * image.height > MAX_IMAGE_PIXELS:
            raise EntityError(
                f"{shown} is {image.width} x {image.height} pixels, over the limit of {MAX_IMAGE_PIXELS} pixels"
            )
        image.load()
    except (OSError, ValueError, Image.DecompressionBombError) as exc:
        raise EntityError(f"{shown} is not a readable image ({exc})") from None
    return image


def _decode(png: bytes) -> tuple[int, int, int, bytes]:
    """(width, height, channels, pixel bytes) of an image, RGB or RGBA, rows top to bottom."""
    image = open_image(png)
    mode = "RGBA" if image.mode in ("RGBA", "LA", "PA") or "transparency" in image.info else "RGB"
    converted = image.convert(mode)
    return converted.width, converted.height, len(mode), converted.tobytes()
