"""Atomic file output for simrun, through meshtool's writer (temporary file, then a rename)."""

from __future__ import annotations

from pathlib import Path

from meshtool.errors import OutputError
from meshtool.outdir import write_file
from simrun.errors import SimrunError


def write_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically.

    Raises:
        SimrunError: The folder cannot be written.
    """
    try:
        write_file(path, data)
    except OutputError as exc:
        raise SimrunError(exc.one_line()) from None


def write_text(path: Path, text: str) -> None:
    """Write UTF-8 text atomically."""
    write_bytes(path, text.encode("utf-8"))
