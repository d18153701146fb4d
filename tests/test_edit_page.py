"""The dashboard's edit mode (simrun/serve/edit_page.js) in real headless Chromium on a real ``simrun serve --edit``.

Ground truth from the server, never the page: a body's pose from ``GET /api/entities`` after the page's drag of
its move handle; ``GET /api/entities`` for inserted and deleted entities; MuJoCo's ``body_mass`` of the scene
the page saved, compiled here. The page's own state only says what it drew (the body nodes of the scene GLB it
loaded again). Without ``--edit`` the page shows no edit control and the server refuses the edit routes.

``SIMRUN_EDIT_SHOTS=/tmp/shots`` also writes the screenshots of docs/serve.md ("Edit mode in the dashboard") there
(a folder outside the checkout: tests leave no files in it; docs/images/edit-*.png are those, quantized to 48 colours).
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path
from typing import Any
from urllib.parse import quote

import numpy as np
import pytest
from scene_text import boebot_scene
from serve_helpers import SCENES, Server, serve
from test_serve_dashboard import ARGS, TOKEN, _chromium, _until

from simrun.record.replay_html import DEFAULT_BUNDLE, VIEWER_VARIABLE
from simrun.scene.scene_file import load_scene

ED = "window.simrunDashboard.edit"
VIEWPORT = {"width": 1200, "height": 820}


@pytest.fixture(scope="module")
def browser():  # type: ignore[no-untyped-def]
    if not (os.environ.get(VIEWER_VARIABLE) or Path(DEFAULT_BUNDLE).is_file()):
        pytest.skip("the three.js viewer bundle is not installed (pip install nicegui)")
    sync_api = pytest.importorskip("playwright.sync_api", reason="pip install playwright (no browser download needed)")
    with sync_api.sync_playwright() as playwright:
        chromium = playwright.chromium.launch(executable_path=_chromium(), args=ARGS, headless=True)
        yield chromium
        chromium.close()


def _entity(server: Server, name: str, token: str | None = None) -> dict[str, Any] | None:
    sent = {"Authorization": "Bearer " + quote(token)} if token else {}
    status, entities = server.request("GET", "/api/entities", headers=sent)
    assert status == 200, (status, entities)
    return next((e for e in entities if e["name"] == name), None)


def _open(browser, server: Server, query: str = ""):  # type: ignore[no-untyped-def]
    page = browser.new_page(viewport=VIEWPORT)
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(server.url + query)
    page.wait_for_function(f"window.simrunDashboard && {ED} && {ED}.ready", timeout=90_000)
    return page, errors


def _settled(page) -> None:  # type: ignore[no-untyped-def]
    page.wait_for_function(f"{ED}.busy === 0", timeout=30_000)


def _shot(page, name: str) -> None:  # type: ignore[no-untyped-def]
    folder = os.environ.get("SIMRUN_EDIT_SHOTS")
    if not folder:
        return
    from PIL import Image

    path = Path(folder) / f"edit-{name}.png"
    page.screenshot(path=str(path))
    Image.open(path).convert("RGB").quantize(colors=96).save(path, optimize=True)  # small PNGs for the docs


def test_edit_mode_selects_moves_inserts_changes_deletes_undoes_and_saves(browser, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    scene = tmp_path / "boebot.toml"
    shutil.copyfile(SCENES / "boebot.toml", scene)
    with serve(scene, "--edit") as server:
        page, errors = _open(browser, server)
        assert page.evaluate(f"{ED}.allowed") is True
        assert page.locator("#edit-tree button").count() == len(server.get("/api/entities"))

        # click the box in the view: its entity is selected, its pane built from the Box schema
        x, y, depth = page.evaluate("window.simrunDashboard.screen('box')")
        assert 0 < x < VIEWPORT["width"] - 340 and 0 < y < VIEWPORT["height"] and depth < 1
        page.mouse.click(x, y)
        page.wait_for_function(f"{ED}.item && {ED}.item.name === 'box'", timeout=20_000)
        schema = server.get("/api/entities/box")["schema"]
        for key in schema["keys"]:  # every key that can change has a field
            if key["name"] in ("name", "parent", *schema["fixed"]):
                continue
            names = [f["name"] for f in key.get("fields", [key])]
            for name in names:
                assert page.locator(f"#edit-props [data-key^='{name}']").count() >= 1, name
        assert page.locator("#edit-tree button.selected").inner_text().startswith("box")
        _shot(page, "select")

        # drag the X move handle: the server's box moves along +X, Y and Z kept
        before = _entity(server, "box")["pose"]
        hx, hy = page.evaluate(f"{ED}.handleAt('X')")
        ox, oy, _ = page.evaluate("window.simrunDashboard.screen('box')")
        ax, ay, _ = page.evaluate(f"{ED}.screenOf([{before[0] + 0.3}, {before[1]}, {before[2]}])")
        page.mouse.move(hx, hy)
        page.mouse.down()
        page.mouse.move(hx + (ax - ox) * 0.6, hy + (ay - oy) * 0.6, steps=10)
        page.mouse.up()
        page.wait_for_function(f"{ED}.lastMove !== null", timeout=20_000)
        _settled(page)
        after = _entity(server, "box")["pose"]
        assert 0.08 < after[0] - before[0] < 0.3, (before, after)
        assert abs(after[1] - before[1]) < 1e-3 and abs(after[2] - before[2]) < 5e-3
        sent = page.evaluate(f"{ED}.lastMove.sent.position")
        assert abs(after[0] - sent[0]) < 1e-3  # where the handle left it
        _shot(page, "move")

        # undo: the box is back where it was
        page.click("#edit-undo")
        _until(lambda: _entity(server, "box")["pose"], lambda p: abs(p[0] - before[0]) < 1e-3)
        _settled(page)

        # the rotate handle: dragging the Z ring turns the server's box about its vertical axis only
        page.check("input[name=edit-mode][value=rotate]")
        page.wait_for_timeout(200)
        edits = page.evaluate(f"{ED}.edits")
        hx, hy = page.evaluate(f"{ED}.handleAt('Z')")
        ox, oy, _ = page.evaluate("window.simrunDashboard.screen('box')")
        page.mouse.move(hx, hy)
        page.mouse.down()
        page.mouse.move(hx - (hy - oy) * 2, hy + (hx - ox) * 2, steps=16)  # along the ring, away from it
        page.mouse.up()
        page.wait_for_function(f"{ED}.edits > {edits}", timeout=20_000)
        _settled(page)
        w, qx, qy, qz = _entity(server, "box")["pose"][3:]
        assert abs(np.degrees(2 * np.arctan2(qz, w))) > 2.0 and abs(qx) < 1e-3 and abs(qy) < 1e-3, (w, qx, qy, qz)
        _shot(page, "rotate")
        page.click("#edit-undo")
        _until(lambda: _entity(server, "box")["pose"][3], lambda w: w > 1 - 1e-9)
        _settled(page)
        page.check("input[name=edit-mode][value=translate]")

        # the property pane edits the mass; MuJoCo's model of the saved scene has it
        field = page.locator("#edit-props input[data-key='mass']")
        field.fill("7.5")
        field.dispatch_event("change")
        _until(lambda: _entity(server, "box")["values"].get("mass"), lambda m: m == 7.5)
        _settled(page)

        # a sphere from the "new entity" dialog: in GET /api/entities and drawn (a body node of the new GLB)
        loads = page.evaluate(f"{ED}.loads")
        page.click("#edit-new")
        page.select_option("#edit-new-type", "Sphere")
        params = page.locator("#edit-new-params")
        assert params.locator("input[data-key='radius']").get_attribute("placeholder") is None
        assert params.locator("input[data-key='radius']").input_value() == "0.05"  # the registry's default
        assert "radius (m)" in params.inner_text()  # with its unit
        page.fill("#edit-new-name", "ball")
        for k, value in enumerate(("1.3", "1.45", "0.3")):
            page.fill(f"#edit-new-params input[data-key='pose.position[{k}]']", value)
            page.dispatch_event(f"#edit-new-params input[data-key='pose.position[{k}]']", "change")
        page.fill("#edit-new-params input[data-key='radius']", "0.08")
        page.dispatch_event("#edit-new-params input[data-key='radius']", "change")
        _shot(page, "new-entity")
        page.click("#edit-new-insert")
        page.wait_for_function(f"{ED}.loads > {loads} && {ED}.item && {ED}.item.name === 'ball'", timeout=30_000)
        _settled(page)
        ball = _entity(server, "ball")
        assert ball is not None and ball["type"] == "Sphere" and ball["values"]["radius"] == 0.08
        assert np.allclose(ball["pose"][:3], [1.3, 1.45, 0.3], atol=1e-9)
        drawn = page.evaluate(
            """() => { const n = window.simrunDashboard.view.bodies.get('ball'); let meshes = 0;
                       if (n) n.traverse((o) => { if (o.isMesh) meshes += 1; }); return meshes; }"""
        )
        assert drawn >= 1
        bx, by, bdepth = page.evaluate("window.simrunDashboard.screen('ball')")
        assert 0 < bx < VIEWPORT["width"] - 340 and 0 < by < VIEWPORT["height"] and bdepth < 1
        page.wait_for_timeout(300)
        _shot(page, "inserted")

        # delete it, undo the delete: gone, then back (same table), and drawn again
        loads = page.evaluate(f"{ED}.loads")
        page.click("#edit-delete")
        page.wait_for_function(f"{ED}.loads > {loads} && !{ED}.bodyNames().includes('ball')", timeout=30_000)
        assert _entity(server, "ball") is None
        _settled(page)
        page.click("#edit-undo")
        page.wait_for_function(f"{ED}.bodyNames().includes('ball')", timeout=30_000)
        _settled(page)
        back = _entity(server, "ball")
        assert back is not None and back["values"]["radius"] == 0.08

        # save the scene (a download): MuJoCo's own compile of it has the edited mass and the sphere
        with page.expect_download() as download:
            page.click("#edit-save")
        saved = tmp_path / "saved.toml"
        saved.write_text(Path(download.value.path()).read_text(encoding="utf-8"), encoding="utf-8")
        model = load_scene(saved).model
        assert model.body("box").mass[0] == pytest.approx(7.5, abs=1e-12)
        assert model.body("ball").mass[0] == pytest.approx(1000.0 * 4.0 / 3.0 * np.pi * 0.08**3, rel=1e-9)
        assert not errors, errors
        page.close()


def test_without_edit_the_page_has_no_edit_controls_and_the_server_refuses(browser) -> None:  # type: ignore[no-untyped-def]
    with serve(SCENES / "boebot.toml") as server:
        page, errors = _open(browser, server)
        assert page.evaluate(f"{ED}.allowed") is False
        for control in ("#edit-new", "#edit-delete", "#edit-undo", "#edit-save", "#edit-tree", "#edit-props"):
            assert page.locator(control).count() == 0, control
        assert "simrun serve --edit" in page.inner_text("#edit")
        assert "box (Box)" in page.inner_text("#entities")  # the plain list stays
        x, y, _ = page.evaluate("window.simrunDashboard.screen('box')")
        page.mouse.click(x, y)
        page.wait_for_timeout(500)
        assert page.evaluate(f"{ED}.selected") is None
        # the page's own request is refused by the server, which changes nothing
        status = page.evaluate(
            """() => fetch('/api/entities/box', {method: 'PATCH', headers: {'Content-Type': 'application/json'},
                                                 body: JSON.stringify({mass: 9})}).then((r) => r.status)"""
        )
        assert status == 403
        assert _entity(server, "box")["values"]["mass"] == 5.0
        assert not errors, errors
        page.close()


def test_edit_mode_with_a_token(browser) -> None:  # type: ignore[no-untyped-def]
    with serve(SCENES / "boebot.toml", "--edit", "--token", TOKEN) as server:
        page, errors = _open(browser, server, "?token=" + quote(TOKEN, safe=""))
        assert page.evaluate(f"{ED}.allowed") is True, page.inner_text("#edit")
        page.click("#edit-tree button[data-name='box']")
        page.wait_for_function(f"{ED}.item && {ED}.item.name === 'box'", timeout=20_000)
        loads = page.evaluate(f"{ED}.loads")
        field = page.locator("#edit-props input[data-key='mass']")
        field.fill("6.25")
        field.dispatch_event("change")
        _until(lambda: _entity(server, "box", TOKEN)["values"].get("mass"), lambda m: m == 6.25)
        page.wait_for_function(f"{ED}.loads > {loads}", timeout=30_000)  # the rebuilt scene, fetched with the token
        _settled(page)
        assert page.evaluate(f"{ED}.error") == "" and not errors, errors
        page.close()


def test_a_child_entity_moves_relative_to_its_parent(browser) -> None:  # type: ignore[no-untyped-def]
    turn = [np.cos(np.pi / 4), 0.0, 0.0, np.sin(np.pi / 4)]  # the box turned 90 degrees about Z
    with serve(SCENES / "boebot.toml", "--edit") as server:
        server.post("/api/entities/box/teleport", {"position": [1.6, 1.0, 0.1], "orientation": turn})
        lid = {"type": "Box", "name": "lid", "dimensions": [0.12, 0.12, 0.02], "pose": {"position": [0, 0, 0.11]}}
        assert server.post("/api/entities", {"entity": lid, "parent": "box"})["inserted"] == ["box/lid"]
        page, errors = _open(browser, server)
        box0, lid0 = _entity(server, "box"), _entity(server, "box/lid")
        x, y, _ = page.evaluate("window.simrunDashboard.screen('box/lid')")
        page.mouse.click(x, y)  # the child's own body selects the child, not its parent
        page.wait_for_function(f"{ED}.item && {ED}.item.name === 'box/lid'", timeout=20_000)
        # its X handle (the lid's own axes: the turned box's X is the world's +Y)
        hx, hy = page.evaluate(f"{ED}.handleAt('X')")
        p = lid0["pose"]
        ox, oy, _ = page.evaluate(f"{ED}.screenOf([{p[0]}, {p[1]}, {p[2]}])")
        ax, ay, _ = page.evaluate(f"{ED}.screenOf([{p[0]}, {p[1] + 0.3}, {p[2]}])")
        loads = page.evaluate(f"{ED}.loads")
        page.mouse.move(hx, hy)
        page.mouse.down()
        page.mouse.move(hx + (ax - ox) * 0.5, hy + (ay - oy) * 0.5, steps=10)
        page.mouse.up()
        page.wait_for_function(f"{ED}.loads > {loads}", timeout=30_000)  # a welded child's pose: a rebuilt world
        _settled(page)
        box1, lid1 = _entity(server, "box"), _entity(server, "box/lid")
        moved = np.subtract(lid1["pose"][:3], lid0["pose"][:3])
        assert 0.05 < moved[1] < 0.3 and abs(moved[0]) < 5e-3 and abs(moved[2]) < 5e-3, moved
        relative = np.subtract(lid1["values"]["pose"]["position"], lid0["values"]["pose"]["position"])
        assert relative[0] == pytest.approx(moved[1], abs=5e-3) and abs(relative[1]) < 5e-3, relative
        assert np.allclose(box1["pose"], box0["pose"], atol=1e-3)  # the parent stays
        assert not errors, errors
        page.close()


SENSOR_SCENE = boebot_scene(
    drive=False,
    tail="""
[[services]]
type = "DriveService"
entity = "boebot"
rate = 25.0

[[sensors]]
type = "Bumper"
name = "bump"
entity = "boebot"
rate = 40.0
""",
)


def test_the_pane_shows_a_sensors_and_a_services_current_settings_and_a_changed_rate(browser, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    scene = tmp_path / "bump.toml"
    scene.write_text(SENSOR_SCENE)
    with serve(scene, "--edit") as server:
        page, errors = _open(browser, server)
        page.click("#edit-tree button[data-name='boebot']")
        page.wait_for_function(f"{ED}.item && {ED}.item.name === 'boebot'", timeout=20_000)
        rate = page.locator("#edit-props details[data-binding='sensor:bump'] input[data-key='rate']")
        drive = page.locator("#edit-props details[data-binding='service:DriveService'] input[data-key='rate']")
        # the scene's values, not the types' defaults (50 Hz each), and not greyed as defaults
        assert rate.input_value() == "40" and "default" not in (rate.get_attribute("class") or "")
        assert drive.input_value() == "25" and "default" not in (drive.get_attribute("class") or "")
        unset = page.locator("#edit-props details[data-binding='sensor:bump'] input[data-key='geom']")
        assert "default" in (unset.get_attribute("class") or "")  # a key the table lacks: its default, greyed
        # change the sensor's rate in the pane: the server's sensor has it, and the pane built again shows it
        page.click("#edit-props details[data-binding='sensor:bump'] summary")
        edits = page.evaluate(f"{ED}.edits")
        rate.fill("12.5")
        rate.dispatch_event("change")
        _until(lambda: server.get("/api/entities/boebot")["sensor_settings"]["bump"]["rate"], lambda r: r == 12.5)
        page.wait_for_function(f"{ED}.edits > {edits}", timeout=30_000)
        _settled(page)
        assert server.get("/api/sensors")[0]["rate_hz"] == pytest.approx(12.5)  # the live sensor's period
        again = page.locator("#edit-props details[data-binding='sensor:bump']")
        assert again.get_attribute("open") is not None  # still open after the pane was built again
        assert rate.input_value() == "12.5" and "default" not in (rate.get_attribute("class") or "")
        # a change from another client shows when the entity is selected again
        server.request("PATCH", "/api/edit/sensors/bump", {"rate": 8.0})
        page.click("#edit-tree button[data-name='ground']")
        page.wait_for_function(f"{ED}.item && {ED}.item.name === 'ground'", timeout=20_000)
        page.click("#edit-tree button[data-name='boebot']")
        page.wait_for_function(f"{ED}.item && {ED}.item.name === 'boebot'", timeout=20_000)
        assert rate.input_value() == "8"
        assert page.evaluate(f"{ED}.error") == "" and not errors, errors
        page.close()
