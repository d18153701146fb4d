"""``.mbin``: the compact, versioned, checksummed binary mesh container (see docs/mbin-spec.md)."""

from meshtool.packfile.meta import PackMeta, SourceEntry
from meshtool.packfile.read import PackedMesh, Section, load, parse
from meshtool.packfile.write import pack

__all__ = ["PackMeta", "PackedMesh", "SourceEntry", "Section", "load", "pack", "parse"]
