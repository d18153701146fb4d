"""A recording as one HTML page that plays it in a browser: offline, from a file:// URL, nothing to install.

The page (``simrun/replay_page.html`` and ``replay_page.js``) holds, inline: the animated GLB of
:mod:`simrun.record.replay_glb` (base64), three.js with its glTF loader and orbit controls (:func:`viewer_bundle`:
the ES module the ``nicegui`` distribution installs, a runtime dependency; ``SIMRUN_VIEWER_JS`` names another
bundle), and the player: play/pause, a time slider, the clock, a legend and
labels that follow each moving entity (robots, the trees with hinge, slide or ball joints, highlighted).
The camera looks at the region the moving bodies cover, from the south-west and above; the user can orbit,
pan and zoom. ``PAGE.html#t=12.5`` opens paused at 12.5 s, ``#t=12.5&play`` plays from there.
"""

from __future__ import annotations

import base64
import html
import json
import math
import os
import re
from importlib import metadata
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from simrun.errors import SimrunError
from simrun.export.glb import COLLISION_GROUP
from simrun.outfile import GENERATOR
from simrun.record.replay_glb import recording_gltf
from simrun.record.replay_tracks import I64, Tracks
from simrun.world.world import World

#: Environment variable naming another viewer bundle (else the one built from nicegui's three.js module).
VIEWER_VARIABLE = "SIMRUN_VIEWER_JS"
#: The distribution that ships three.js (r180) with GLTFLoader and OrbitControls as one ES module, and the file.
VIEWER_DISTRIBUTION = "nicegui"
VIEWER_MODULE = "nicegui/elements/scene/dist/index.js"
#: The three exports of that module the pages use (``globalThis.SimrunThree``).
VIEWER_EXPORTS = ("THREE", "GLTFLoader", "OrbitControls")
_HERE = Path(__file__).resolve().parent
#: Camera field of view (vertical, degrees) and the direction it looks from (Z-up world, towards the target).
FOV = 40.0
VIEW_FROM = np.array([-0.45, -1.0, 0.85])
_EXPORT_CLAUSE = re.compile(r"\bexport\s*\{([^{}]*)\}\s*;?\s*(?://[#@] sourceMappingURL=\S*\s*)?\Z")
_NAME = r"[A-Za-z_$][\w$]*"
_SPECIFIER = re.compile(rf"\s*({_NAME})(?:\s+as\s+({_NAME}))?\s*")
#: A static import declaration (at a statement's start) or import.meta: module-only syntax.
_IMPORT = re.compile(
    r"(?:^|[;}])\s*import\s*(?:[{*\"']|[A-Za-z_$][\w$]*\s*(?:,|from\b))|\bimport\.meta\b", re.MULTILINE
)


def _installed_module() -> Path | None:
    """Where the installed ``nicegui`` distribution keeps its three.js module (its RECORD; nothing imported)."""
    try:
        dist = metadata.distribution(VIEWER_DISTRIBUTION)
    except metadata.PackageNotFoundError:
        return None
    return Path(str(dist.locate_file(VIEWER_MODULE)))


#: The installed three.js module the pages are built from (absent when ``nicegui`` is not installed).
DEFAULT_BUNDLE = _installed_module() or _HERE / f"({VIEWER_DISTRIBUTION} is not installed)"


def viewer_bundle() -> str:
    """The viewer's script for a page: a classic script that sets ``globalThis.SimrunThree``.

    Built from the ES module :data:`VIEWER_MODULE` of the installed ``nicegui`` distribution (three.js with
    GLTFLoader and OrbitControls, its licence comments kept): the module's body inside a strict function,
    its ``export {...}`` clause replaced by the assignment of the three :data:`VIEWER_EXPORTS`. Nothing is
    fetched at page load; the same installed version gives the same text, byte for byte.
    ``SIMRUN_VIEWER_JS=PATH`` names another bundle: a script that already sets ``SimrunThree`` (the one
    ``scripts/install_three_viewer.sh`` builds from npm), used as it is, or an ES module with those exports.

    Raises:
        SimrunError: No bundle (how to install one), or a file that has neither form.
    """
    named = os.environ.get(VIEWER_VARIABLE)
    path = Path(named) if named else _installed_module()
    if path is None:
        raise SimrunError(
            f"the HTML player needs three.js from the {VIEWER_DISTRIBUTION!r} distribution, which is not installed: "
            f"pip install 'nicegui>=3.18,<4' (a dependency of simrun), or set {VIEWER_VARIABLE} to a viewer bundle"
        )
    try:
        source = path.read_text(encoding="utf-8")
    except OSError as exc:
        where = f"{VIEWER_VARIABLE}={named}" if named else str(path)
        hint = (
            f"unset {VIEWER_VARIABLE} to use nicegui's three.js, or build a bundle with "
            "scripts/install_three_viewer.sh (needs npm)"
            if named
            else "reinstall nicegui (pip install --force-reinstall 'nicegui>=3.18,<4')"
        )
        raise SimrunError(
            f"the HTML player needs the three.js viewer bundle ({where}: {exc.strerror}); {hint}"
        ) from None
    if named and "SimrunThree" in source:
        return _script_safe(source)
    return _script_safe(_classic_script(source, path))


def _classic_script(module: str, path: Path) -> str:
    """An ES module without imports as a classic script that sets ``globalThis.SimrunThree`` to its exports.

    Raises:
        SimrunError: The module imports, or does not end with an ``export {...}`` clause naming every
            :data:`VIEWER_EXPORTS`.
    """
    clause = _EXPORT_CLAUSE.search(module)
    if clause is None or _IMPORT.search(module, 0, clause.start()):
        raise SimrunError(
            f"{path} is not a self-contained three.js ES module ending in an export clause; "
            f"set {VIEWER_VARIABLE} to a viewer bundle or reinstall 'nicegui>=3.18,<4'"
        )
    exported: dict[str, str] = {}
    for item in clause.group(1).split(","):
        if not item.strip():
            continue
        found = _SPECIFIER.fullmatch(item)
        if found is None:
            raise SimrunError(f"{path}: cannot read the export {item.strip()!r}")
        exported[found.group(2) or found.group(1)] = found.group(1)
    missing = [name for name in VIEWER_EXPORTS if name not in exported]
    if missing:
        raise SimrunError(f"{path} does not export {', '.join(missing)} (exports: {', '.join(sorted(exported))})")
    where = f"{VIEWER_DISTRIBUTION} {_version()}: {VIEWER_MODULE}" if path == _installed_module() else path.name
    names = ", ".join(f"{name}: {exported[name]}" for name in VIEWER_EXPORTS)
    return (
        f"/* three.js with GLTFLoader and OrbitControls from {where} (MIT), as a classic script */\n"
        f'(function () {{\n"use strict";\n{module[: clause.start()].rstrip()}\n'
        f"globalThis.SimrunThree = {{{names}}};\n}})();\n"
    )


def _version() -> str:
    try:
        return metadata.version(VIEWER_DISTRIBUTION)
    except metadata.PackageNotFoundError:
        return "?"


def _script_safe(source: str) -> str:
    """Script text that cannot end its ``<script>`` element early."""
    return source.replace("</script", "<\\/script").replace("</SCRIPT", "<\\/SCRIPT").replace("<!--", "<\\!--")


def _y_up(v: Any) -> list[float]:
    x, y, z = (float(c) for c in v)
    return [x, z, -y]


def _labels(model: mujoco.MjModel, moving: list[int]) -> list[dict[str, Any]]:
    """One label per tree with a moving body: the tree's root body, robots (articulated trees) first.

    A label hangs ``lift`` metres above its body's origin: above every visual geom of the body, 2 cm clear.
    """
    articulated = {int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE), int(mujoco.mjtJoint.mjJNT_BALL)}
    roots = sorted({int(model.body_rootid[b]) for b in moving} - {0})
    labels = []
    for root in roots:
        robot = any(
            int(model.body_rootid[model.jnt_bodyid[j]]) == root and int(model.jnt_type[j]) in articulated
            for j in range(model.njnt)
        )
        name = model.body(root).name or f"body{root}"
        lift = max(
            (
                float(np.linalg.norm(model.geom_pos[g])) + float(model.geom_rbound[g])
                for g in range(model.ngeom)
                if int(model.geom_bodyid[g]) == root and int(model.geom_group[g]) < COLLISION_GROUP
            ),
            default=0.0,
        )
        labels.append({"body": name, "text": name, "robot": robot, "lift": lift + 0.02})
    return sorted(labels, key=lambda item: not item["robot"])


def _camera(tracks: Tracks, moving: list[int]) -> dict[str, Any]:
    """A camera on the region the moving bodies cover (every body, when none moves)."""
    chosen = moving or list(range(1, tracks.positions.shape[1])) or [0]
    points = tracks.positions[:, chosen].reshape(-1, 3)
    low, high = points.min(axis=0), points.max(axis=0)
    target = (low + high) / 2
    radius = max(float(np.linalg.norm(high - low)) / 2, 0.5)
    distance = 1.15 * radius / math.sin(math.radians(FOV) / 2)
    eye = target + VIEW_FROM / np.linalg.norm(VIEW_FROM) * distance
    return {
        "fov": FOV,
        "eye": _y_up(eye),
        "target": _y_up(target),
        "near": distance / 200,
        "far": distance * 200,
        "radius": radius,
    }


def recording_html(world: World, tracks: Tracks, keys: dict[int, I64], title: str, glb: bytes | None = None) -> str:
    """The page (see the module) for ``tracks`` keyed at ``keys``.

    Args:
        world: The compiled world the recording was replayed in.
        tracks: Every body's pose per frame (:func:`simrun.record.replay_tracks.read_tracks`).
        keys: Keyframe indices per moving body.
        title: Shown as the page's title and heading (the recording's name).
        glb: The animation to embed (an edited recording's, :func:`simrun.record.replay_edits.edited_gltf`);
            ``None``: :func:`simrun.record.replay_glb.recording_gltf` of ``tracks``.

    Raises:
        SimrunError: The viewer bundle is missing, or the world has nothing to show.
    """
    viewer = viewer_bundle()
    glb = recording_gltf(world, tracks, keys).glb() if glb is None else glb
    moving = sorted(keys)
    labels = _labels(world.model, moving)
    camera = _camera(tracks, moving)
    config = {
        "start": float(tracks.times[0]),
        "end": float(tracks.times[-1]),
        "camera": camera,
        "sun": [c * camera["radius"] for c in (3.0, 10.0, 6.0)],
        "background": "#dde4ec",
        "labels": labels,
    }
    legend = (
        "".join(f"<li>{html.escape(item['text'])}{' (robot)' if item['robot'] else ''}</li>" for item in labels)
        or "<li>nothing moves</li>"
    )
    values = {
        "GENERATOR": html.escape(GENERATOR),
        "TITLE": html.escape(f"{title} - simrun recording"),
        "HEADING": html.escape(title),
        "LEGEND": legend,
        "CONFIG": json.dumps(config, sort_keys=True).replace("</", "<\\/"),
        "GLB": base64.b64encode(glb).decode("ascii"),
        "VIEWER": viewer,
        "PLAYER": _script_safe((_HERE / "replay_page.js").read_text(encoding="utf-8")),
    }
    template = (_HERE / "replay_page.html").read_text(encoding="utf-8")
    parts = template.split("@")
    out = [parts[0]]
    for k in range(1, len(parts), 2):  # @NAME@ markers alternate with the text between them
        if parts[k] not in values:
            raise SimrunError(f"internal: unknown marker @{parts[k]}@ in replay_page.html")
        out += [values[parts[k]], parts[k + 1]]
    return "".join(out)
