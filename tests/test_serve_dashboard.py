"""The dashboard of simrun serve in real headless Chromium (Playwright driving the system browser).

Ground truth from the server: the robot's body pose after the page's forward key; the page's own counters
only say that laser scans and camera frames arrived.
"""

from __future__ import annotations

import shutil
import time
from pathlib import Path

import pytest
from serve_helpers import SCENES, serve

from simrun.record.replay_html import DEFAULT_BUNDLE, VIEWER_VARIABLE

SENSORS = SCENES / "boebot_sensors.toml"
ARGS = ["--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--hide-scrollbars", "--mute-audio"]


def _chromium() -> str:
    for name in ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable"):
        found = shutil.which(name)
        if found:
            return found
    pytest.skip("Chromium is not installed (apt-get install chromium)")


def _until(read, done, timeout: float = 30.0):
    """``read()`` until ``done(value)``, at most ``timeout`` wall seconds (the server's pace varies with load)."""
    deadline = time.monotonic() + timeout
    while True:
        value = read()
        if done(value):
            return value
        assert time.monotonic() < deadline, value
        time.sleep(0.1)


@pytest.fixture(scope="module")
def browser():
    import os

    if not (os.environ.get(VIEWER_VARIABLE) or Path(DEFAULT_BUNDLE).is_file()):
        pytest.skip("the three.js viewer bundle is not installed: run scripts/install_three_viewer.sh")
    sync_api = pytest.importorskip("playwright.sync_api", reason="pip install playwright (no browser download needed)")
    with sync_api.sync_playwright() as playwright:
        chromium = playwright.chromium.launch(executable_path=_chromium(), args=ARGS, headless=True)
        yield chromium
        chromium.close()


def test_dashboard_shows_the_world_and_drives_the_robot(browser):
    with serve(SENSORS) as server:
        page = browser.new_page(viewport={"width": 1100, "height": 700})
        foreign: list[str] = []
        page.on(
            "request",
            lambda r: None if r.url.startswith((server.url, "data:", f"blob:{server.url}")) else foreign.append(r.url),
        )
        page.goto(server.url)
        page.wait_for_function("window.simrunDashboard && window.simrunDashboard.ready", timeout=90_000)
        assert page.evaluate("document.documentElement.dataset.state") == "ready"
        assert not foreign  # offline: everything from this server (blob: URLs are the glTF textures)

        # the robot is in the scene, on screen
        x, y, depth = page.evaluate("window.simrunDashboard.screen('boebot')")
        assert 0 < x < 760 and 0 < y < 700 and depth < 1
        assert "boebot (BoeBot, robot)" in page.inner_text("#entities")

        # forward key: cmd_vel through the server; the simulator says the robot moved forward (+X), straight
        start = server.get("/api/state")["poses"]["boebot"]
        page.keyboard.press("ArrowUp")
        page.keyboard.press("ArrowUp")
        assert page.evaluate("window.simrunDashboard.teleop") == [0.1, 0]
        moved = _until(lambda: server.get("/api/state")["poses"]["boebot"], lambda p: p[0] - start[0] > 0.05)
        assert abs(moved[1] - start[1]) < 0.01
        page.keyboard.press("Space")

        def still(_: object) -> bool:
            before = server.get("/api/state")
            time.sleep(0.5)
            after = server.get("/api/state")
            return (
                after["time"] > before["time"] + 0.1
                and abs(after["poses"]["boebot"][0] - before["poses"]["boebot"][0]) < 0.001
            )

        _until(lambda: None, still)  # space stops it

        # the page shows the new pose, the laser is drawn and the camera panel updates
        page.wait_for_function(f"window.simrunDashboard.poses.boebot[0] > {start[0] + 0.05}", timeout=10_000)
        lasers, images = page.evaluate("[window.simrunDashboard.laserUpdates, window.simrunDashboard.imageUpdates]")
        page.wait_for_function(
            f"window.simrunDashboard.laserUpdates >= {lasers + 3} && window.simrunDashboard.imageUpdates > {images}",
            timeout=30_000,
        )
        size = page.evaluate("[document.getElementById('camera-view_cam').naturalWidth, "
                             "document.getElementById('camera-view_cam').naturalHeight]")  # fmt: skip
        assert size == [160, 120]

        # pause and step from the page
        page.click("#pause")
        page.wait_for_function("document.getElementById('pause').textContent === 'Resume'", timeout=10_000)
        paused = server.get("/api/state")
        assert paused["paused"]
        page.click("#step")
        page.wait_for_function(f"window.simrunDashboard.time > {paused['time'] + 0.01}", timeout=10_000)
        assert server.get("/api/state")["time"] == pytest.approx(paused["time"] + 0.02)
        page.close()


#: A token with URL specials and letters beyond latin-1 (fetch cannot put those in a header as they are).
TOKEN = 'p+a&s=s%w#o?r/d; "quoted" é€ ключ 密钥'


def test_the_dashboard_works_with_any_printable_token(browser):
    from urllib.parse import quote

    with serve(SCENES / "boebot.toml", "--token", TOKEN) as server:
        page = browser.new_page(viewport={"width": 900, "height": 600})
        errors: list[str] = []
        page.on("pageerror", lambda e: errors.append(str(e)))
        page.goto(server.url + "?token=" + quote(TOKEN, safe=""))
        page.wait_for_function("window.simrunDashboard && window.simrunDashboard.ready", timeout=90_000)
        assert page.evaluate("document.documentElement.dataset.state") == "ready", errors
        # the scene (GET /api/scene.glb with the token in Authorization) and a POST from the page
        x, y, depth = page.evaluate("window.simrunDashboard.screen('boebot')")
        assert 0 < x < 900 and 0 < y < 600 and depth < 1
        page.click("#pause")
        page.wait_for_function("document.getElementById('pause').textContent === 'Resume'", timeout=10_000)
        status, state = server.request("GET", "/api/state", headers={"Authorization": "Bearer " + quote(TOKEN)})
        assert status == 200 and state["paused"] is True
        assert not errors
        page.close()
