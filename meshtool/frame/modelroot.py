"""Model roots: the folder a simulator treats as one model, so references may resolve anywhere inside it.

A Gazebo model keeps ``model.config``/``model.sdf`` at its top with ``meshes/x.obj`` whose MTL names
``../materials/textures/x.png``; a ROS package keeps ``package.xml`` (and often a URDF) at its top. The
model root of an OBJ is the nearest folder at or above the OBJ's folder that holds one of :data:`MARKERS`
(searched up to the repository root, the folder holding ``.git``, and at most :data:`MAX_MARKER_LEVELS`
levels up: ``pkg/meshes/robot/visual/high/x.obj`` is four below ``pkg/package.xml``) or a ``*.urdf`` file
(at most :data:`MAX_LEVELS` levels up); never the temporary folder, the home folder or ``/``, and never
above a repository root. References may then resolve anywhere inside it,
never outside it (except into explicit ``--search-path`` folders); paths inside it are shown relative to the
OBJ's folder (``../materials/textures/x.png``).
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from meshtool.errors import OptionsError
from meshtool.files.resolve import Resolver, list_names
from meshtool.findings import Finding, info
from meshtool.formats import URDF_SUFFIX

#: File names that mark the top folder of a model (Gazebo, SDFormat, ROS).
MARKERS = ("model.config", "model.sdf", "package.xml")
#: How many folders above the OBJ's folder are searched for a ``*.urdf`` file (``pkg/meshes/visual/x.obj``
#: is two below ``pkg/robot.urdf``).
MAX_LEVELS = 3
#: How many folders above the OBJ's folder are searched for a marker file (stopping at a repository root).
MAX_MARKER_LEVELS = 8
#: What marks a repository root: the search for a model root goes no higher.
REPOSITORY_MARKERS = (".git", ".hg", ".svn")


@dataclass(frozen=True, slots=True)
class ModelRoot:
    """A model root.

    Attributes:
        folder: The root folder (absolute, symlinks resolved).
        marker: The file that marks it (``model.config``, ``package.xml``, ``robot.urdf``...).
        kind: ``gazebo`` (model.config / model.sdf), ``ros`` (package.xml), ``urdf``, or ``explicit`` (given
            with ``--model-root``: references resolve inside it and its description files are searched for
            the mesh's consumers, but it is no evidence of the up axis).
    """

    folder: Path
    marker: str
    kind: str


def find_model_root(
    obj_dir: Path, max_levels: int = MAX_LEVELS, max_marker_levels: int = MAX_MARKER_LEVELS
) -> ModelRoot | None:
    """The nearest model root at or above ``obj_dir``, never above the repository root holding it.

    Args:
        obj_dir: Folder of the OBJ file.
        max_levels: Folders above ``obj_dir`` searched for a ``*.urdf`` file (0: only ``obj_dir``).
        max_marker_levels: Folders above ``obj_dir`` searched for a :data:`MARKERS` file.

    Returns:
        The model root, or ``None`` when no folder in reach holds a marker.
    """
    here = Path(os.path.realpath(obj_dir))
    shared = {Path(os.path.realpath(tempfile.gettempdir())), Path(os.path.realpath(Path.home())), Path("/")}
    for level, folder in enumerate([here, *here.parents][: max(max_levels, max_marker_levels) + 1]):
        if folder in shared:  # a marker dropped in /tmp or ~ must not open them up
            break
        names = list_names(folder)
        if level <= max_marker_levels:
            for marker in MARKERS:
                if marker in names and (folder / marker).is_file():
                    kind = "ros" if marker == "package.xml" else "gazebo"
                    return ModelRoot(folder, marker, kind)
        if level <= max_levels:
            urdfs = [n for n in names if n.lower().endswith(URDF_SUFFIX) and (folder / n).is_file()]
            if urdfs:
                return ModelRoot(folder, urdfs[0], "urdf")
        if any(marker in names for marker in REPOSITORY_MARKERS):  # the repository's top: nothing above it
            break
    return None


class ModelRootResolver(Resolver):
    """A :class:`~meshtool.files.resolve.Resolver` whose roots also include the model root.

    Args:
        asset_dir: The folder of the OBJ file.
        search_paths: Folders the user allows with ``--search-path``.
        model_root: The model root (an ancestor of ``asset_dir``), or ``None``.
    """

    def __init__(
        self,
        asset_dir: Path,
        search_paths: Sequence[Path] = (),
        model_root: ModelRoot | None = None,
        *,
        confine: Path | None = None,
    ) -> None:
        super().__init__(asset_dir, search_paths, confine=confine)
        self.model_root = model_root
        if model_root is not None and model_root.folder != self.asset_dir:
            self.roots.append(model_root.folder)

    def display(self, path: Path, resolved: bool = False) -> str:
        """Like :meth:`Resolver.display`; a file inside the model root only is shown relative to the OBJ."""
        real = Path(os.path.abspath(path)) if resolved else Path(os.path.realpath(path))
        inside_first = any(real == root or root in real.parents for root in self.roots[: len(self.search_paths) + 1])
        root = self.model_root.folder if self.model_root is not None else None
        if not inside_first and root is not None and (real == root or root in real.parents):
            return Path(os.path.relpath(real, self.asset_dir)).as_posix()
        return super().display(path, resolved)


def explicit_root(folder: Path, obj_dir: Path) -> ModelRoot:
    """The ``--model-root`` folder as a model root of kind ``explicit``.

    Raises:
        OptionsError: ``folder`` does not hold ``obj_dir`` (at any depth).
    """
    real = Path(os.path.realpath(folder))
    here = Path(os.path.realpath(obj_dir))
    if real != here and real not in here.parents:
        raise OptionsError(
            f"--model-root {str(folder)!r} does not hold the mesh's folder {str(obj_dir)!r}",
            hint="name a folder at or above the mesh",
        )
    return ModelRoot(real, "--model-root", "explicit")


def model_root_resolver(
    src: Path,
    search_paths: Sequence[Path] = (),
    *,
    confine: Path | None = None,
    model_root: Path | None = None,
) -> tuple[ModelRootResolver, list[Finding]]:
    """A resolver for the OBJ ``src`` that may resolve inside its model root, and a finding naming the root.

    Args:
        src: The OBJ file.
        search_paths: Folders the user allows with ``--search-path``.
        confine: See :class:`meshtool.files.resolve.Resolver`.
        model_root: ``--model-root``: the model root, instead of the one found (:func:`explicit_root`).

    Returns:
        The resolver and zero or one ``model-root`` finding (info).
    """
    root = explicit_root(model_root, src.parent) if model_root is not None else find_model_root(src.parent)
    resolver = ModelRootResolver(src.parent, search_paths, root, confine=confine)
    if root is None or root.folder == resolver.asset_dir:
        return resolver, []
    rel = Path(os.path.relpath(root.folder, resolver.asset_dir)).as_posix()
    return resolver, [
        info(
            "model-root",
            f"model root {rel!r} ({root.marker}): references may resolve anywhere inside it",
            src.name,
        )
    ]
