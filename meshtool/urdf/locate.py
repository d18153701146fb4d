"""Where a URDF's mesh references lead, and reading them race-free: ``package://``, relative and ``file://``.

A mesh is found and read in one step (:meth:`MeshLocator.read`): the reference is turned into a path inside
an allowed folder (the robot's own package, a ``--package-dir`` mapping, or with ``--allow-outside`` the
mesh's own folder), then read through :class:`meshtool.files.resolve.Resolver`, which walks from that folder one
component at a time with ``O_NOFOLLOW``. A symbolic link swapped in after the check makes the read fail; no
byte from outside the folder is ever returned, and the bytes handed on are the bytes that were checked.

``package://NAME/...`` resolves, by default, only inside the robot's own package: the nearest folder at or
above the URDF (at most :data:`meshtool.frame.modelroot.MAX_LEVELS` levels, never the temporary or home folder)
that holds a ``package.xml``, else the URDF's folder (its parent when the URDF sits in ``urdf/``,
``robots/`` or ``xacro/``). ``NAME`` must be that package's folder name or the ``<name>`` in its
``package.xml``. Other packages need ``--package-dir NAME=DIR``; ``--package-search`` restores the wide
search (folders named ``NAME`` above the URDF and beside each of them). ``..`` never climbs out of a package.
"""

from __future__ import annotations

import os
import re
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from meshtool.errors import MeshtoolError, ResolveError
from meshtool.files.resolve import Resolver, find_package_dir, list_names
from meshtool.files.safeopen import MIB, printable, read_file
from meshtool.formats import mesh_suffixes
from meshtool.frame.modelroot import MAX_LEVELS

#: Folders whose URDF lives one level below its package (``pkg/urdf/robot.urdf``).
URDF_FOLDERS = ("urdf", "robots", "xacro")
_PACKAGE_NAME = re.compile(rb"<name>\s*([^<\s]+)\s*</name>")


class UrdfError(MeshtoolError, ValueError):
    """The URDF cannot be imported (bad XML, a missing or escaping mesh, an unsupported construct)."""


@dataclass(frozen=True, slots=True)
class FoundMesh:
    """A mesh file, read.

    Attributes:
        path: The file read (absolute, symbolic links resolved: the file the bytes came from).
        root: The folder its own references (MTL, textures, glTF buffers) may resolve in.
        data: Its bytes.
    """

    path: Path
    root: Path
    data: bytes


class MeshLocator:
    """Finds and reads the meshes one URDF names.

    Args:
        urdf: The URDF file.
        packages: ``--package-dir`` mappings, name -> folder (the empty name maps ``package:///...``).
        allow_outside: Relative and ``file://`` paths may leave the robot's package (the mesh's own folder
            is then its root).
        package_search: Look for ``package://NAME`` in folders named ``NAME`` above the URDF and beside them.
    """

    def __init__(
        self, urdf: Path, packages: dict[str, Path], *, allow_outside: bool = False, package_search: bool = False
    ) -> None:
        self.urdf_dir = Path(os.path.realpath(Path(urdf).parent))
        self.packages = {name: Path(os.path.realpath(folder)) for name, folder in packages.items()}
        self.allow_outside = allow_outside
        self.package_search = package_search
        self.own, self.own_names = _own_package(self.urdf_dir)

    def read(self, ref: str, where: dict[str, Any]) -> FoundMesh:
        """Find the mesh ``ref`` names and read it race-free.

        Args:
            ref: The ``filename`` of the ``<mesh>``.
            where: ``path`` and ``line`` of the ``<mesh>`` element, for errors.

        Raises:
            UrdfError: Unknown package, a path outside the allowed folders, a missing, unreadable or
                unsupported file, or one that changed while it was read.
        """
        candidate, root = self._candidate(ref, where)
        try:
            real = Path(os.path.realpath(candidate))
        except (OSError, ValueError):  # a link changed under realpath: the read below would refuse it too
            raise UrdfError(
                f"mesh {ref!r} changed while it was being read (a symbolic link appeared in its path); not read",
                **where,
                hint="do not modify the robot's files while meshtool reads them",
            ) from None
        inside = Resolver(root).inside(real)
        if self.allow_outside and not inside:
            root = real.parent
        elif not inside:
            raise UrdfError(
                f"mesh {ref!r} is outside the robot's folder {printable(root)}",
                **where,
                hint="move it into the package, or pass --allow-outside",
            )
        if real.suffix.lower() not in mesh_suffixes():
            raise UrdfError(f"mesh {ref!r}: unsupported type {real.suffix!r}", **where)
        resolver = Resolver(root)
        try:
            found, data = resolver.read_real(candidate)
        except ResolveError as exc:
            if not os.path.lexists(real):
                raise UrdfError(f"mesh {ref!r} not found (looked for {printable(real)})", **where) from None
            raise UrdfError(f"mesh {ref!r} {exc.message}", **where, hint=exc.hint) from None
        return FoundMesh(found, root, data)

    def _candidate(self, ref: str, where: dict[str, Any]) -> tuple[Path, Path]:
        """The path ``ref`` names (not yet resolved) and the folder it must stay in."""
        text = ref.strip()
        if text.startswith("package://"):
            package, _, rest = text[len("package://") :].partition("/")
            root = self._package(package, ref, where)
            parts = [p for p in rest.split("/") if p not in ("", ".")]
            if ".." in parts:
                raise UrdfError(
                    f"mesh {ref!r} climbs out of its package with '..'",
                    **where,
                    hint="name the file from the package's top folder, or map another package with --package-dir",
                )
            return root.joinpath(*parts), root
        if text.startswith("file://"):
            text = text[len("file://") :]
        path = Path(text)
        return (path if path.is_absolute() else self.urdf_dir / path), self.own

    def _package(self, name: str, ref: str, where: dict[str, Any]) -> Path:
        """The folder of package ``name`` (``""``: the robot's own package)."""
        if name in self.packages:
            return self.packages[name]
        if not name:
            return self.own
        if name in (".", "..") or "\\" in name or "\x00" in name:
            raise UrdfError(f"mesh {ref!r}: {name!r} is not a package name", **where, hint="name a ROS package")
        if name in self.own_names:
            return self.own
        found = find_package_dir(self.urdf_dir, name) if self.package_search else None
        if found is None:
            wider = "" if self.package_search else " (or --package-search to look above the robot's folder)"
            raise UrdfError(
                f"package {name!r} of mesh {ref!r} not found: it is not the robot's own package {printable(self.own)}",
                **where,
                hint=f"pass --package-dir {name}=FOLDER{wider}",
            )
        return found


def _own_package(urdf_dir: Path) -> tuple[Path, set[str]]:
    """The robot's own package folder and the names it answers to (folder name, ``package.xml`` name)."""
    shared = {Path(os.path.realpath(tempfile.gettempdir())), Path(os.path.realpath(Path.home())), Path("/")}
    for folder in [urdf_dir, *urdf_dir.parents][: MAX_LEVELS + 1]:
        if folder in shared:
            break
        if "package.xml" in list_names(folder):
            names = {folder.name}
            try:
                found = _PACKAGE_NAME.search(read_file(folder / "package.xml", MIB))
            except ResolveError:
                found = None
            if found:
                names.add(found.group(1).decode("utf-8", "replace"))
            return folder, names
    own = urdf_dir.parent if urdf_dir.name in URDF_FOLDERS and urdf_dir.parent != urdf_dir else urdf_dir
    return own, {own.name}


__all__ = ["URDF_FOLDERS", "FoundMesh", "MeshLocator", "UrdfError"]
