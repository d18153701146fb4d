"""Environment checks: is MuJoCo usable here, and which headless rendering backend starts."""

from __future__ import annotations

import os
import subprocess
import sys
from dataclasses import dataclass, field

import mujoco

from simrun.run.headless import HEADLESS, PACKAGES, GLChoice, available, gl_choice

_PROBE = """
import mujoco
model = mujoco.MjModel.from_xml_string('<mujoco><worldbody><geom size="1"/></worldbody></mujoco>')
data = mujoco.MjData(model)
with mujoco.Renderer(model, 8, 8) as renderer:
    renderer.update_scene(data)
    renderer.render()
"""


@dataclass(slots=True)
class DoctorReport:
    """What :func:`check_environment` found.

    Attributes:
        mujoco_version: ``mujoco.__version__``.
        physics_ok: Whether a model compiled and stepped.
        physics_error: The error when it did not.
        gl: Backend name (``egl``, ``osmesa``) to ``None`` when it rendered, else the error's last line.
        choice: The backend this process uses and how it was chosen (:mod:`simrun.run.headless`).
    """

    mujoco_version: str
    physics_ok: bool
    physics_error: str | None
    gl: dict[str, str | None] = field(default_factory=dict)
    choice: GLChoice | None = None

    def lines(self) -> list[str]:
        """Human-readable report lines."""
        out = [
            f"mujoco {self.mujoco_version}: physics {'ok' if self.physics_ok else 'FAILED: ' + str(self.physics_error)}"
        ]
        if self.choice is not None:
            used = self.choice.backend or "none"
            problem = f"; cannot render: {self.choice.problem}" if self.choice.problem else ""
            out.append(f"rendering uses MUJOCO_GL={used} ({self.choice.reason}){problem}")
        for backend, error in self.gl.items():
            out.append(f"MUJOCO_GL={backend}: {'renders' if error is None else 'unavailable (' + error + ')'}")
        return out


def check_environment(backends: tuple[str, ...] = HEADLESS, timeout_s: float = 60.0) -> DoctorReport:
    """Compile and step a small model here; try each GL backend in a child process (GL init can abort).

    Args:
        backends: ``MUJOCO_GL`` values to try.
        timeout_s: Limit per backend probe, seconds.

    Returns:
        The report.
    """
    ok, error = True, None
    try:
        model = mujoco.MjModel.from_xml_string(
            '<mujoco><worldbody><body pos="0 0 1"><freejoint/><geom size="0.1"/></body>'
            '<geom type="plane" size="1 1 0.1"/></worldbody></mujoco>'
        )
        data = mujoco.MjData(model)
        mujoco.mj_step(model, data, 500)
        if not 0.05 < float(data.qpos[2]) < 0.15:
            ok, error = False, f"sphere ended at z={float(data.qpos[2]):.3f} m, expected to rest at 0.1 m"
    except Exception as exc:  # report any MuJoCo failure as a finding of the check
        ok, error = False, f"{type(exc).__name__}: {exc}"
    gl: dict[str, str | None] = {}
    for backend in backends:
        if backend in PACKAGES and not available(backend):
            gl[backend] = f"libraries not installed: apt-get install {' '.join(PACKAGES[backend])}"
            continue
        env = dict(os.environ, MUJOCO_GL=backend, PYOPENGL_PLATFORM=backend)
        try:
            proc = subprocess.run(
                [sys.executable, "-c", _PROBE],
                env=env,
                capture_output=True,
                text=True,
                timeout=timeout_s,
                check=False,
            )
            last = (proc.stderr.strip().splitlines() or ["exit code " + str(proc.returncode)])[-1]
            gl[backend] = None if proc.returncode == 0 else last[:200]
        except subprocess.TimeoutExpired:
            gl[backend] = f"timed out after {timeout_s:.0f} s"
    return DoctorReport(mujoco.__version__, ok, error, gl, gl_choice())
