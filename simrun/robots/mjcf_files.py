"""The files an MJCF model reads: includes, meshes, textures, height fields, skins, flexcomp files.

:func:`model_files` is the one list, and it comes from the one reader (:func:`simrun.robots.mjcf_read.read_mjcf`):
:class:`~simrun.robots.mjcf_robot.MjcfRobot` builds from what that reader read and records the same files as
read by the world (``World.files_read``), so ``simrun test`` bundles exactly them; anything else that needs a
model's files asks here. How the files are found (MuJoCo's rules, ``src/xml/xml.cc`` ``mjIncludeXML`` and
``src/xml/xml_util.cc`` ``ResolveFilePath``, checked against MuJoCo's own load in ``tests/test_mjcf_files.py``)
is told in :mod:`simrun.robots.mjcf_read` and kept once, MuJoCo-free, in :mod:`meshtool.files.mjcf_xml`:

- ``<include file>``: an absolute name as given; a relative one first relative to the main model's folder,
  then relative to the folder of the file that holds the ``<include>`` (nested includes too). Included files
  are spliced in before the model is read, so their ``<compiler>`` settings count as the main file's.
- A mesh, height field, skin or flexcomp ``file`` relative to ``<compiler meshdir>``, a texture (and each cube
  face) relative to ``texturedir`` (``assetdir`` sets both where they are not given), those folders relative to
  the main model's folder unless absolute; an element of an included file whose file is not found there is
  read beside that included file (MuJoCo writes its absolute name).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from meshtool.files.mjcf_xml import asset_file
from simrun.robots.mjcf_read import ReadFile, read_mjcf

#: One file an MJCF model reads (kind, name, path as MuJoCo builds it, real path read, in-memory name, cube face).
ModelFile = ReadFile
#: Most ``<include>`` files followed from one model (nested ones count).
MAX_INCLUDES = 4096


def resolve(model_dir: Path, folder: str, file: str) -> Path:
    """Where MuJoCo reads an asset ``file``: absolute as given, else under the compiler ``folder``.

    ``folder`` is relative to the model's folder ``model_dir`` unless absolute.
    """
    return asset_file(Path(model_dir), folder, file, None, False)


def model_files(path: Path, roots: Sequence[Path] | None = None) -> list[ModelFile]:
    """Every file MuJoCo reads to load the MJCF at ``path``: the model, its includes, then its assets.

    Args:
        path: The main MJCF file.
        roots: Folders the files may be in besides the model's own; ``None``: anywhere (a listing, as
            MuJoCo itself would read them; a world confines its models, :mod:`simrun.robots.mjcf_read`).

    Raises:
        MjcfReadError: The model or a file it names cannot be read (one line naming the element and path).
    """
    return read_mjcf(Path(path), [Path("/")] if roots is None else roots, "listed_").read


def include_files(path: Path, roots: Sequence[Path] | None = None) -> list[Path]:
    """Every file ``<include>`` brings into the model at ``path``, in MuJoCo's reading order (nested ones too).

    Raises:
        MjcfReadError: As :func:`model_files`.
    """
    return [f.path for f in model_files(path, roots) if f.kind == "include"]
