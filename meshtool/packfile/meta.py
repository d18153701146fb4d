"""``PackMeta``: the pack stage's record (defined with the other stage records in :mod:`meshtool.stages`).

The writer builds one (:meth:`PackMeta.of_asset`) and stores :attr:`PackMeta.raw` as canonical JSON; readers get
one from :attr:`meshtool.packfile.read.PackedMesh.pack_meta`. Which files a pack was made from is
:meth:`PackMeta.source_files`; whether they are still the same is :func:`meshtool.pipeline.source_states`.
"""

from meshtool.stages import PackMeta, SourceEntry, file_entries, source_entries, source_files, source_path

__all__ = ["PackMeta", "SourceEntry", "file_entries", "source_entries", "source_files", "source_path"]
