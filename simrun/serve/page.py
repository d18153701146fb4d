"""The dashboard of ``simrun serve`` (``GET /``): one page, offline, the replay page's three.js viewer.

The page (``simrun/serve/page.html`` and ``page.js``) inlines the viewer bundle that ``simrun replay
--html`` uses (:func:`simrun.record.replay_html.viewer_bundle`) and loads the world's meshes from
``/api/scene.glb`` (:mod:`simrun.serve.scene_glb`: the replay page's glTF, one node per body, without
animation); the WebSocket stream moves the body nodes, draws the laser scans in the scene and fills the camera
panels. Nothing is fetched from another host.
"""

from __future__ import annotations

import html
import json
from pathlib import Path
from typing import Any

from simrun.errors import SimrunError
from simrun.record.replay_html import _script_safe, viewer_bundle
from simrun.serve.edit_bundle import edit_page_script
from simrun.serve.openapi import API_VERSION

_HERE = Path(__file__).resolve().parent


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
