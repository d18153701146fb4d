"""``.mbin``: the compact, versioned, checksummed binary mesh container (see docs/mbin-spec.md)."""

from meshtool.packfile.read import PackedMesh, Section, load, parse
from meshtool.packfile.write import pack

__all__ = ["PackedMesh", "Section", "load", "pack", "parse"]
