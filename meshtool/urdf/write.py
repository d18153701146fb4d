"""Writing an imported URDF robot: the MJCF (compiled first), its meshes and textures, and ``meshes/*.mbin``.

Nothing the user made is replaced (:mod:`meshtool.files.outdir`'s rules): the import's sources never, a previous
import's files only when meshtool's stamp in its ``NAME.xml`` lists them unchanged.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

from meshtool.files.outdir import GENERATORS, check_output, write_file
from meshtool.files.resolve import file_sha256
from meshtool.formats import suffix
from meshtool.mjcf.model_desc import stamped_files
from meshtool.urdf.import_robot import UrdfImport

#: Bytes of an existing ``NAME.xml`` read to find meshtool's stamp (it is the XML's first element).
_STAMP_READ = 1 << 20


def write_import(result: UrdfImport, out_dir: Path, *, force: bool | None = None) -> list[Path]:
    """Write the MJCF (compiled first), its meshes and textures, and ``meshes/*.mbin`` under ``out_dir``.

    Nothing the user made is replaced (:mod:`meshtool.files.outdir`'s rules, checked for every file before the
    first is written): never one of :attr:`UrdfImport.sources`; an existing ``.mbin`` or ``.msh`` only when
    meshtool wrote it; ``NAME.xml`` only when it carries meshtool's stamp; a PNG only when the stamped
    ``NAME.xml`` there lists it with its current SHA-256 (a file of the previous import, unchanged since)
    or holds exactly the bytes to be written. ``force`` replaces the others, never a source.

    Args:
        result: The import.
        out_dir: The output folder (created when missing).
        force: ``None`` uses :func:`meshtool.files.outdir.overwrite_allowed`'s setting (``--force``).

    Raises:
        ModelError: No MJCF builder is installed, or MuJoCo refuses the model (nothing is written).
        OutputError: A file would replace a source or a file meshtool did not write (nothing is written).
    """
    files = result.mjcf()
    xml_name = f"{result.name}{suffix('mjcf')}"
    previous = _previous_import(out_dir / xml_name)
    outputs = {**files, **result.mbins}
    for name, data in sorted(outputs.items()):
        target = out_dir / name
        ours = previous is not None and (name == xml_name or previous.get(name) == file_sha256(target))
        check_output(target, force=True if ours else force, inputs=result.sources, data=data)
    written = []
    for name in sorted(outputs, key=lambda n: (n == xml_name, n)):  # the XML (the record) last
        target = out_dir / name
        write_file(target, outputs[name])
        written.append(target)
    return written


def _previous_import(xml: Path) -> dict[str, str] | None:
    """The files (name -> SHA-256) listed by a meshtool-stamped MJCF at ``xml``; ``None`` when there is none."""
    try:
        fd = os.open(xml, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0))
    except OSError:
        return None
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            return None
        head = os.read(fd, _STAMP_READ)
    except OSError:
        return None
    finally:
        os.close(fd)
    return stamped_files(head, GENERATORS)


__all__ = ["write_import"]
