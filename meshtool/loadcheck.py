"""Does MuJoCo accept a packed asset? ``obj2bin``'s check before it writes the ``.mbin``.

The pack is described as a model (:class:`meshtool.model.ModelDesc`) the way simrun loads an ``.mbin``:
one fixed body, one visual mesh per submesh (every one of them, however small; ``inertia="shell"``,
massless), one collision mesh per hull (``inertia="convex"``, density 1000 kg/m^3), its materials and PNG
textures. The ``meshtool.mjcf`` ``check`` plugin (simrun's) compiles it in memory: nothing is written and
nothing is simulated, so the check costs one MuJoCo compile (mesh inertias, hulls, texture decoding).

meshtool never imports MuJoCo: without the plugin (simrun not installed) the check is skipped with a
``mujoco-check-skipped`` note.
"""

from __future__ import annotations

import re

from meshtool.errors import MeshtoolError
from meshtool.findings import Finding, info
from meshtool.model import BodyDesc, ModelDesc, ModelError, TextureDesc, check_model
from meshtool.packfile.read import PackedMesh

#: The name every element of the checked model starts with.
PREFIX = "asset"
#: Density of the collision hulls in the checked model, kg/m^3 (``meshtool mjcf``'s default).
DENSITY = 1000.0
_ELEMENT = re.compile(r"\s*\(element '([^']*)'\)$")
_REFUSES = "MuJoCo refuses the model: "


def check_pack(data: bytes, source: str) -> list[Finding]:
    """Compile the packed asset ``data`` in MuJoCo through the installed plugin.

    Args:
        data: ``.mbin`` bytes.
        source: The input file, as the user named it (for the error and the finding).

    Returns:
        ``[]`` when MuJoCo compiled it; a ``mujoco-check-skipped`` note when no plugin is installed.

    Raises:
        ModelError: MuJoCo refuses the asset: its message, the part, hull or texture at fault, and a hint.
    """
    from meshtool.packfile import parse

    with parse(data, source, verify=False) as packed:  # the packer's own bytes
        from meshtool.mjcf import mesh_parts

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
        return [
            info(
                "mujoco-check-skipped",
                "not compiled in MuJoCo: no MJCF check plugin is installed (install simrun to have obj2bin check "
                "that MuJoCo loads what it writes)",
                source,
            )
        ]
    return []


def _describe(packed: PackedMesh, textures: list[TextureDesc]) -> dict[str, str]:
    """Element name -> what it is in the user's terms (part and material, hull, texture file)."""
    parts = list(packed.meta.get("parts", []))
    files = list(packed.meta.get("textures", []))
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
