"""Measure MuJoCo's coefficient of restitution for contact damping ratios (simrun.world.entity.RESTITUTION_TABLE).

Usage: python scripts/calibrate_restitution.py
"""

from __future__ import annotations

import mujoco
import numpy as np

from simrun.world.entity import CONTACT_TIMECONST


def bounce(zeta: float, timestep: float = 0.002, height: float = 1.0) -> float:
    """sqrt(bounce height / drop height) of a 5 cm ball dropped on a plane."""
    spec = mujoco.MjSpec()
    spec.option.timestep = timestep
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[1, 1, 0.1])
    body = spec.worldbody.add_body(pos=[0, 0, height + 0.05])
    body.add_freejoint()
    body.add_geom(
        type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.05, 0, 0], mass=0.1, solref=[CONTACT_TIMECONST, zeta], priority=1
    )
    model = spec.compile()
    data = mujoco.MjData(model)
    z = []
    while data.time < 2.5:
        mujoco.mj_step(model, data)
        z.append(data.qpos[2] - 0.05)
    track = np.array(z)
    first = int(np.argmax(track < 0.002))
    after = track[first:]
    rising = int(np.argmax(np.diff(after) > 0))
    return float(np.sqrt(max(after[rising : rising + int(1.2 / timestep)].max(), 0.0) / height))


if __name__ == "__main__":
    for zeta in (0.15, 0.2, 0.25, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0):
        print(f"({zeta}, {bounce(zeta):.3f}),  # timestep 0.001: {bounce(zeta, 0.001):.3f}")
