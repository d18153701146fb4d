"""The options of ``meshtool normalize`` (the read-to-repair part of ``obj2bin`` too), and safe file stems."""

from __future__ import annotations

import math
import re
import unicodedata
from dataclasses import dataclass
from pathlib import Path

from meshtool.errors import OptionsError
from meshtool.frame.units import UNIT_FACTORS

_SAFE_FILE_CHARS = re.compile(r"[^a-z0-9_.-]+")


@dataclass(frozen=True, slots=True)
class NormaliseOptions:
    """Options of :func:`meshtool.repair.normalise.normalise` (the fields of ``meshtool normalize``).

    Attributes:
        units: Unit of the source coordinates; ``None`` means metres (or, for a file meshtool wrote,
            what its header says).
        scale: Extra uniform scale applied after the unit conversion.
        up: Up axis of the source; ``None`` means ``y`` (the OBJ convention), or ``z`` for a file meshtool
            wrote.
        name: Output folder and file stem; ``None`` derives it from the source file name.
        search_paths: Extra folders references may resolve into.
        strict: Fail instead of writing when there are warnings.
        confine: Read every file the source references from beneath this folder, without following links
            (see :class:`meshtool.files.resolve.Resolver`); ``None``: the asset folder and search paths are roots.
        model_root: ``--model-root``: the folder at or above the source that is its model root (references
            may resolve inside it; its description files are searched for the source's consumers); ``None``:
            found (:func:`meshtool.frame.modelroot.find_model_root`, :func:`meshtool.frame.consumers.find_index_root`).
    """

    units: str | None = None
    scale: float = 1.0
    up: str | None = None
    name: str | None = None
    search_paths: tuple[Path, ...] = ()
    strict: bool = False
    confine: Path | None = None
    model_root: Path | None = None

    def __post_init__(self) -> None:
        if self.units is not None and self.units not in UNIT_FACTORS and self.units != "auto":
            raise OptionsError(f"unknown unit {self.units!r}", hint=f"use one of {', '.join(UNIT_FACTORS)} or auto")
        if self.up is not None and self.up not in ("y", "z", "auto"):
            raise OptionsError(f"unknown up axis {self.up!r}", hint="use y, z or auto")
        if not (math.isfinite(self.scale) and self.scale > 0):
            raise OptionsError(f"scale must be a positive finite number, got {self.scale!r}")
        if self.name is not None and not safe_file_stem(self.name):
            raise OptionsError(f"name {self.name!r} has no usable characters", hint="use letters, digits, _ . -")


def safe_file_stem(text: str) -> str:
    """A file stem made of ``[a-z0-9_.-]``: accents stripped, lower case, other runs become ``_``."""
    ascii_text = unicodedata.normalize("NFKD", text).encode("ascii", "ignore").decode("ascii").lower()
    return _SAFE_FILE_CHARS.sub("_", ascii_text).strip("_.-")
