import os

os.environ.setdefault("MUJOCO_GL", "egl")  # headless rendering; must be set before mujoco is imported

import shutil
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest

CHECKOUT = Path(__file__).resolve().parent.parent
FIXTURES = CHECKOUT / "fixtures"
#: What running the tests may leave in the checkout: Python's and the test tools' own caches.
_CACHES = ("__pycache__", ".pytest_cache", ".hypothesis", ".mypy_cache", ".ruff_cache")
_SOURCES = (".py", ".pyi", ".md", ".toml", ".sh", ".js", ".cjs", ".html", ".css")


def _checkout_entries() -> set[str] | None:
    """Untracked and ignored entries of the checkout (``git status``, folders collapsed); None without git."""
    if shutil.which("git") is None or not (CHECKOUT / ".git").exists():
        return None
    done = subprocess.run(
        ["git", "status", "--porcelain", "--ignored", "--untracked-files=normal"],
        cwd=CHECKOUT,
        capture_output=True,
        text=True,
        check=False,
    )
    if done.returncode != 0:
        return None
    entries = {line[3:] for line in done.stdout.splitlines() if line[:2] == "!!"}
    # an untracked source file is someone's work in progress (a shared tree), not a test's output
    entries |= {line[3:] for line in done.stdout.splitlines() if line[:2] == "??" and not line.endswith(_SOURCES)}
    return {e for e in entries if not any(part in _CACHES for part in Path(e).parts)}


def pytest_sessionstart(session: pytest.Session) -> None:
    """Remember what the checkout holds (in the controller only, when tests run on pytest-xdist workers)."""
    if not hasattr(session.config, "workerinput"):
        session.config.stash[_BEFORE] = _checkout_entries()


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    """Fail the run when tests left files in the checkout (``MUJOCO_LOG.TXT``, outputs written beside inputs)."""
    if hasattr(session.config, "workerinput"):
        return
    before = session.config.stash.get(_BEFORE, None)
    after = _checkout_entries()
    if before is None or after is None:
        return
    stray = sorted(after - before)
    if stray:
        reporter = session.config.pluginmanager.get_plugin("terminalreporter")
        if reporter is not None:
            reporter.write("\n")
            reporter.write_line(f"FAILED: tests left files in the checkout {CHECKOUT}: {', '.join(stray)}", red=True)
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


_BEFORE = pytest.StashKey[set[str] | None]()


@pytest.fixture(scope="session", autouse=True)
def _work_outside_the_checkout(tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    """Every test runs with a temporary working folder: what a library drops into the current folder (MuJoCo's
    ``MUJOCO_LOG.TXT`` on a model warning, Hypothesis' database) never lands in the checkout."""
    here = Path.cwd()
    os.chdir(tmp_path_factory.mktemp("cwd"))
    try:
        yield
    finally:
        os.chdir(here)


@pytest.fixture(autouse=True)
def _private_user_cache(tmp_path_factory: pytest.TempPathFactory, monkeypatch: pytest.MonkeyPatch) -> None:
    """Each test gets its own user cache folder (decompositions, MuJoCo checks): never the developer's, and a
    result cached by one test never answers another's question (subprocesses inherit the variable)."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path_factory.mktemp("user-cache")))


@pytest.fixture
def fixtures() -> Path:
    return FIXTURES


def gl_available() -> tuple[bool, str]:
    """Whether an offscreen OpenGL context starts here, and why not."""
    import mujoco

    try:
        model = mujoco.MjModel.from_xml_string("<mujoco><worldbody><geom size='1'/></worldbody></mujoco>")
        with mujoco.Renderer(model, 8, 8) as renderer:
            renderer.render()
    except Exception as exc:
        return False, f"no OpenGL context ({type(exc).__name__}: {exc})"
    return True, ""


GL, GL_WHY = gl_available()
needs_gl = pytest.mark.skipif(not GL, reason=GL_WHY)
