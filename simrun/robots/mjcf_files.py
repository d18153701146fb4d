"""The files an MJCF model reads, found as MuJoCo finds them: includes, meshes, textures, height fields, skins.

:func:`model_files` is the one list: :class:`~simrun.robots.mjcf_robot.MjcfRobot` reads the assets it names into
memory (and records every file as read by the world, so ``simrun test`` bundles them), and anything else that
needs a model's files asks it.

How MuJoCo finds them (``src/xml/xml.cc``, ``mjIncludeXML``, checked against MuJoCo's own load in
``tests/test_mjcf_files.py``):

- ``<include file>``: an absolute name as given; a relative one first relative to the main model's folder,
  then relative to the folder of the file that holds the ``<include>`` (nested includes too). Included files
  are spliced in before the model is read, so their ``<compiler>`` settings count as the main file's.
- Assets are listed from the model MuJoCo parsed (:meth:`mujoco.MjSpec.from_file`), which holds every
  included element: a mesh, height field or skin ``file`` relative to ``<compiler meshdir>``, a texture
  (and each cube face) relative to ``texturedir`` (``assetdir`` sets both where they are not given), those
  folders relative to the main model's folder unless absolute; an absolute file name as given (MuJoCo writes
  one for an asset of an included file it found beside that file).
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco

#: Most ``<include>`` files followed from one model (nested ones count).
MAX_INCLUDES = 4096


@dataclass(frozen=True, slots=True)
class ModelFile:
    """One file an MJCF model reads.

    Attributes:
        kind: ``model`` (the main file), ``include``, ``mesh``, ``texture``, ``hfield`` or ``skin``.
        name: The asset's name in the model (``""`` for the model and its includes).
        path: Where MuJoCo reads it (as MuJoCo builds the name: symbolic links not followed).
        element: The spec element naming it (assets only), to point it elsewhere (:meth:`point_to`).
        face: For a cube texture's face file, its index in ``cubefiles``; else ``None``.
    """

    kind: str
    name: str
    path: Path
    element: Any = None
    face: int | None = None

    def point_to(self, file: str) -> None:
        """Make the spec element name ``file`` instead (an in-memory file, say); nothing for includes."""
        if self.element is None:
            return
        if self.face is None:
            self.element.file = file
        else:
            faces = list(self.element.cubefiles)
            faces[self.face] = file
            self.element.cubefiles = faces


def resolve(model_dir: Path, folder: str, file: str) -> Path:
    """Where MuJoCo reads an asset ``file``: absolute as given, else under the compiler ``folder``.

    ``folder`` is relative to the model's folder ``model_dir`` unless absolute.
    """
    name = Path(file)
    if name.is_absolute():
        return name
    base = Path(folder) if folder and Path(folder).is_absolute() else model_dir / folder
    return base / name


def include_files(path: Path) -> list[Path]:
    """Every file ``<include>`` brings into the model at ``path``, in MuJoCo's reading order (nested ones too).

    An include MuJoCo cannot find, a file that cannot be parsed or one already included is left out (MuJoCo's
    own read of the model reports it, with its line).
    """
    main_dir = path.parent
    found: list[Path] = []
    seen = {os.path.realpath(path)}

    def walk(file: Path) -> None:
        try:
            root = ET.parse(file).getroot()
        except (ET.ParseError, OSError, ValueError):
            return
        for element in root.iter("include"):
            name = element.get("file")
            if not name or len(found) >= MAX_INCLUDES:
                continue
            target = _include_target(Path(name), main_dir, file.parent)
            if target is None or os.path.realpath(target) in seen:
                continue
            seen.add(os.path.realpath(target))
            found.append(target)
            walk(target)

    walk(path)
    return found


def _include_target(name: Path, main_dir: Path, including_dir: Path) -> Path | None:
    if name.is_absolute():
        return name if name.is_file() else None
    for candidate in (main_dir / name, including_dir / name):
        if candidate.is_file():
            return candidate
    return None


def asset_files(spec: mujoco.MjSpec, path: Path) -> list[ModelFile]:
    """The mesh, texture, height field and skin files of ``spec`` (read from ``path``), where MuJoCo reads them."""
    model_dir = path.parent
    compiler = spec.compiler
    files: list[ModelFile] = []
    for mesh in spec.meshes:
        if mesh.file:
            files.append(ModelFile("mesh", mesh.name, resolve(model_dir, compiler.meshdir, mesh.file), mesh))
    for texture in spec.textures:
        if texture.file:
            where = resolve(model_dir, compiler.texturedir, texture.file)
            files.append(ModelFile("texture", texture.name, where, texture))
        for face, file in enumerate(texture.cubefiles):
            if file:
                where = resolve(model_dir, compiler.texturedir, file)
                files.append(ModelFile("texture", texture.name, where, texture, face))
    for hfield in spec.hfields:
        if hfield.file:
            files.append(ModelFile("hfield", hfield.name, resolve(model_dir, compiler.meshdir, hfield.file), hfield))
    for skin in spec.skins:
        if skin.file:
            files.append(ModelFile("skin", skin.name, resolve(model_dir, compiler.meshdir, skin.file), skin))
    return files


def model_files(path: Path, spec: mujoco.MjSpec | None = None) -> list[ModelFile]:
    """Every file MuJoCo reads to load the MJCF at ``path``: the model, its includes, then its assets.

    Args:
        path: The main MJCF file.
        spec: The model as :meth:`mujoco.MjSpec.from_file` read it from ``path`` (read here when not given).

    Raises:
        ValueError: MuJoCo cannot read the model (only when ``spec`` is not given).
    """
    if spec is None:
        spec = mujoco.MjSpec.from_file(str(path))
    listed = [ModelFile("model", "", path), *(ModelFile("include", "", p) for p in include_files(path))]
    return listed + asset_files(spec, path)
