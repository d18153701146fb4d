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

Rule 3 (and 5) also match names whose bytes on disk are not UTF-8: a reference read as Latin-1 matches
the file whose name has those bytes.

Nothing outside the asset roots (the OBJ's folder and the explicit search paths, after following
symbolic links) is ever read: a reference that would leave them becomes a finding. Reading is race-free:
:meth:`Resolver.read` opens the file by walking from its root without following symbolic links
(:mod:`meshtool.files.safeopen`), so a link swapped in after resolution cannot lead out of the root. FIFOs,
sockets and devices are never opened for reading, and every read is bounded (:class:`ReadLimits`). Every
lookup is recorded as a :class:`Resolution`.
"""

from __future__ import annotations

import mmap
import os
import re
import stat
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import unquote

from meshtool.errors import ResolveError
from meshtool.files.safeopen import (
    DEFAULT_LIMITS,
    ReadLimits,
    describe_mode,
    is_folder,
    is_regular,
    open_regular,
    printable,
    read_beneath,
    read_file,
    sha256_of,
)
from meshtool.findings import Finding, info, warning

__all__ = ["DEFAULT_LIMITS", "ReadLimits", "Resolution", "Resolver", "printable"]

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
        found: The file found (absolute, symlinks resolved, inside the roots), or ``None``. Once read with
            :meth:`Resolver.read_resolution`, the file that was actually opened; ``None`` when the read was
            refused.
        rule: The rule that found it (see the module docstring), ``refused`` when the file was found but
            its read was refused (it changed, grew too large or became a special file), or ``None``.
        findings: What is worth telling about this reference.
        refused: Why the read was refused (the one-line reason), else ``None``.
    """

    ref: str
    kind: str
    origin: str
    line: int
    found: Path | None = None
    rule: str | None = None
    findings: list[Finding] = field(default_factory=list)
    refused: str | None = None


class Resolver:
    """Finds and reads files inside a set of asset roots.

    Args:
        asset_dir: The folder of the OBJ file; the first root.
        search_paths: Further folders the user allows references to resolve into.
        limits: Most bytes read per file, per kind of file.
        confine: A folder every read must lie beneath, walked from without following links (the package of a
            URDF mesh, whose own folder is not a trusted root: a link swapped in above it after it was found
            must not make the folder's outside target a root).
    """

    def __init__(
        self,
        asset_dir: Path,
        search_paths: Sequence[Path] = (),
        limits: ReadLimits = DEFAULT_LIMITS,
        *,
        confine: Path | None = None,
    ) -> None:
        self.confine = Path(os.path.realpath(confine)) if confine is not None else None
        self.asset_dir = _realpath(asset_dir) or Path(os.path.abspath(asset_dir))
        self.search_paths = [Path(os.path.realpath(p)) for p in search_paths]
        self.roots = [self.asset_dir, *self.search_paths]
        self.limits = limits
        self._listing: dict[Path, _Listing] = {}
        self._embedded: dict[str, tuple[Path, bytes]] = {}
        self._embedded_paths: dict[Path, tuple[str, bytes]] = {}

    # -- embedded files ------------------------------------------------------------------------------------

    def embed(self, container: Path, name: str, data: bytes) -> str:
        """Register a file held inside another one (a GLB image, a ``data:`` URI) and return its reference.

        The reference (``CONTAINER/NAME``, made unique) resolves with rule ``embedded`` to a virtual path
        "inside" the container file (no real file can be there: the container is a file, not a folder);
        :meth:`read` returns the bytes (within the limit of the kind) and :meth:`display` shows the
        reference. Nothing is written to disk.

        Args:
            container: The file that holds the data.
            name: A name for it (an image's name with its file suffix).
            data: The bytes.
        """
        base = f"{printable(container.name)}/{re.sub(r'[^A-Za-z0-9_.-]+', '_', name).strip('_.') or 'embedded'}"
        ref, n = base, 2
        while ref in self._embedded:
            ref, n = f"{base}_{n}", n + 1
        path = Path(os.path.abspath(container.parent)).joinpath(*ref.split("/"))
        self._embedded[ref] = (path, data)
        self._embedded_paths[path] = (ref, data)
        return ref

    # -- reading -------------------------------------------------------------------------------------------

    def read_source(self, path: Path, kind: str = "obj") -> bytes:
        """Read a file the user named on the command line (the OBJ itself); symbolic links are followed.

        Args:
            path: The file.
            kind: Selects the size limit (``obj``; ``other`` for URDF and ``.mbin`` files).

        Raises:
            ResolveError: When it does not exist, is not a regular file (a folder, FIFO, device or socket),
                is larger than the limit, or cannot be read.
        """
        return read_file(path, self.limits.for_kind(kind), printable(path))

    def read(self, found: Path, kind: str = "other") -> bytes:
        """Read a file returned by :meth:`resolve`, race-free.

        The path is resolved once to find its root, then opened by walking from that root without following
        any symbolic link (``openat`` + ``O_NOFOLLOW``): if a component was replaced by a link since, the
        read fails; it never returns bytes from outside the roots.

        Args:
            found: The file (normally :attr:`Resolution.found`).
            kind: ``mtl``, ``texture`` or ``other``; selects the size limit.

        Raises:
            ResolveError: When it left the roots, changed while being read, is not a regular file, is larger
                than the limit, or cannot be read.
        """
        return self._read_real(found, kind)[1]

    def read_resolution(self, res: Resolution, kind: str | None = None) -> bytes:
        """Read the file a resolution found, race-free, and make the resolution record what was read.

        On success :attr:`Resolution.found` becomes the file actually opened (a path inside a root, reached
        from it without following any link). When the read is refused, ``found`` becomes ``None``, ``rule``
        ``refused`` and :attr:`Resolution.refused` the reason, so that nothing ever records a file that
        was not read (a link swapped in after the lookup can name anything); the error is raised again for
        the caller to turn into its finding or error.

        Args:
            res: A resolution whose ``found`` is set.
            kind: Selects the size limit; default the resolution's kind.

        Raises:
            ResolveError: As :meth:`read`.
        """
        if res.found is None:
            raise ResolveError(f"{res.kind} {res.ref.strip()!r} was not found", path=res.origin, line=res.line)
        try:
            res.found, data = self._read_real(res.found, kind or res.kind)
        except ResolveError as exc:
            res.found, res.rule, res.refused = None, "refused", exc.message
            raise
        return data

    def read_real(self, found: Path, kind: str = "other") -> tuple[Path, bytes]:
        """:meth:`read`, also returning the path actually read (inside a root, reached without links).

        Raises:
            ResolveError: As :meth:`read`.
        """
        return self._read_real(found, kind)

    def _read_real(self, found: Path, kind: str) -> tuple[Path, bytes]:
        """The path read (inside a root, without links) and the bytes of :meth:`read`."""
        embedded = self._embedded_paths.get(found)
        if embedded is not None:
            ref, blob = embedded
            limit = self.limits.for_kind(kind)
            if len(blob) > limit:
                raise ResolveError(f"is {len(blob)} bytes, more than the limit of {limit} bytes; not read", path=ref)
            return found, blob
        real = _realpath(found)
        if real is None:
            raise ResolveError(
                "changed while it was being read; not read",
                path=printable(found),
                hint="do not modify the asset while meshtool reads it",
            )
        root = self._root_of(real)
        if self.confine is not None and root is not None:
            root = self.confine if real == self.confine or self.confine in real.parents else None
        if root is None:
            raise ResolveError("is outside the asset folder and search paths; not read", path=printable(found))
        rel = real.relative_to(root).parts
        return real, read_beneath(root, rel, self.limits.for_kind(kind), self.display(real, resolved=True))

    def inside(self, path: Path) -> bool:
        """Whether ``path`` (after resolving symlinks) lies inside one of the roots."""
        real = _realpath(path)
        return real is not None and self._root_of(real) is not None

    def _root_of(self, real: Path) -> Path | None:
        """The first root that holds the real path ``real`` (no symlinks looked up), else ``None``."""
        for root in self.roots:
            if real == root or root in real.parents:
                return root
        return None

    def display(self, path: Path, resolved: bool = False) -> str:
        r"""A path for messages and metadata: relative to the asset folder, or ``<search-path N>/rel``.

        Bytes of names that are not UTF-8 are shown as ``\xNN`` (see :func:`printable`).

        Args:
            path: The file.
            resolved: ``path`` is already a real path (a :attr:`Resolution.found`): it is shown as it is,
                never looked up again (a link swapped in since must not change what is recorded).
        """
        embedded = self._embedded_paths.get(path)
        if embedded is not None:
            return embedded[0]
        real = Path(os.path.abspath(path)) if resolved else (_realpath(path) or Path(os.path.abspath(path)))
        for n, root in enumerate(self.roots):
            if real == root or root in real.parents:
                rel = printable(real.relative_to(root).as_posix())
                return rel if n == 0 else f"<search-path {n}>/{rel}"
        return printable(real.as_posix())

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
        if ref in self._embedded:
            res.found, res.rule = self._embedded[ref][0], "embedded"
            return res
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
        base = _realpath(base_dir) or Path(os.path.abspath(base_dir))
        escaped = False
        special: str | None = None
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
            real = _realpath(path)  # looked up once: containment, kind and the record all use this path
            if real is None:
                continue
            if self._root_of(real) is None:
                escaped = True
                continue
            mode = _lmode(real)
            if mode is None or stat.S_ISDIR(mode) or stat.S_ISLNK(mode):  # a link: it changed since; skip
                continue
            if not stat.S_ISREG(mode):
                special = special or describe_mode(mode)
                continue
            res.found, res.rule = real, rule
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
        if res.found is None and special is not None:
            res.findings.append(
                warning(
                    f"{kind}-not-a-file",
                    f"{kind} {shown!r} is {special}, not a regular file; not read",
                    origin,
                    line,
                )
            )
        elif res.found is None:
            res.findings.append(warning(f"{kind}-missing", f"{kind} {shown!r} not found", origin, line))
        elif res.rule not in ("exact",):
            res.findings.append(
                info(
                    f"{kind}-reference-repaired",
                    f"{kind} {shown!r} found as {self.display(res.found, resolved=True)!r} (rule: {res.rule})",
                    origin,
                    line,
                )
            )
        return res

    def _walk(self, start: Path, parts: list[str], exact: bool) -> Path | None:
        """Follow ``parts`` from ``start``; ``exact`` matches names as written, else ignoring case.

        Returns the path reached when something exists there (a file, or a special file the caller
        reports), or a path outside the roots (reported as escaping; never probed or read), else ``None``.
        """
        current = start
        for n, part in enumerate(parts):
            if part == "..":
                current = current.parent
                continue
            if exact:
                current = current / part
                continue
            name = self._listing_of(current).match(part)
            if name is None:
                return None
            current = current / name
            if n < len(parts) - 1 and not is_folder(current):
                return None
        if not self.inside(current):
            return current
        return current if _mode(current) is not None else None

    def _listing_of(self, folder: Path) -> _Listing:
        """The folder's names, listed once per resolver (a ``mtllib`` with many names lists it once)."""
        listing = self._listing.get(folder)
        if listing is None:
            names: list[str] = []
            if self.inside(folder):
                try:
                    names = os.listdir(folder)
                except (OSError, ValueError):
                    names = []
            listing = self._listing[folder] = _Listing(names)
        return listing


class _Listing:
    """A folder's entry names indexed for exact and case-insensitive lookup, including non-UTF-8 names."""

    def __init__(self, names: list[str]) -> None:
        self.names = set(names)
        self.folded: dict[str, str] = {}
        for name in sorted(names, reverse=True):  # the smallest name wins a case clash (deterministic)
            self.folded[name.casefold()] = name

    def match(self, part: str) -> str | None:
        """The entry named ``part``, else its Latin-1 byte spelling, else either ignoring case."""
        spellings = [part]
        try:
            raw = os.fsdecode(part.encode("latin-1"))
        except UnicodeEncodeError:
            raw = part
        if raw != part:
            spellings.append(raw)
        for spelling in spellings:
            if spelling in self.names:
                return spelling
        for spelling in spellings:
            found = self.folded.get(spelling.casefold())
            if found is not None:
                return found
        return None


def _realpath(path: str | os.PathLike[str]) -> Path | None:
    """``os.path.realpath``, or ``None`` when a link changed under it (it raises ``OSError`` then)."""
    try:
        return Path(os.path.realpath(path))
    except (OSError, ValueError):
        return None


def _lmode(path: Path) -> int | None:
    """``st_mode`` of ``path`` itself (a symbolic link is not followed), ``None`` when it cannot be looked up."""
    try:
        return os.lstat(path).st_mode
    except (OSError, ValueError):
        return None


def _mode(path: Path) -> int | None:
    """``st_mode`` of ``path`` (symlinks followed), ``None`` when it cannot be looked up (also too-long names)."""
    try:
        return os.stat(path).st_mode
    except (OSError, ValueError):
        return None


def file_sha256(path: Path) -> str | None:
    """SHA-256 hex digest of a file the user pointed at (or that a manifest names), ``None`` if unreadable.

    Read in chunks; FIFOs, devices and sockets give ``None`` without being read.
    """
    return sha256_of(path)


def find_files(root: Path, suffix: str, special: bool = False) -> list[Path]:
    """Regular files under ``root`` (recursively) whose suffix matches ``suffix`` ignoring case, sorted.

    With ``special``, also entries that are neither regular files nor folders (a FIFO named ``x.obj``), for
    callers that report them; they must never be opened.
    """
    return sorted(
        p
        for p in root.rglob("*")
        if p.suffix.lower() == suffix.lower() and (is_regular(p) or (special and not p.is_dir()))
    )


def map_readonly(path: Path) -> mmap.mmap | None:
    """Memory-map a regular file the user named, read-only; ``None`` for an empty file.

    Raises:
        ResolveError: It cannot be opened or is not a regular file (FIFOs and devices are never opened
            for reading).
    """
    fd = open_regular(path)
    try:
        if os.fstat(fd).st_size == 0:
            return None
        return mmap.mmap(fd, 0, access=mmap.ACCESS_READ)
    except OSError as exc:
        raise ResolveError(f"cannot be read: {exc.strerror}", path=printable(path)) from None
    finally:
        os.close(fd)


def read_cache(path: Path) -> bytes | None:
    """Bytes of a cache or scratch file meshtool wrote itself, ``None`` when it is missing or unreadable."""
    try:
        return read_file(path, DEFAULT_LIMITS.other)
    except ResolveError:
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
        if is_folder(folder / name):
            return Path(os.path.realpath(folder / name))
    return None


def is_file(path: Path) -> bool:
    """Whether ``path`` names an existing regular file (never raises, also not for over-long names)."""
    return is_regular(path)


def list_names(folder: Path) -> list[str]:
    """Sorted names of the entries of ``folder`` (empty when it cannot be listed)."""
    try:
        return sorted(os.listdir(folder))
    except (OSError, ValueError):
        return []
