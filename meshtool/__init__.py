"""meshtool: make real-world OBJ/MTL exports simulation-ready.

The public API: :func:`normalise` / :func:`normalise_to` (one OBJ to a clean asset folder),
:func:`parse_obj` and :func:`parse_mtl` (plain readers), :func:`pack` and :func:`load` (the ``.mbin``
format), :class:`Finding` and the errors in
:mod:`meshtool.errors`. meshtool never imports simrun or mujoco.

The names are imported on first use (PEP 562), so ``import meshtool`` (and ``meshtool --version``) costs
no numpy, trimesh or Pillow import; ``from meshtool import load`` works as usual.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

if TYPE_CHECKING:
    from meshtool.errors import MeshtoolError
    from meshtool.findings import Finding, Severity
    from meshtool.packfile import PackedMesh, load, pack
    from meshtool.read.obj.mtl import parse_mtl
    from meshtool.read.obj.parse import parse_obj
    from meshtool.repair.normalise import NormalisedAsset, NormaliseOptions, normalise, normalise_to, write_asset

#: Public name -> the module that defines it.
_LAZY = {
    "MeshtoolError": "meshtool.errors",
    "Finding": "meshtool.findings",
    "Severity": "meshtool.findings",
    "NormalisedAsset": "meshtool.repair.normalise",
    "NormaliseOptions": "meshtool.repair.normalise",
    "normalise": "meshtool.repair.normalise",
    "normalise_to": "meshtool.repair.normalise",
    "write_asset": "meshtool.repair.normalise",
    "parse_mtl": "meshtool.read.obj.mtl",
    "parse_obj": "meshtool.read.obj.parse",
    "PackedMesh": "meshtool.packfile",
    "load": "meshtool.packfile",
    "pack": "meshtool.packfile",
}


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'meshtool' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value  # later lookups skip this hook
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_LAZY})


__all__ = [
    "Finding",
    "MeshtoolError",
    "NormaliseOptions",
    "NormalisedAsset",
    "PackedMesh",
    "Severity",
    "__version__",
    "load",
    "normalise",
    "normalise_to",
    "pack",
    "parse_mtl",
    "parse_obj",
    "write_asset",
]
