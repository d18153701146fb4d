"""Atomic output folders: everything is written to a temporary folder beside the target, then renamed.

A reader never sees a half-written asset folder, a failed run leaves nothing behind, and an existing
folder is only replaced when meshtool wrote it (it holds an ``asset.json``).
"""

from __future__ import annotations

import os
import re
import shutil
import tempfile
from pathlib import Path

from meshtool.errors import OutputError

SAFE_FILE = re.compile(r"^[a-z0-9_][a-z0-9_.-]*$")
MARKER = "asset.json"


def write_folder(parent: Path, name: str, files: dict[str, bytes]) -> Path:
    """Write ``files`` as ``parent/name/`` atomically.

    Args:
        parent: Output folder (created when missing).
        name: Folder name, ``[a-z0-9_.-]+``.
        files: File name (``[a-z0-9_.-]+``, no folders) to contents; must include ``asset.json``.

    Returns:
        The written folder.

    Raises:
        OutputError: A bad name, an existing folder that meshtool did not write, or an OS error (the
            temporary folder is removed and an existing folder restored).
    """
    for file_name in (name, *files):
        if not SAFE_FILE.match(file_name):
            raise OutputError(f"unsafe output name {file_name!r}", hint="names must match [a-z0-9_.-]+")
    target = parent / name
    if target.exists() and not (target.is_dir() and (target / MARKER).is_file()):
        raise OutputError(
            "exists and was not written by meshtool; not replacing it",
            path=str(target),
            hint="choose another --name or output folder, or remove it",
        )
    try:
        parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{name}.tmp-", dir=parent))
    except OSError as exc:
        raise OutputError(f"cannot create the output folder: {exc.strerror}", path=str(parent)) from None
    old: Path | None = None
    try:
        for file_name in sorted(files):
            with open(tmp / file_name, "wb") as handle:
                handle.write(files[file_name])
                handle.flush()
                os.fsync(handle.fileno())
        os.chmod(tmp, 0o755)
        if target.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{name}.old-", dir=parent))
            os.rmdir(old)
            os.rename(target, old)
        os.rename(tmp, target)
    except OSError as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        if old is not None and old.exists() and not target.exists():
            os.rename(old, target)
        raise OutputError(f"cannot write the output: {exc.strerror}", path=str(target)) from None
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
    return target


def write_file(out: Path, data: bytes) -> None:
    """Write ``data`` to ``out`` through a temporary file in the same folder and a rename."""
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{out.name}.", suffix=".tmp", dir=out.parent)
        done = False
        try:
            with os.fdopen(fd, "wb") as handle:
                handle.write(data)
                handle.flush()
                os.fsync(handle.fileno())
            os.chmod(tmp, 0o644)
            os.replace(tmp, out)
            done = True
        finally:
            if not done:  # never leave a partial file behind, whatever interrupted the write
                os.unlink(tmp)
    except OSError as exc:
        raise OutputError(f"cannot write: {exc.strerror}", path=str(out)) from None
