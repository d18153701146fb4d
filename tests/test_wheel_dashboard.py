"""simrun from its wheel alone: the dashboard drives the robot and a replay page plays offline, in headless Chromium.

The wheel is built from a copy of the checkout (``pip wheel --no-deps``; build isolation, as ``make install``
builds: pip takes setuptools from its cache or the index) and installed with ``pip install --no-deps
--no-index`` into a fresh venv, so the install itself fetches nothing: no npm, no network, no ``tools/``.
The wheel's dependencies come from this interpreter's site-packages through a ``.pth`` path line (its
``.pth`` files, the editable install's finder among them, are not run), and the test checks that every
``Requires-Dist`` of the installed wheel (nicegui, which ships the pages' three.js, included) is met there.
Everything runs from a temporary folder with ``SIMRUN_VIEWER_JS`` unset.

Ground truth: the simulator's state from the server's API (the robot moved forward after the page's key),
Chromium's own request log (nothing but the server, ``data:``/``blob:`` URLs and the page's file), and the
player's clock advancing. Skips, saying why, without Chromium or Playwright.
"""

from __future__ import annotations

import contextlib
import json
import os
import select
import shutil
import signal
import subprocess
import sys
import sysconfig
import time
import urllib.request
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SCENES = ROOT / "fixtures" / "scenes"
ARGS = ["--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--hide-scrollbars", "--mute-audio"]
#: What the wheel is built from (a copy: building in the checkout would leave build/ and *.egg-info there).
SOURCES = ("pyproject.toml", "README.md", "meshtool", "simrun")


def _chromium() -> str:
    for name in ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable"):
        found = shutil.which(name)
        if found:
            return found
    pytest.skip("Chromium is not installed (apt-get install chromium)")


def _env() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in ("SIMRUN_VIEWER_JS", "PYTHONPATH", "VIRTUAL_ENV")}
    env.update(MUJOCO_GL=env.get("MUJOCO_GL", "egl"), PYTHONUNBUFFERED="1", PYTHONNOUSERSITE="1")
    return env


def _run(*command: str | Path, cwd: Path, timeout: float = 300) -> str:
    done = subprocess.run([str(c) for c in command], cwd=cwd, env=_env(), capture_output=True, text=True,
                          timeout=timeout, check=False)  # fmt: skip
    assert done.returncode == 0, (command, done.stdout[-3000:], done.stderr[-3000:])
    return done.stdout


@pytest.fixture(scope="module")
def venv(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The ``bin`` folder of a fresh venv with the built wheel installed (and nothing else of the checkout)."""
    _chromium()
    pytest.importorskip("playwright.sync_api", reason="pip install playwright (no browser download needed)")
    top = tmp_path_factory.mktemp("wheel")
    source = top / "source"
    source.mkdir()
    for name in SOURCES:
        if (ROOT / name).is_dir():
            shutil.copytree(ROOT / name, source / name, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
        else:
            shutil.copy2(ROOT / name, source / name)
    started = time.monotonic()
    _run(sys.executable, "-m", "pip", "wheel", "--no-deps", "--quiet", "-w", top / "dist", source, cwd=top)
    (wheel,) = (top / "dist").glob("meshtool_simrun-*.whl")
    _run(sys.executable, "-m", "venv", top / "venv", cwd=top)
    python = top / "venv" / "bin" / "python"
    site = Path(_run(python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])", cwd=top).strip())
    ours = dict.fromkeys([sysconfig.get_paths()["purelib"], sysconfig.get_paths()["platlib"]])
    (site / "zz_simrun_test_dependencies.pth").write_text("".join(f"{p}\n" for p in ours))
    _run(python, "-m", "pip", "install", "--no-deps", "--no-index", "--quiet", wheel, cwd=top)
    print(
        f"wheel {wheel.name} ({wheel.stat().st_size} bytes) built and installed in {time.monotonic() - started:.1f} s"
    )

    # the wheel's simrun, not the checkout's; every dependency it declares is met; the viewer is nicegui's
    check = """
import json, simrun
from importlib import metadata
from packaging.requirements import Requirement
from simrun.record.replay_html import DEFAULT_BUNDLE
unmet = []
for line in metadata.requires("meshtool-simrun"):
    req = Requirement(line)
    if req.marker is not None and not req.marker.evaluate({"extra": ""}):
        continue
    try:
        version = metadata.version(req.name)
    except metadata.PackageNotFoundError:
        version = None
    if version is None or not req.specifier.contains(version, prereleases=True):
        unmet.append(f"{line} (found {version})")
print(json.dumps({"simrun": simrun.__file__, "unmet": unmet, "bundle": str(DEFAULT_BUNDLE),
                  "nicegui": metadata.version("nicegui")}))
"""
    found = json.loads(_run(python, "-c", check, cwd=top))
    assert Path(found["simrun"]).is_relative_to(site), found
    assert not found["unmet"], found
    bundle = Path(found["bundle"])  # nicegui's module, where pip installed it; not the checkout's tools/
    assert bundle.is_file() and any(bundle.is_relative_to(p) for p in ours), found
    assert not bundle.is_relative_to(ROOT / "tools"), found
    assert (top / "venv" / "bin" / "simrun").is_file()
    return top / "venv" / "bin"


@pytest.fixture(scope="module")
def browser(venv: Path) -> Iterator[object]:
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        chromium = playwright.chromium.launch(executable_path=_chromium(), args=ARGS, headless=True)
        yield chromium
        chromium.close()


def _until(read, done, timeout: float = 30.0):  # type: ignore[no-untyped-def]
    deadline = time.monotonic() + timeout
    while True:
        value = read()
        if done(value):
            return value
        assert time.monotonic() < deadline, value
        time.sleep(0.1)


def _get(url: str) -> bytes:
    with urllib.request.urlopen(url, timeout=30) as response:
        return bytes(response.read())


@contextlib.contextmanager
def _serving(venv: Path, scene: Path, *options: str, cwd: Path) -> Iterator[str]:
    """The wheel's ``simrun serve SCENE OPTIONS`` on 127.0.0.1 (a free port): its URL; ended with SIGINT, exit 0."""
    process = subprocess.Popen(
        [str(venv / "simrun"), "serve", str(scene), "--host", "127.0.0.1", "--port", "0", *options],
        cwd=cwd, env=_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    assert process.stdout is not None
    try:
        line, deadline = "", time.monotonic() + 90
        while time.monotonic() < deadline and process.poll() is None:
            if select.select([process.stdout], [], [], 0.5)[0]:
                line = process.stdout.readline()
                if line.startswith("serving ") or not line:
                    break
        assert line.startswith("serving "), (line, process.poll())
        yield line.split()[1]
    finally:
        if process.poll() is None:
            process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=60)
    assert process.returncode == 0, (out, err)


def _ours(page, url: str) -> list[str]:  # type: ignore[no-untyped-def]
    """The URLs the page requests from anywhere but this server (``data:``/``blob:`` URLs are its own)."""
    foreign: list[str] = []
    page.on("request", lambda r: None if r.url.startswith((url, "data:", f"blob:{url}")) else foreign.append(r.url))
    return foreign


def test_dashboard_from_the_wheel_drives_the_robot(venv: Path, browser, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    with _serving(venv, SCENES / "boebot.toml", cwd=tmp_path) as url:
        assert "from nicegui " in _get(url).decode("utf-8")  # the page's three.js: nicegui's module, inlined

        page = browser.new_page(viewport={"width": 1100, "height": 700})
        foreign = _ours(page, url)
        page.goto(url)
        page.wait_for_function("window.simrunDashboard && window.simrunDashboard.ready", timeout=90_000)
        assert page.evaluate("document.documentElement.dataset.state") == "ready"

        def pose() -> list[float]:
            return list(json.loads(_get(url.rstrip("/") + "/api/state"))["poses"]["boebot"])

        start = pose()
        page.keyboard.press("ArrowUp")
        page.keyboard.press("ArrowUp")
        assert page.evaluate("window.simrunDashboard.teleop") == [0.1, 0]
        moved = _until(pose, lambda p: p[0] - start[0] > 0.05)  # the simulator: forward (+X), straight
        assert abs(moved[1] - start[1]) < 0.01
        page.keyboard.press("Space")
        assert not foreign, foreign  # everything from this server
        page.close()


def test_edit_page_from_the_wheel_moves_a_box_with_its_handle(venv: Path, browser, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """``--edit`` from the wheel: its edit script and the vendored TransformControls (package data) load; a drag
    of the box's X handle moves the simulator's box along +X (``GET /api/entities``), Y and Z kept."""
    edit = "window.simrunDashboard.edit"
    scene = tmp_path / "boebot.toml"
    shutil.copyfile(SCENES / "boebot.toml", scene)
    with _serving(venv, scene, "--edit", cwd=tmp_path) as url:

        def box() -> list[float]:
            entities = json.loads(_get(url.rstrip("/") + "/api/entities"))
            return list(next(e for e in entities if e["name"] == "box")["pose"])

        page = browser.new_page(viewport={"width": 1200, "height": 820})
        foreign = _ours(page, url)
        errors: list[str] = []
        page.on("pageerror", lambda e: errors.append(str(e)))
        page.goto(url)
        page.wait_for_function(f"window.simrunDashboard && {edit} && {edit}.ready", timeout=90_000)
        assert page.evaluate(f"{edit}.allowed") is True
        x, y, _ = page.evaluate("window.simrunDashboard.screen('box')")
        page.mouse.click(x, y)
        page.wait_for_function(f"{edit}.item && {edit}.item.name === 'box'", timeout=20_000)
        before = box()
        hx, hy = page.evaluate(f"{edit}.handleAt('X')")
        ax, ay, _ = page.evaluate(f"{edit}.screenOf([{before[0] + 0.3}, {before[1]}, {before[2]}])")
        page.mouse.move(hx, hy)
        page.mouse.down()
        page.mouse.move(hx + (ax - x) * 0.6, hy + (ay - y) * 0.6, steps=10)
        page.mouse.up()
        after = _until(box, lambda p: p[0] - before[0] > 0.08)
        assert after[0] - before[0] < 0.3 and abs(after[1] - before[1]) < 1e-3, (before, after)
        assert not errors and not foreign, (errors, foreign)
        page.close()


def test_replay_page_from_the_wheel_plays_offline(venv: Path, browser, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    scene, commands = SCENES / "boebot.toml", SCENES / "square.commands.toml"
    _run(venv / "simrun", "play", scene, "--duration", "6", "--commands", commands, "--record", "run.simlog",
         cwd=tmp_path)  # fmt: skip
    _run(venv / "simrun", "replay", "run.simlog", "--html", "run.html", cwd=tmp_path)
    page_file = tmp_path / "run.html"
    print(f"replay page: {page_file.stat().st_size} bytes")

    context = browser.new_context(offline=True, viewport={"width": 800, "height": 600})
    requests: list[str] = []
    context.on("request", lambda r: requests.append(r.url))
    context.route(
        "**/*", lambda route: route.abort() if not route.request.url.startswith("file:") else route.continue_()
    )
    page = context.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(page_file.as_uri() + "#t=1&play")
    page.wait_for_function("window.simrunPlayer && window.simrunPlayer.ready", timeout=90_000)
    assert page.evaluate("document.documentElement.dataset.state") == "ready"
    first = page.evaluate("window.simrunPlayer.time()")
    assert 1.0 <= first < 3.0
    later = _until(lambda: page.evaluate("window.simrunPlayer.time()"), lambda t: t > first + 0.5)
    assert float(page.inner_text("#status")) == pytest.approx(later, abs=0.5)  # the clock on screen moves
    assert not errors, errors
    assert all(u.startswith(("data:", "blob:")) or u.split("#")[0] == page_file.as_uri() for u in requests), requests
    context.close()
