"""Opening files an asset names without races, hangs or unbounded memory.

Every byte meshtool reads from a user's asset goes through this module (via :mod:`meshtool.files.resolve`):

- **Open first, then check what was opened.** :func:`read_beneath` walks from an asset root one component
  at a time with ``openat`` and ``O_NOFOLLOW``, so a symbolic link swapped in after the reference was
  resolved makes the open fail instead of leading out of the root; there is no second lookup by name.
- **Regular files only.** Files are opened with ``O_NONBLOCK`` (opening a FIFO never waits for a writer)
  and ``fstat`` decides: FIFOs, sockets and devices are refused before a single byte is read.
- **Bounded.** The size is checked with ``fstat`` before reading against a per-kind limit
  (:class:`ReadLimits`); a file that grows or shrinks while it is read is refused.

POSIX only (``openat``/``O_NOFOLLOW``), like the rest of the toolchain.
"""

from __future__ import annotations

import errno
import hashlib
import os
import stat
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from meshtool.errors import ResolveError

GIB = 1 << 30
MIB = 1 << 20

_READ = os.O_RDONLY | os.O_CLOEXEC | os.O_NONBLOCK
_DIR = os.O_RDONLY | os.O_CLOEXEC | os.O_DIRECTORY
_CHUNK = 1 << 30  # one read(2) call returns at most ~2 GiB on Linux


@dataclass(frozen=True, slots=True)
class ReadLimits:
    """Largest file, in bytes, meshtool reads into memory, per kind of file.

    Attributes:
        obj: The OBJ itself (default 1 GiB).
        mtl: A material library (default 64 MiB).
        texture: A texture image file, before decoding (default 256 MiB; the decoded size is limited
            separately, see :mod:`meshtool.repair.textures`).
        other: Anything else read whole: URDF files and the meshes they name, ``.mbin`` files read for
            validation (default 1 GiB).
    """

    obj: int = GIB
    mtl: int = 64 * MIB
    texture: int = 256 * MIB
    other: int = GIB

    def for_kind(self, kind: str) -> int:
        """The limit for ``obj``, ``mtl``, ``texture`` or anything else (``other``)."""
        return {"obj": self.obj, "mtl": self.mtl, "texture": self.texture}.get(kind, self.other)


DEFAULT_LIMITS = ReadLimits()


def printable(name: str | os.PathLike[str]) -> str:
    r"""A file name safe to print and to write into UTF-8 JSON.

    Names on disk that are not valid UTF-8 come back from the OS with surrogate escapes (``b\udcfe.obj``);
    those bytes are shown as ``\xfe`` instead.
    """
    text = os.fspath(name)
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        return os.fsencode(text).decode("utf-8", "backslashreplace")
    return text


def describe_mode(mode: int) -> str:
    """What a non-regular file is, for messages (``a FIFO``, ``a folder``, ``a character device``...)."""
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISSOCK(mode):
        return "a socket"
    if stat.S_ISCHR(mode):
        return "a character device"
    if stat.S_ISBLK(mode):
        return "a block device"
    if stat.S_ISLNK(mode):
        return "a symbolic link"
    return "not a regular file"


def error_from(exc: OSError, shown: str, beneath: bool = False) -> ResolveError:
    """A one-line :class:`ResolveError` for an ``OSError`` raised while opening or reading ``shown``.

    ``beneath``: the error came from :func:`read_beneath`, where ``ELOOP``/``ENOTDIR`` mean a component
    became a symbolic link (or a file) after the path was resolved.
    """
    code = exc.errno
    if code == errno.ENOENT:
        return ResolveError("does not exist", path=shown, hint="check the path")
    if code == errno.ENAMETOOLONG:
        return ResolveError("cannot be read: the file name is too long", path=shown, hint="shorten the name")
    if code == errno.EISDIR:
        return ResolveError("is a folder, not a file", path=shown, hint="name a file")
    if code == errno.ENOTDIR and not beneath:
        return ResolveError("does not exist (a part of its path is not a folder)", path=shown, hint="check the path")
    if code in (errno.ELOOP, errno.ENOTDIR) and beneath:
        return ResolveError(
            "changed while it was being read (a symbolic link or file appeared in its path); not read",
            path=shown,
            hint="do not modify the asset while meshtool reads it",
        )
    reason = exc.strerror or type(exc).__name__
    return ResolveError(f"cannot be read: {reason}", path=shown)


def read_file(path: Path, limit: int, shown: str | None = None) -> bytes:
    """Read a regular file the user named (symlinks followed), refusing special files and oversized ones.

    Args:
        path: The file.
        limit: Most bytes accepted.
        shown: Name for messages (default: the path).

    Raises:
        ResolveError: Missing, not a regular file, larger than ``limit``, changed while read, unreadable.
    """
    shown = shown if shown is not None else printable(path)
    return read_fd(_open(path, shown), limit, shown)


def read_beneath(root: Path, parts: Sequence[str], limit: int, shown: str) -> bytes:
    """Read ``root/parts...`` without following any symbolic link below ``root``.

    ``root`` must be a real path (symlinks resolved); ``parts`` are plain names (no ``..``, no ``/``). Each
    folder is opened relative to the previous one with ``O_NOFOLLOW``, so a component replaced by a
    symbolic link after the path was resolved fails the open instead of being followed.

    Raises:
        ResolveError: As :func:`read_file`; also when a component is (now) a symbolic link.
    """
    if not parts:
        raise ResolveError("is a folder, not a file", path=shown, hint="name a file")
    if any(p in ("", ".", "..") or "/" in p or "\x00" in p for p in parts):
        raise ResolveError("is not a plain relative path", path=shown)
    try:
        dir_fd = os.open(root, _DIR)
    except OSError as exc:
        raise error_from(exc, shown) from None
    try:
        for part in parts[:-1]:
            try:
                next_fd = os.open(part, _DIR | os.O_NOFOLLOW, dir_fd=dir_fd)
            except OSError as exc:
                raise _not_a_folder(exc, part, dir_fd, shown) from None
            os.close(dir_fd)
            dir_fd = next_fd
        before = os.stat(parts[-1], dir_fd=dir_fd, follow_symlinks=False)
        if stat.S_ISLNK(before.st_mode):
            raise OSError(errno.ELOOP, "a symbolic link appeared")
        if not stat.S_ISREG(before.st_mode):
            raise _not_regular(before.st_mode, shown)
        fd = os.open(parts[-1], _READ | os.O_NOFOLLOW, dir_fd=dir_fd)
    except ResolveError:  # a FileNotFoundError, hence an OSError: let it through unchanged
        raise
    except OSError as exc:
        raise error_from(exc, shown, beneath=True) from None
    finally:
        os.close(dir_fd)
    return read_fd(fd, limit, shown)


def read_fd(fd: int, limit: int, shown: str) -> bytes:
    """Read a whole file from an open descriptor (closed on return) after checking it with ``fstat``.

    Raises:
        ResolveError: Not a regular file, larger than ``limit``, or its size changed while reading.
    """
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise _not_regular(info.st_mode, shown)
        size = info.st_size
        if size > limit:
            raise ResolveError(
                f"is {_bytes(size)}, over the {_bytes(limit)} limit for this kind of file; not read",
                path=shown,
                hint="check that it is the right file; the read limits are listed in the README",
            )
        chunks: list[bytes] = []
        remaining = size
        while remaining > 0:
            chunk = os.read(fd, min(remaining, _CHUNK))
            if not chunk:
                break
            chunks.append(chunk)
            remaining -= len(chunk)
        if remaining or os.read(fd, 1):
            raise ResolveError(
                "changed size while it was being read; not read",
                path=shown,
                hint="do not modify the asset while meshtool reads it",
            )
    except ResolveError:
        raise
    except OSError as exc:
        raise error_from(exc, shown) from None
    finally:
        os.close(fd)
    return chunks[0] if len(chunks) == 1 else b"".join(chunks)


def open_regular(path: Path, shown: str | None = None) -> int:
    """Open a regular file for reading (symlinks followed, never blocking); the caller closes the descriptor.

    Raises:
        ResolveError: Missing, not a regular file or unreadable.
    """
    shown = shown if shown is not None else printable(path)
    fd = _open(path, shown)
    try:
        mode = os.fstat(fd).st_mode
    except OSError as exc:
        os.close(fd)
        raise error_from(exc, shown) from None
    if not stat.S_ISREG(mode):
        os.close(fd)
        raise _not_regular(mode, shown)
    return fd


def sha256_of(path: Path) -> str | None:
    """SHA-256 hex digest of a regular file, read in chunks; ``None`` when it is missing or not regular."""
    try:
        fd = open_regular(path)
    except ResolveError:
        return None
    digest = hashlib.sha256()
    try:
        while chunk := os.read(fd, MIB):
            digest.update(chunk)
    except OSError:
        return None
    finally:
        os.close(fd)
    return digest.hexdigest()


def is_regular(path: Path) -> bool:
    """Whether ``path`` names a regular file (symlinks followed); ``False`` for any error, never raises."""
    try:
        return stat.S_ISREG(os.stat(path).st_mode)
    except (OSError, ValueError):
        return False


def is_folder(path: Path) -> bool:
    """Whether ``path`` names a folder (symlinks followed); ``False`` for any error, never raises."""
    try:
        return stat.S_ISDIR(os.stat(path).st_mode)
    except (OSError, ValueError):
        return False


def _open(path: Path, shown: str) -> int:
    if "\x00" in os.fspath(path):
        raise ResolveError("the file name contains a NUL byte", path=shown, hint="fix the name")
    try:
        mode = os.stat(path).st_mode  # devices and FIFOs are refused before any open(2)...
        if not stat.S_ISREG(mode):
            raise _not_regular(mode, shown)
        return os.open(path, _READ)  # ...and fstat after it catches one swapped in between
    except ResolveError:
        raise
    except OSError as exc:
        raise error_from(exc, shown) from None


def _not_regular(mode: int, shown: str) -> ResolveError:
    what = describe_mode(mode)
    if stat.S_ISDIR(mode):
        return ResolveError("is a folder, not a file", path=shown, hint="name a file")
    return ResolveError(f"is {what}, not a regular file; not read", path=shown, hint="replace it with a regular file")


def _not_a_folder(exc: OSError, part: str, dir_fd: int, shown: str) -> OSError | ResolveError:
    """Why the folder ``part`` (a component of ``shown``'s path, in ``dir_fd``) could not be opened.

    A FIFO, device or file where a folder is expected is named as such. A symbolic link (the path was resolved
    without one: it appeared after) or a folder by now (it changed during the read), and any other error, are
    returned unchanged for :func:`error_from`, which says the file changed while it was read.
    """
    if exc.errno not in (errno.ENOTDIR, errno.ELOOP):
        return exc
    try:
        mode = os.stat(part, dir_fd=dir_fd, follow_symlinks=False).st_mode
    except OSError:
        return exc
    if stat.S_ISLNK(mode) or stat.S_ISDIR(mode):
        return exc
    what = "a file" if stat.S_ISREG(mode) else describe_mode(mode)
    return ResolveError(
        f"does not exist: a part of its path ({part!r}) is {what}, not a folder",
        path=shown,
        hint="check the path",
    )


def _bytes(n: int) -> str:
    """``n`` bytes for a message, rounded to 0.1 KiB/MiB/GiB (exact bytes when rounding would hide a difference)."""
    for unit, size in (("GiB", GIB), ("MiB", MIB), ("KiB", 1024)):
        if n >= size:
            if n % size and round(n / size, 1) * size == (n // size) * size:
                return f"{n:,} bytes"
            return f"{n / size:.1f} {unit}".replace(".0 ", " ")
    return f"{n} bytes"
