import os

os.environ.setdefault("MUJOCO_GL", "egl")  # headless rendering; must be set before mujoco is imported

from pathlib import Path

import pytest

FIXTURES = Path(__file__).resolve().parent.parent / "fixtures"


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
