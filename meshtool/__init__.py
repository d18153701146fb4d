"""meshtool: make real-world OBJ/MTL exports simulation-ready.

The public API: :func:`normalise` / :func:`normalise_to` (one OBJ to a clean asset folder),
:func:`parse_obj` and :func:`parse_mtl` (plain readers), :func:`pack` and :func:`load` (the ``.mbin``
format), :class:`Finding` and the errors in
:mod:`meshtool.errors`. meshtool never imports simrun or mujoco.
"""

__version__ = "0.1.0"

from meshtool.errors import MeshtoolError
from meshtool.findings import Finding, Severity
from meshtool.normalise import NormalisedAsset, NormaliseOptions, normalise, normalise_to, write_asset
from meshtool.obj.mtl import parse_mtl
from meshtool.obj.parse import parse_obj
from meshtool.packfile import PackedMesh, load, pack

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
