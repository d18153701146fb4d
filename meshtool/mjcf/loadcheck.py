"""Does MuJoCo accept a packed asset? ``obj2bin``'s check before it writes the ``.mbin``.

The pack is described as a model (:class:`meshtool.mjcf.model_desc.ModelDesc`) the way simrun loads an ``.mbin``:
one fixed body, one visual mesh per submesh (every one of them, however small; ``inertia="shell"``,
massless), one collision mesh per hull (``inertia="convex"``, density 1000 kg/m^3), its materials and PNG
textures. The ``meshtool.mjcf`` ``check`` plugin (simrun's) compiles it in memory: nothing is written and
nothing is simulated, so the check costs one MuJoCo compile (mesh inertias, hulls, texture decoding).

meshtool never imports MuJoCo: without the plugin (simrun not installed) the check is skipped with a
``mujoco-check-skipped`` note.

Passing checks are remembered in a cache folder (``obj2bin``: the user cache, ``--no-cache`` turns it off):
one marker per SHA-256 of the ``.mbin`` bytes together with the plugin's identity (its distribution, version
and the content of every file of its package) and the MuJoCo distribution's version, sealed as a cache entry
(:mod:`meshtool.files.cachefile`): an empty, damaged or copied marker is a miss. The same bytes checked by the
same plugin and MuJoCo compile the same way, so a hit skips the compile and MuJoCo's import; any change of
the pack, of simrun or of MuJoCo is a miss. Refusals are never cached (the next run states the reason again).
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import re
from importlib import metadata
from pathlib import Path

from meshtool.errors import MeshtoolError
from meshtool.files.cachefile import read_entry, write_entry
from meshtool.files.safeopen import sha256_of
from meshtool.findings import Finding, info
from meshtool.mjcf.model_desc import BodyDesc, ModelDesc, ModelError, TextureDesc
from meshtool.packfile.read import PackedMesh
from meshtool.plugins import MJCF_GROUP, check_model, installed

#: The name every element of the checked model starts with.
PREFIX = "asset"
#: Density of the collision hulls in the checked model, kg/m^3 (``meshtool mjcf``'s default).
DENSITY = 1000.0
#: Kind and payload of a remembered passing check (:mod:`meshtool.files.cachefile`).
MARKER_KIND = "meshtool-load-check"
PASSED = b"compiled\n"
_ELEMENT = re.compile(r"\s*\(element '([^']*)'\)$")
_REFUSES = "MuJoCo refuses the model: "


def check_pack(data: bytes, source: str, cache_dir: Path | None = None) -> tuple[str, list[Finding]]:
    """Compile the packed asset ``data`` in MuJoCo through the installed plugin.

    Args:
        data: ``.mbin`` bytes.
        source: The input file, as the user named it (for the error and the finding).
        cache_dir: Folder of remembered passing checks; ``None`` compiles every time.

    Returns:
        ``("compiled", [])`` when MuJoCo compiled it, ``("cached", [])`` when these bytes passed before with
        the same plugin and MuJoCo, ``("skipped", [note])`` when no plugin is installed.

    Raises:
        ModelError: MuJoCo refuses the asset: its message, the part, hull or texture at fault, and a hint.
    """
    found = _marker(cache_dir, data)
    if found is not None and read_entry(found[0], MARKER_KIND, found[1]).payload == PASSED:
        return "cached", []
    from meshtool.packfile import parse

    with parse(data, source, verify=False) as packed:  # the packer's own bytes
        from meshtool.mjcf.asset_model import mesh_parts

        parts = mesh_parts(packed, PREFIX, keep_small=True)
        names = _describe(packed, parts.textures)
        for geom in parts.collision:
            geom.density = DENSITY
        body = BodyDesc(PREFIX, geoms=[*parts.visual, *parts.collision])
        model = ModelDesc(PREFIX, parts.meshes, parts.textures, parts.materials, bodies=[body])
    try:
        checked = check_model(model)
    except ModelError as exc:
        raise _refusal(exc, names, source) from None
    if not checked:
        return "skipped", [
            info(
                "mujoco-check-skipped",
                "not compiled in MuJoCo: no MJCF check plugin is installed (install simrun to have obj2bin check "
                "that MuJoCo loads what it writes)",
                source,
            )
        ]
    if found is not None:  # an unwritable cache costs the next run a compile, nothing else
        write_entry(found[0], MARKER_KIND, found[1], PASSED)
    return "compiled", []


def plugin_identity() -> str | None:
    """What a cached check depends on, without importing the plugin or MuJoCo; ``None`` without a plugin.

    The check plugin's entry point, its distribution and version, every file of its top-level package (path
    and SHA-256 of its content: modification times decide nothing) and the installed MuJoCo distribution's
    version.
    """
    point = installed(MJCF_GROUP, "check")
    if point is None:
        return None
    dist = getattr(point, "dist", None)
    parts = [point.value, f"{dist.name} {dist.version}" if dist is not None else "?"]
    spec = importlib.util.find_spec(point.value.split(":")[0].split(".")[0])  # a top-level name: not imported
    for folder in (spec.submodule_search_locations or []) if spec is not None else []:
        for root, dirs, files in os.walk(folder):
            dirs[:] = sorted(d for d in dirs if d != "__pycache__")
            for name in sorted(files):
                if name.endswith(".py"):
                    path = os.path.join(root, name)
                    parts.append(f"{os.path.relpath(path, folder)} {sha256_of(Path(path))}")
    for name in ("mujoco-core", "mujoco"):
        try:
            parts.append(f"{name} {metadata.version(name)}")
        except metadata.PackageNotFoundError:
            continue
    return "\n".join(parts)


def _marker(cache_dir: Path | None, data: bytes) -> tuple[Path, str] | None:
    """Where a passing check of ``data`` is remembered and the key it answers (``None``: no cache or no plugin).

    The marker is a cache entry (:mod:`meshtool.files.cachefile`) whose payload is :data:`PASSED`: an empty file,
    another marker copied over it, or one damaged is a miss, and the check runs again.
    """
    if cache_dir is None:
        return None
    identity = plugin_identity()
    if identity is None:
        return None
    digest = hashlib.sha256(identity.encode() + b"\0" + data).hexdigest()
    return cache_dir / digest[:2] / f"{digest}.ok", digest


def _describe(packed: PackedMesh, textures: list[TextureDesc]) -> dict[str, str]:
    """Element name -> what it is in the user's terms (part and material, hull, texture file)."""
    parts = list(packed.pack_meta.parts)
    files = list(packed.pack_meta.textures)
    out: dict[str, str] = {}
    for k, (_, _, material, part) in enumerate(packed.submeshes.tolist()):
        material_name = packed.materials[material].get("name") if packed.materials else None
        part_name = parts[part] if part < len(parts) else part
        what = f"visual mesh {k}: part {part_name!r}" + (f", material {material_name!r}" if material_name else "")
        out[f"{PREFIX}_visual_{k}"] = what
    for k in range(len(packed.hulls)):
        out[f"{PREFIX}_collision_{k}"] = f"collision hull {k}"
    for k, texture in enumerate(textures):
        out[texture.name] = f"texture {files[k] if k < len(files) else k}"
    return out


def _refusal(exc: MeshtoolError, names: dict[str, str], source: str) -> ModelError:
    text = exc.message.removeprefix(_REFUSES)
    found = _ELEMENT.search(text)
    element = found.group(1) if found else ""
    text = _ELEMENT.sub("", text).strip()
    for name in sorted(names, key=len, reverse=True):  # MuJoCo repeats the element's name in its message
        text = text.replace(f" '{name}.png'", "")
        if f": {name} " in f"{text} ":  # "mesh volume is too small: NAME . Try setting inertia to shell"
            text = text[: f"{text} ".index(f": {name} ")]
    what = names.get(element, element)
    if element.startswith(f"{PREFIX}_collision_"):
        hint = "the hull is too small or too thin for MuJoCo: check --units and --scale"
    elif element.startswith(f"{PREFIX}_visual_"):
        hint = "fix that part in the source"
    else:
        hint = "fix the source"
    return ModelError(
        f"MuJoCo refuses the converted asset: {text}" + (f" ({what})" if what else ""),
        path=source,
        hint=f"{hint}, or pass --no-check to write the .mbin anyway",
    )
