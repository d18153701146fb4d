"""Reading user files safely: regular files only (never a FIFO, device or socket), with a size limit.

A FIFO named as a texture would block a reader forever and a device such as ``/dev/zero`` never ends, so
every file simrun reads is opened with ``O_NONBLOCK`` (opening a FIFO then returns at once), checked with
``fstat`` on the opened descriptor (no second lookup by name, so no race), and read up to a limit.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path
from typing import BinaryIO

from meshtool.files.safeopen import describe_mode
from simrun.errors import SimrunError

#: Default largest file simrun reads whole (scenes, commands, textures, height-field images), bytes.
MAX_FILE_BYTES = 256 * 1024 * 1024


class FileReadError(SimrunError, OSError):
    """A file cannot be read: missing, not a regular file, too large, or an OS error."""


def open_regular(path: Path, what: str = "file") -> BinaryIO:
    """Open ``path`` for reading in binary, refusing anything that is not a regular file.

    Args:
        path: The file.
        what: What it is, for the message (``texture``, ``scene``...).

    Raises:
        FileReadError: It cannot be opened, or it is a folder, FIFO, device or socket.
    """
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0))
    except OSError as exc:
        raise FileReadError(f"{path}: {what} cannot be read: {exc.strerror}") from None
    except ValueError:  # a NUL byte in the name: no file can have it
        raise FileReadError(f"{path!r}: {what} name contains a NUL byte; name a file") from None
    handed_over = False
    try:
        mode = os.fstat(fd).st_mode
        if not stat.S_ISREG(mode):
            raise FileReadError(f"{path}: {what} is {describe_mode(mode)}, not a regular file; name a file")
        if hasattr(os, "set_blocking"):
            os.set_blocking(fd, True)
        file = os.fdopen(fd, "rb")
        handed_over = True
        return file
    finally:
        if not handed_over:  # refused or failed: the descriptor is ours to close
            os.close(fd)


_CHUNK = 1 << 20  # bytes read at a time past a file's size when it was opened


def read_regular(path: Path, what: str = "file", limit: int = MAX_FILE_BYTES) -> bytes:
    """The bytes of a regular file of at most ``limit`` bytes.

    Raises:
        FileReadError: As :func:`open_regular`, or the file is larger than ``limit``.
    """
    with open_regular(path, what) as file:
        size = os.fstat(file.fileno()).st_size
        if size > limit:
            raise FileReadError(f"{path}: {what} is {size} bytes, over the limit of {limit} bytes")
        try:  # the size it has now, then what it grew by, in chunks: never a buffer of ``limit`` bytes up front
            parts = [file.read(size), file.read(1)]  # one byte past its size: did it grow?
            got = len(parts[0]) + len(parts[1])
            while parts[-1] and got <= limit:
                chunk = file.read(min(_CHUNK, limit + 1 - got))
                if not chunk:
                    break
                parts.append(chunk)
                got += len(chunk)
        except OSError as exc:
            raise FileReadError(f"{path}: {what} cannot be read: {exc.strerror}") from None
    data = parts[0] if not parts[1] else b"".join(parts)
    if len(data) > limit:
        raise FileReadError(f"{path}: {what} grew past the limit of {limit} bytes while being read")
    return data


def check_regular(path: Path, what: str = "file") -> None:
    """Refuse a path that does not name a readable regular file (opens it, never reads it)."""
    open_regular(path, what).close()
