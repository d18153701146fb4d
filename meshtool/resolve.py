r"""The resolver: the one module that looks up and reads files named by an asset.

Files name other files (``mtllib``, ``map_Kd``) in whatever form the designer's machine produced:
backslashes, wrong case, absolute Windows or UNC paths, ``file://`` or ``model://`` URIs. The resolver tries,
in order:

1. ``exact``: the path as written, relative to the referencing file's folder;
2. ``backslash``: backslashes read as separators;
3. ``case-insensitive``: the same path matched component by component ignoring case;
4. ``trailing-components``: for absolute paths and URIs, ever shorter trailing parts of the path
   (``C:\Users\x\Desktop\Head 1\Head 1.bmp`` -> ``Head 1/Head 1.bmp`` -> ``Head 1.bmp``);
5. ``basename``: the file name alone beside the referencing file, then beside the OBJ, ignoring case;
6. ``search-path``: the relative path, then the file name, in each ``--search-path`` folder in order.

Nothing outside the asset roots (the OBJ's folder and the explicit search paths, after following
symbolic links) is ever read: a reference that would leave them becomes a finding. Every lookup is
recorded as a :class:`Resolution`.
"""

from __future__ import annotations

import hashlib
import mmap
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import unquote

from meshtool.errors import ResolveError
from meshtool.findings import Finding, info, warning

_URI = re.compile(r"^([A-Za-z][A-Za-z0-9+.-]*)://")
_WINDOWS_ABS = re.compile(r"^[A-Za-z]:[\\/]")


@dataclass(slots=True)
class Resolution:
    """How one reference was resolved.

    Attributes:
        ref: The reference exactly as written in the file.
        kind: ``mtl`` or ``texture``.
        origin: The referencing file, relative to the asset folder.
        line: 1-based line of the reference.
        found: The file found (absolute, symlinks resolved), or ``None``.
        rule: The rule that found it (see the module docstring), or ``None``.
        findings: What is worth telling about this reference.
    """

    ref: str
    kind: str
    origin: str
    line: int
    found: Path | None = None
    rule: str | None = None
    findings: list[Finding] = field(default_factory=list)


class Resolver:
    """Finds and reads files inside a set of asset roots.

    Args:
        asset_dir: The folder of the OBJ file; the first root.
        search_paths: Further folders the user allows references to resolve into.
    """

    def __init__(self, asset_dir: Path, search_paths: Sequence[Path] = ()) -> None:
        self.asset_dir = Path(os.path.realpath(asset_dir))
        self.search_paths = [Path(os.path.realpath(p)) for p in search_paths]
        self.roots = [self.asset_dir, *self.search_paths]
        self._listing: dict[Path, list[str]] = {}

    # -- reading -------------------------------------------------------------------------------------------

    def read_source(self, path: Path) -> bytes:
        """Read a file the user named on the command line (the OBJ itself).

        Raises:
            ResolveError: When it does not exist, is not a file or cannot be read.
        """
        if not path.is_file():
            what = "is a folder, not a file" if path.is_dir() else "does not exist"
            raise ResolveError(what, path=str(path), hint="check the path")
        try:
            return path.read_bytes()
        except OSError as exc:
            raise ResolveError(f"cannot be read: {exc.strerror}", path=str(path)) from None

    def read(self, found: Path) -> bytes:
        """Read a file returned by :meth:`resolve` (it is inside a root by construction).

        Raises:
            ResolveError: When it left the roots or cannot be read.
        """
        if not self.inside(found):
            raise ResolveError("is outside the asset folder and search paths", path=str(found))
        try:
            return found.read_bytes()
        except OSError as exc:
            raise ResolveError(f"cannot be read: {exc.strerror}", path=self.display(found)) from None

    def inside(self, path: Path) -> bool:
        """Whether ``path`` (after resolving symlinks) lies inside one of the roots."""
        real = Path(os.path.realpath(path))
        return any(real == root or root in real.parents for root in self.roots)

    def display(self, path: Path) -> str:
        """A path for messages and metadata: relative to the asset folder, or ``<search-path N>/rel``."""
        real = Path(os.path.realpath(path))
        for n, root in enumerate(self.roots):
            if real == root or root in real.parents:
                rel = real.relative_to(root).as_posix()
                return rel if n == 0 else f"<search-path {n}>/{rel}"
        return real.as_posix()

    # -- resolving -----------------------------------------------------------------------------------------

    def resolve(self, ref: str, base_dir: Path, kind: str, origin: str, line: int) -> Resolution:
        r"""Find the file a reference names.

        Args:
            ref: The reference as written (``Head 1.bmp``, ``C:\tex\a.bmp``, ``file:///x/a.png``).
            base_dir: Folder of the referencing file.
            kind: ``mtl`` or ``texture`` (used in finding codes and messages).
            origin: The referencing file for messages.
            line: Line of the reference.

        Returns:
            The resolution; ``found`` is ``None`` when nothing inside the roots matches.
        """
        res = Resolution(ref, kind, origin, line)
        text = ref.strip().strip('"').strip()
        foreign = False
        uri = _URI.match(text)
        if uri:
            foreign = True
            text = unquote(text[uri.end() :])
        normal = text.replace("\\", "/")
        if _WINDOWS_ABS.match(text) or normal.startswith("/"):
            foreign = True
        parts = [p for p in normal.split("/") if p not in ("", ".")]
        if parts and _WINDOWS_ABS.match(parts[0] + "/"):
            parts = parts[1:]
        if not parts:
            res.findings.append(warning(f"{kind}-reference-empty", f"empty {kind} reference", origin, line))
            return res
        base = Path(os.path.realpath(base_dir))
        escaped = False
        candidates: list[tuple[str, list[str], Path]] = []
        if not foreign:
            if "\\" not in text:
                candidates.append(("exact", parts, base))
            else:
                candidates.append(("backslash", parts, base))
            candidates.append(("case-insensitive", parts, base))
        else:
            candidates.extend(("trailing-components", parts[k:], base) for k in range(len(parts)))
        basename = parts[-1]
        candidates.append(("basename", [basename], base))
        if base != self.asset_dir:
            candidates.append(("basename", [basename], self.asset_dir))
        for root in self.search_paths:
            if not foreign:
                candidates.append(("search-path", parts, root))
            candidates.append(("search-path", [basename], root))

        for rule, rel, start in candidates:
            exact = rule in ("exact", "backslash")
            path = self._walk(start, rel, exact)
            if path is None:
                continue
            if not self.inside(path):
                escaped = True
                continue
            res.found, res.rule = Path(os.path.realpath(path)), rule
            break

        shown = ref.strip()
        if escaped:
            res.findings.append(
                warning(
                    "reference-outside-root",
                    f"{kind} reference {shown!r} points outside the asset folder; not read "
                    "(add its folder with --search-path to allow it)",
                    origin,
                    line,
                )
            )
        if res.found is None:
            res.findings.append(warning(f"{kind}-missing", f"{kind} {shown!r} not found", origin, line))
        elif res.rule not in ("exact",):
            res.findings.append(
                info(
                    f"{kind}-reference-repaired",
                    f"{kind} {shown!r} found as {self.display(res.found)!r} (rule: {res.rule})",
                    origin,
                    line,
                )
            )
        return res

    def _walk(self, start: Path, parts: list[str], exact: bool) -> Path | None:
        """Follow ``parts`` from ``start``; ``exact`` matches names as written, else ignoring case."""
        current = start
        for n, part in enumerate(parts):
            if part == "..":
                current = current.parent
                continue
            if exact:
                current = current / part
                continue
            names = self._names(current)
            if part in names:
                current = current / part
                continue
            lowered = part.casefold()
            matches = sorted(name for name in names if name.casefold() == lowered)
            if not matches:
                return None
            current = current / matches[0]
            if n < len(parts) - 1 and not current.is_dir():
                return None
        if not self.inside(current):
            return current  # reported as escaping; never probed or read
        return current if current.is_file() else None

    def _names(self, folder: Path) -> list[str]:
        if folder not in self._listing:
            try:
                self._listing[folder] = sorted(os.listdir(folder)) if self.inside(folder) else []
            except OSError:
                self._listing[folder] = []
        return self._listing[folder]


def file_sha256(path: Path) -> str | None:
    """SHA-256 hex digest of a file the user pointed at (or that a manifest names), ``None`` if unreadable."""
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest() if path.is_file() else None
    except OSError:
        return None


def find_files(root: Path, suffix: str) -> list[Path]:
    """Files under ``root`` (recursively) whose suffix matches ``suffix`` ignoring case, sorted."""
    return sorted(p for p in root.rglob("*") if p.is_file() and p.suffix.lower() == suffix.lower())


def map_readonly(path: Path) -> mmap.mmap | None:
    """Memory-map a file the user named, read-only; ``None`` for an empty file.

    Raises:
        ResolveError: It cannot be opened.
    """
    try:
        with open(path, "rb") as handle:
            if handle.seek(0, 2) == 0:
                return None
            return mmap.mmap(handle.fileno(), 0, access=mmap.ACCESS_READ)
    except OSError as exc:
        raise ResolveError(f"cannot be read: {exc.strerror}", path=str(path)) from None


def read_cache(path: Path) -> bytes | None:
    """Bytes of a cache or scratch file meshtool wrote itself, ``None`` when it is missing or unreadable."""
    try:
        return path.read_bytes() if path.is_file() else None
    except OSError:
        return None


def find_package_dir(start: Path, name: str) -> Path | None:
    """The ROS package folder ``name`` for a ``package://name/...`` URI, searched from ``start`` upwards.

    An ancestor of ``start`` named ``name`` wins (``pkg/urdf/robot.urdf``), then a sibling folder ``name``
    of an ancestor (``src/pkg`` beside ``src/robot_description``). Symlinks are resolved.
    """
    here = Path(os.path.realpath(start))
    for folder in (here, *here.parents):
        if folder.name == name:
            return folder
        if (folder / name).is_dir():
            return Path(os.path.realpath(folder / name))
    return None


def is_file(path: Path) -> bool:
    """Whether ``path`` names an existing regular file."""
    return path.is_file()


def list_names(folder: Path) -> list[str]:
    """Sorted names of the entries of ``folder`` (empty when it cannot be listed)."""
    try:
        return sorted(os.listdir(folder))
    except OSError:
        return []
