"""Consumer files: the URDF, SDF and MJCF files that use a mesh, and what they say about it.

A robot or world description that references a mesh fixes two things the mesh cannot say: its frame (URDF,
SDFormat and MJCF are all Z-up, and use the mesh's coordinates as they are) and its unit (the file's
``scale``: ``0.001`` means the mesh is in millimetres).

Where projects keep them: vendors put the model two or more folders above its meshes
(``robots/NAME/robot.xml`` over ``meshes/PART/part.obj`` and ``meshes/convex/PART/part.obj``). The search
walks up from the mesh's folder to its *index root* (:func:`find_index_root`): an explicit ``--model-root``,
else the nearest folder at most :data:`MAX_ROOT_LEVELS` levels up that holds ``package.xml`` (ROS),
``model.config`` / ``model.sdf`` (Gazebo) or ``.git`` / ``.hg`` / ``.svn`` (a repository), or that is a
Python package's top folder (its parent is ``site-packages``: pip-installed models such as dm_control's);
never the temporary folder, the home folder or ``/``. Without one, a urdf model root
(:func:`meshtool.frame.modelroot.find_model_root`) is indexed whole; else the *nearby* search: the folder above the
mesh's folder with its subfolders (``robot/urdf/`` beside ``robot/meshes/``) and, while that holds no
description file, up to :data:`MAX_NEARBY_LEVELS` levels up (level L read L folders deep).

Every description file under the root is read once (:class:`~meshtool.frame.consumer_index.ConsumerIndex`,
keyed by root, built on the first mesh that needs it and reused by every later mesh under the same root; kept
while nothing under the root changes; bounded by ``MAX_FILES``, ``MAX_TOTAL_BYTES``, ``MAX_DEPTH`` and
``MAX_ENTRIES``, ``docs/limits.md``): each reference is resolved to the file it names, so the index maps mesh
file -> the consumers using it.

References resolve as their consumer resolves them: URDF and SDFormat relative to the file, ``package://NAME``
/ ``model://NAME`` in the ancestor folder named ``NAME`` (or whose ``package.xml`` names it, or beside one),
else by the path's tail from inside the folder that package would be; MJCF as MuJoCo does, ``<include
file>`` relative to the main file's folder and spliced in, mesh ``file`` relative to ``<compiler meshdir>``
(``assetdir`` where no ``meshdir`` is given, else the main file's folder; beside the included file when not
found there; ``strippath``), with ``<default>`` classes' mesh ``scale``, by the one MJCF reading simrun uses
too (:mod:`meshtool.files.mjcf_xml`).

Three modules: this one (the references a mesh has, ranked, and the frame conflict), the index
(:mod:`meshtool.frame.consumer_index`: roots, the walk, the cache, the bounds) and the per-format readers
(:mod:`meshtool.frame.consumer_refs`). Description files are read bounded and parsed by lxml with no DTD and
no entities; a file that does not parse is skipped.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from meshtool.findings import Finding, warning
from meshtool.frame.consumer_index import (
    INDEX,
    MAX_BYTES,
    MAX_DEPTH,
    MAX_ENTRIES,
    MAX_FILES,
    MAX_NEARBY_ENTRIES,
    MAX_NEARBY_LEVELS,
    MAX_ROOT_LEVELS,
    MAX_TOTAL_BYTES,
    PYTHON_PACKAGE_FOLDERS,
    RACY_SECONDS,
    SUFFIXES,
    ConsumerIndex,
    IndexRoot,
    find_index_root,
    shared_folders,
)
from meshtool.frame.consumer_refs import MAX_INCLUDES, Scale, Use
from meshtool.frame.modelroot import ModelRoot

__all__ = [
    "INDEX",
    "MAX_BYTES",
    "MAX_DEPTH",
    "MAX_ENTRIES",
    "MAX_FILES",
    "MAX_INCLUDES",
    "MAX_NEARBY_ENTRIES",
    "MAX_NEARBY_LEVELS",
    "MAX_ROOT_LEVELS",
    "MAX_TOTAL_BYTES",
    "PYTHON_PACKAGE_FOLDERS",
    "RACY_SECONDS",
    "READS_NO_MATERIALS",
    "SUFFIXES",
    "ConsumerIndex",
    "ConsumerRef",
    "IndexRoot",
    "Scale",
    "consumers_and_limit",
    "find_consumers",
    "find_index_root",
    "frame_conflict",
    "printable_root",
]

#: Consumer formats whose loaders never read an OBJ's MTL or the textures it names (MuJoCo: ``docs/findings.md``).
READS_NO_MATERIALS = ("mjcf",)


@dataclass(frozen=True, slots=True)
class ConsumerRef:
    """One reference to the mesh in a description file.

    Attributes:
        file: The description file, relative to the mesh's folder (``../../robots/arm/robot.xml``).
        format: ``urdf``, ``sdf`` or ``mjcf``.
        scale: The (x, y, z) scale the file applies, or ``None`` when it gives none (that is 1 1 1).
        ref: The reference as written.
    """

    file: str
    format: str
    scale: Scale | None
    ref: str

    def describe(self) -> str:
        """``robot.urdf (URDF, scale 0.001 0.001 0.001)``."""
        scale = " ".join(_num(s) for s in self.scale) if self.scale else "none"
        return f"{self.file} ({self.format.upper()}, scale {scale})"

    @property
    def frame(self) -> str:
        """The frame the consumer uses the mesh in: every consumer format is Z-up, so its scale tells them apart.

        ``Z-up, scale 0.001 0.001 0.001`` (no scale reads as ``1 1 1``).
        """
        return "Z-up, scale " + " ".join(_num(s) for s in (self.scale or (1.0, 1.0, 1.0)))

    @property
    def reads_materials(self) -> bool:
        """Whether the consumer's loader reads the OBJ's MTL and textures (MuJoCo's MJCF compiler does not)."""
        return self.format not in READS_NO_MATERIALS


def find_consumers(obj: Path, root: ModelRoot | None, index: ConsumerIndex | None = None) -> list[ConsumerRef]:
    """Every reference to ``obj`` in the description files under its index root, nearest file first.

    Args:
        obj: The mesh file.
        root: Its model root (or an ``explicit`` one from ``--model-root``), or ``None``.
        index: The index to use (default: the run's, :data:`INDEX`).

    Returns:
        The references, ordered by how many folders separate the file from the mesh's folder, then by path.
    """
    refs, _ = consumers_and_limit(obj, root, index)
    return refs


def consumers_and_limit(
    obj: Path, root: ModelRoot | None, index: ConsumerIndex | None = None
) -> tuple[list[ConsumerRef], str | None]:
    """:func:`find_consumers` and the limit that stopped the index (a sentence), or ``None``."""
    iroot = find_index_root(obj.parent, root)
    uses, built = (index or INDEX).lookup(obj, iroot)
    here = Path(os.path.realpath(obj.parent))
    if iroot.kind == "nearby":  # no root: climb while no description file is in sight (robot/urdf/ above)
        shared = shared_folders()
        level = iroot.depth
        while not built.files and built.limit is None and 0 < level < MAX_NEARBY_LEVELS:
            level += 1
            up = [here, *here.parents][level] if level < len(here.parts) else None
            if up is None or up in shared:
                break
            iroot = IndexRoot(up, "nearby", "", level)
            uses, built = (index or INDEX).lookup(obj, iroot)
        if built.limit is not None and iroot.kind == "nearby":
            return _ranked(uses, here), None  # a heuristic reach, not a root: no warning
    limit = None if built.limit is None else f"{printable_root(iroot)}: {built.limit}"
    return _ranked(uses, here), limit


def _ranked(uses: Sequence[Use], here: Path) -> list[ConsumerRef]:
    """The uses as references shown relative to ``here``, nearest first, without repeats."""
    seen: set[tuple[str, str, Scale | None]] = set()
    ranked: list[tuple[int, str, ConsumerRef]] = []
    for use in uses:
        shown = Path(os.path.relpath(use.file, here)).as_posix()
        if (shown, use.ref, use.scale) in seen:
            continue
        seen.add((shown, use.ref, use.scale))
        distance = len(Path(shown).parts) - 1  # folders up plus folders down
        ranked.append((distance, shown, ConsumerRef(shown, use.format, use.scale, use.ref)))
    ranked.sort(key=lambda r: (r[0], r[1]))
    return [r[2] for r in ranked]


def printable_root(root: IndexRoot) -> str:
    """``/path/to/root (repository, .git)`` for messages."""
    what = f"{root.kind}, {root.marker}" if root.marker else root.kind
    return f"{root.folder.as_posix()} ({what})"


def frame_conflict(consumers: Sequence[ConsumerRef], path: str | None) -> Finding | None:
    """A ``consumer-frames-differ`` warning when two consumer files use the mesh in different frames.

    One file using the mesh at several scales (a URDF mirroring one STL for two links) places each use
    itself; two files disagreeing leave ``obj2bin`` one frame to choose.

    Args:
        consumers: The mesh's consumers (:func:`find_consumers`).
        path: The mesh as findings name it.

    Returns:
        The warning (naming one file per frame; the first, nearest one is the frame applied), or ``None``.
    """
    if not any(a.file != b.file and a.frame != b.frame for a in consumers for b in consumers):
        return None
    frames: dict[str, ConsumerRef] = {}
    for ref in consumers:
        frames.setdefault(ref.frame, ref)
    listed = "; ".join(f"{ref.file} uses it {frame}" for frame, ref in frames.items())
    first = consumers[0]
    return warning(
        "consumer-frames-differ",
        f"consumers use the mesh in {len(frames)} different frames ({listed}): applied {first.file}'s",
        path,
    )


def _num(value: float) -> str:
    text = repr(float(value))
    return text[:-2] if text.endswith(".0") else text
