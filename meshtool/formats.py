"""The one registry of file formats: every mesh format meshtool reads and every file meshtool or simrun writes.

Two tables, read by everything that needs to know about a format (as :mod:`simrun.world.registry` is for scene
types):

* :data:`MESH_FORMATS`: a :class:`MeshFormat` row per input format: its name, suffixes, label, its reader
  (``module:function``, one signature for all: ``read(data, path, src, resolver) -> SourceMesh``), and how its
  unit and up axis are decided. :func:`meshtool.read.read_mesh`, the folder scans of ``obj2bin``,
  ``validate`` and ``meshtool urdf``, the up-axis defaults and the CLI help texts are derived from it.
* :data:`OUTPUTS`: an :class:`OutputFormat` row per file the project writes: name, suffixes, what it is,
  how an existing file is recognised as ours (so it may be replaced without ``--force``), how it is
  stamped, and which function writes it. :func:`meshtool.files.outdir.check_output` and
  :func:`simrun.outfile.check_output` decide overwrites through it; ``simrun replay``'s formats are its rows.

Beside them, :data:`REPORT_FORMATS` lists ``meshtool validate``'s report formats with their suffixes (a ``-o``
file without ``--format`` is told by its suffix, :func:`report_format_for`).

``docs/formats.md`` ("Formats registry") is kept in step with both tables by ``tests/test_formats_registry.py``.
Adding a mesh format is one reader module with a ``read`` function plus one row here (or a call of
:func:`register_mesh_format`); adding an output is one row. This module imports nothing but the standard
library, so any module may import it.
"""

from __future__ import annotations

import contextlib
import importlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

#: How a format's up axis is decided. ``evidence``: names, comments, geometry and consumer files, then the
#: format's fallback; ``spec``: the format's specification fixes it whoever consumes the file (glTF);
#: ``declared``: the file declares it (COLLADA ``<up_axis>``), unless a consumer file (URDF) uses the mesh as is.
UpRule = Literal["evidence", "spec", "declared"]
#: How a format's unit is decided: ``evidence`` (options, consumer files, size), ``spec`` (glTF: metres),
#: ``declared`` (COLLADA ``<unit meter>``).
UnitRule = Literal["evidence", "spec", "declared"]


@dataclass(frozen=True, slots=True)
class MeshFormat:
    """One mesh format meshtool reads.

    Attributes:
        name: Format name (``obj``, ``stl``...): ``asset.json``'s source role and the reader's ``format``.
        label: How people write it (``OBJ``, ``glTF``).
        suffixes: Lower-case file suffixes, dot included.
        reader: ``module:function`` of ``read(data: bytes, path: str, src: Path, resolver: Resolver) -> SourceMesh``
            (imported on first use).
        up: How the up axis is decided (:data:`UpRule`).
        fallback_up: ``y`` or ``z``: the up axis when the rule finds nothing.
        fallback_reason: Why, as a finding says it.
        units: How the unit is decided (:data:`UnitRule`).
        suggested_unit: A unit suggested when metres is implausible (STL from CAD: ``mm``), or ``None``.
        text: Whether the format is text (its encoding is checked by ``validate``).
    """

    name: str
    label: str
    suffixes: tuple[str, ...]
    reader: str
    up: UpRule
    fallback_up: Literal["y", "z"]
    fallback_reason: str
    units: UnitRule
    suggested_unit: str | None = None
    text: bool = False

    def read(self) -> Callable[..., Any]:
        """The reader function (its module imported now)."""
        reader: Callable[..., Any] = _resolve(self.reader)
        return reader

    def placed_up(self) -> Literal["y", "z"]:
        """The up axis a robot description (URDF) places a file of this format with.

        A URDF places its meshes as they are, in the link's Z-up frame, whatever a file declares (Assimp and
        MeshLab write COLLADA ``Y_UP`` whatever they hold); a format whose specification fixes the axis (glTF
        2.0, section 3.4 "Coordinate System and Units": Y-up) is turned as ``obj2bin`` turns it.
        """
        return "y" if self.up == "spec" and self.fallback_up == "y" else "z"


@dataclass(frozen=True, slots=True)
class OutputFormat:
    """One kind of file meshtool or simrun writes.

    Attributes:
        name: The kind (``mbin``, ``glb``...): ``simrun replay``'s format names, ``check_output``'s kinds.
        suffixes: Lower-case suffixes, the first the default.
        what: What the file holds, for docs.
        owner: ``meshtool`` or ``simrun``: the package whose writer writes it (messages name it).
        recognise: ``module:function`` of ``recognise(path: Path, size: int) -> bool``: whether an existing file
            is one of ours, so it may be replaced without ``--force``.
        stamp: How the file says it is ours (for docs), or how it is recognised when it has no room for that.
        writer: ``module:function`` that writes it.
        marked: Whether ``recognise`` checks a generator stamp (``False``: any file of the kind is replaced).
        magic: Byte prefixes of a file of the kind, for formats recognised by their magic number alone
            (``recognise`` is then empty).
    """

    name: str
    suffixes: tuple[str, ...]
    what: str
    owner: Literal["meshtool", "simrun"]
    recognise: str
    stamp: str
    writer: str
    marked: bool = True
    magic: tuple[bytes, ...] = ()

    def recogniser(self) -> Callable[[Path, int], bool]:
        """The recognising function (its module imported now)."""
        if self.magic:
            has_magic = _resolve("meshtool.files.recognise:has_magic")  # named, as every row names its code
            magic = self.magic
            return lambda path, size: bool(has_magic(path, magic))
        return _resolve(self.recognise)  # type: ignore[no-any-return]


_R = "meshtool.read."
MESH_FORMATS: list[MeshFormat] = [
    MeshFormat(
        "obj", "OBJ", (".obj",), "meshtool.read.obj.parse:read", "evidence", "y",
        "the OBJ convention (Y-up) assumed", "evidence", text=True,
    ),
    MeshFormat(
        "stl", "STL", (".stl",), _R + "stl:read", "evidence", "z",
        "STL from CAD: Z-up assumed (no other evidence)", "evidence", suggested_unit="mm",
    ),
    MeshFormat(
        "ply", "PLY", (".ply",), _R + "ply:read", "evidence", "y",
        "PLY defines no up axis; Y-up assumed, as for OBJ", "evidence",
    ),
    MeshFormat(
        "gltf", "glTF", (".gltf",), _R + "gltf:read", "spec", "y", "glTF 2.0 is Y-up by its specification", "spec"
    ),
    MeshFormat("glb", "GLB", (".glb",), _R + "gltf:read", "spec", "y", "glTF 2.0 is Y-up by its specification", "spec"),
    MeshFormat(
        "collada", "COLLADA", (".dae",), _R + "collada:read", "declared", "y",
        "COLLADA's default <up_axis> is Y_UP", "declared",
    ),
]  # fmt: skip

_W = "meshtool.files.recognise:"
OUTPUTS: list[OutputFormat] = [
    OutputFormat(
        "mbin", (".mbin",), "packed mesh (docs/mbin-spec.md)", "meshtool", _W + "is_mbin",
        "metadata `tool.name` = meshtool", "meshtool.packfile.write:pack",
    ),
    OutputFormat(
        "glb", (".glb",), "binary glTF: a pack, a scene or an animated recording", "meshtool", _W + "is_glb",
        "`asset.generator` meshtool or simrun", "meshtool.packfile.export:to_glb",
    ),
    OutputFormat(
        "gltf", (".gltf",), "glTF JSON with embedded buffers: an animated recording", "simrun", _W + "is_gltf",
        "`asset.generator` simrun, near the start", "simrun.record.replay_export:export_recording",
    ),
    OutputFormat(
        "usd", (".usda", ".usdc", ".usd"), "USD stage: a pack, a scene or an animated recording", "meshtool",
        _W + "is_usd", "`customLayerData.generator` meshtool or simrun", "meshtool.packfile.usd:export_usd",
    ),
    OutputFormat(
        "msh", (".msh",), "MuJoCo's legacy binary mesh, beside an MJCF", "meshtool", _W + "is_msh",
        "no room: the four counts must account for the size exactly", "meshtool.packfile.export:to_msh", False,
    ),
    OutputFormat(
        "obj", (".obj",), "Wavefront OBJ: a mesh beside an MJCF, or a normalised asset's mesh", "meshtool",
        _W + "is_obj", "a first comment line naming meshtool or simrun", "simrun.export.mjcf_builder:folder_files",
    ),
    OutputFormat(
        "mjcf", (".xml",), "MJCF model", "simrun", _W + "is_mjcf",
        "no room: root element `<mujoco>`", "simrun.export.mjcf_builder:build_files", False,
    ),
    OutputFormat(
        "mjz", (".mjz",), "zip of an MJCF folder", "simrun", "",
        "no room: zip magic number", "simrun.world.archive:save_mjz", False, (b"PK\x03\x04",),
    ),
    OutputFormat(
        "html", (".html", ".htm"), "recording player page", "simrun", _W + "is_html",
        '`<meta name="generator">` simrun, near the start', "simrun.record.replay_export:export_recording",
    ),
    OutputFormat(
        "png", (".png",), "rendered image", "simrun", "",
        "no room: PNG magic number", "simrun.run.session:run_play", False, (b"\x89PNG\r\n\x1a\n",),
    ),
    OutputFormat(
        "gif", (".gif",), "rendered animation", "simrun", "",
        "no room: GIF magic number", "simrun.run.play:encode_gif", False, (b"GIF87a", b"GIF89a"),
    ),
    OutputFormat(
        "mp4", (".mp4",), "rendered video", "simrun", _W + "is_mp4",
        "no room: `ftyp` box", "simrun.run.play:encode_mp4", False,
    ),
    OutputFormat(
        "simlog", (".simlog",), "recording (docs/recordings.md)", "simrun", "",
        "no room: .simlog magic line", "simrun.record.simlog:Recorder", False, (b"\x89SIMLOG\n",),
    ),
    OutputFormat(
        "mcap", (".mcap",), "a recording as MCAP messages (poses, odometry, sensors) for Foxglove", "simrun", "",
        "no room: MCAP magic number", "simrun.record.mcap_export:export_mcap", False, (b"\x89MCAP0\r\n",),
    ),
]  # fmt: skip


#: Robot and world descriptions that may name a mesh (consumer files: their scale, units and placement are
#: evidence for the mesh's frame), by suffix: URDF, SDFormat (``.sdf``, ``.world``), and ``.xml``, which may
#: hold either (or MJCF).
DESCRIPTION_SUFFIXES: tuple[str, ...] = (".urdf", ".sdf", ".xml", ".world")
#: The URDF's own suffix among them (a ROS package's robot: :mod:`meshtool.frame.modelroot`).
URDF_SUFFIX = DESCRIPTION_SUFFIXES[0]
#: An OBJ's material library (written beside the OBJ by ``normalize`` and ``unpack``).
MTL_SUFFIX = ".mtl"
#: Images a material may name or a glTF file embed, by MIME type (glTF 2.0, 3.9.1 "Images"; KHR_texture_basisu
#: and EXT_texture_webp add the last two), with the suffix an embedded image is named by. PNG is the output row's.
IMAGE_SUFFIXES: dict[str, str] = {
    "image/png": next(row for row in OUTPUTS if row.name == "png").suffixes[0],
    "image/jpeg": ".jpg",
    "image/webp": ".webp",
    "image/ktx2": ".ktx2",
}
#: Files a mesh may read besides itself (materials, textures, glTF buffers) or be read by (URDF, xacro):
#: ``validate``'s reports list them as the inputs of an asset.
COMPANION_SUFFIXES: tuple[str, ...] = (
    MTL_SUFFIX,
    ".bin",
    IMAGE_SUFFIXES["image/png"],
    IMAGE_SUFFIXES["image/jpeg"],
    ".jpeg",
    ".tga",
    ".bmp",
    URDF_SUFFIX,
    ".xacro",
)


@dataclass(frozen=True, slots=True)
class ReportFormat:
    """One report format of ``meshtool validate`` (``--format``; ``-o FILE`` without it is told by suffix).

    Attributes:
        name: The ``--format`` value (``json``, ``junit``...).
        suffixes: Lower-case suffixes a report file of this format is named with, the first the usual one;
            empty for a format read from stdout (GitHub annotations).
        what: What the report is, for help texts and docs.
    """

    name: str
    suffixes: tuple[str, ...]
    what: str


#: The reports of ``meshtool validate``, in ``--format`` order. A report's suffix may be an output's too (a
#: JUnit ``.xml`` is no MJCF): :func:`report_format_for` reads only this table.
REPORT_FORMATS: list[ReportFormat] = [
    ReportFormat("text", (".txt",), "the human report: findings grouped worst first, then the verdict"),
    ReportFormat("json", (".json",), "one JSON document (docs/validate-report.schema.json)"),
    ReportFormat("junit", (".xml",), "JUnit XML: one testcase per asset"),
    ReportFormat("github", (), "GitHub Actions workflow commands: an annotation per finding"),
    ReportFormat("html", (".html", ".htm"), "one self-contained page, a card (and thumbnail) per asset"),
]


def report_format_for(path: Path | str) -> ReportFormat | None:
    """The report format a ``-o`` file's suffix names (case-insensitive), ``None`` for another suffix."""
    suffix = Path(path).suffix.lower()
    return next((row for row in REPORT_FORMATS if suffix in row.suffixes), None)


def _resolve(target: str) -> Any:
    module, _, name = target.partition(":")
    value: Any = importlib.import_module(module)
    for part in name.split("."):
        value = getattr(value, part)
    return value


def mesh_suffixes() -> tuple[str, ...]:
    """Every suffix meshtool reads as a mesh, in registry order."""
    return tuple(s for row in MESH_FORMATS for s in row.suffixes)


def mesh_format(path: Path | str) -> MeshFormat | None:
    """The row of ``path``'s suffix (case-insensitive), ``None`` for a suffix no reader takes."""
    suffix = Path(path).suffix.lower()
    return next((row for row in MESH_FORMATS if suffix in row.suffixes), None)


def mesh_format_named(name: str) -> MeshFormat:
    """The row named ``name`` (``KeyError`` for an unknown one)."""
    for row in MESH_FORMATS:
        if row.name == name:
            return row
    raise KeyError(name)


def mesh_labels() -> str:
    """The input formats as help texts name them: ``OBJ, STL, PLY, glTF, GLB, COLLADA``."""
    return ", ".join(row.label for row in MESH_FORMATS)


def output_named(name: str) -> OutputFormat:
    """The output row named ``name`` (``KeyError`` for an unknown one)."""
    for row in OUTPUTS:
        if row.name == name:
            return row
    raise KeyError(name)


def output_for(path: Path | str) -> OutputFormat | None:
    """The output row of ``path``'s suffix, ``None`` when nothing the project writes has it."""
    suffix = Path(path).suffix.lower()
    return next((row for row in OUTPUTS if suffix in row.suffixes), None)


def suffix(name: str) -> str:
    """The default suffix of output ``name`` (``.mbin``...): its own name's, else its first."""
    suffixes = output_named(name).suffixes
    return f".{name}" if f".{name}" in suffixes else suffixes[0]


def check_suffix(path: Path, name: str) -> str | None:
    """``None`` when ``path`` has a suffix of output ``name``, else why not (``USD output must end in ...``)."""
    row = output_named(name)
    if path.suffix.lower() in row.suffixes:
        return None
    listed = " or ".join(row.suffixes) if len(row.suffixes) < 3 else ", ".join(row.suffixes[:-1])
    if len(row.suffixes) >= 3:
        listed += f" or {row.suffixes[-1]}"
    return f"{row.name.upper() if row.name != 'mjcf' else 'MJCF'} output must end in {listed}"


@contextlib.contextmanager
def register_mesh_format(row: MeshFormat) -> Iterator[MeshFormat]:
    """Within the block, ``row`` is a mesh format like the built-in ones (plug-ins and tests).

    Raises:
        ValueError: A suffix or name some row already has.
    """
    taken = set(mesh_suffixes())
    if any(s in taken for s in row.suffixes) or any(r.name == row.name for r in MESH_FORMATS):
        raise ValueError(f"mesh format {row.name!r}: its name or a suffix is registered already")
    MESH_FORMATS.append(row)
    try:
        yield row
    finally:
        MESH_FORMATS.remove(row)
