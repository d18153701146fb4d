"""The dashboard of ``simrun serve`` (``GET /``): one page, offline, the replay page's three.js viewer.

The page (``simrun/serve/page.html`` and ``page.js``) inlines the viewer bundle that ``simrun replay
--html`` uses (:func:`simrun.record.replay_html.viewer_bundle`) and loads the world's meshes from
``/api/scene.glb`` (:func:`world_glb`: the replay page's glTF, one node per body, without animation);
the WebSocket stream moves the body nodes, draws the laser scans in the scene and fills the camera
panels. Nothing is fetched from another host.
"""

from __future__ import annotations

import html
import json
from pathlib import Path
from typing import Any

import numpy as np

from simrun.errors import SimrunError
from simrun.record.replay_glb import recording_gltf
from simrun.record.replay_html import _script_safe, viewer_bundle
from simrun.record.replay_tracks import Tracks
from simrun.serve.edit_bundle import edit_page_script
from simrun.serve.openapi import API_VERSION
from simrun.world.world import World

_HERE = Path(__file__).resolve().parent


def world_glb(world: World) -> bytes:
    """The world's visual geoms as binary glTF at the current poses (Y-up root, one node per body)."""
    data = world.data
    tracks = Tracks(
        np.array([float(data.time)]), np.array(data.xpos, dtype=np.float64)[None], np.array(data.xquat)[None], 0.02
    )
    return recording_gltf(world, tracks, {}, "live").glb()


def dashboard_html(catalogue: dict[str, Any], token: bool, recording: bool = False) -> str:
    """The dashboard page for a world's ``catalogue``.

    Args:
        catalogue: :func:`simrun.serve.catalogue.build_catalogue` of the served world.
        token: The server needs a token (the page takes it from ``?token=`` and sends it on).
        recording: The server can record (``--record``): the page offers record/stop.

    Raises:
        SimrunError: The viewer bundle is missing (how to install it).
    """
    config = {"catalogue": catalogue, "token": token, "recording": recording, "api_version": API_VERSION}
    values = {
        "CONFIG": json.dumps(config, sort_keys=True).replace("</", "<\\/"),
        "VIEWER": viewer_bundle(),
        "DASHBOARD": _script_safe((_HERE / "page.js").read_text(encoding="utf-8")),
        "EDIT": edit_page_script(),  # edit mode (simrun/serve/edit_page.js), shown when the server allows edits
        "TITLE": html.escape("simrun serve"),
    }
    template = (_HERE / "page.html").read_text(encoding="utf-8")
    parts = template.split("@")
    out = [parts[0]]
    for k in range(1, len(parts), 2):
        if parts[k] not in values:
            raise SimrunError(f"internal: unknown marker @{parts[k]}@ in page.html")
        out += [values[parts[k]], parts[k + 1]]
    return "".join(out)
