"""The physics plugin of ``meshtool validate``: compile, drop, settle, weigh and photograph one asset.

Registered under the entry-point group ``meshtool.validate`` as ``physics`` (see
:mod:`meshtool.validate.plugin_types`). The asset becomes a free body (visual geoms in group 2, its collision
hulls in group 3 at ``limits["density"]``) 5 % of its size (at most :data:`DROP_HEIGHT`) above a plane,
tilted so that it lands on an edge or corner, and is simulated for ``limits["settle_time"]`` seconds with
rolling resistance (:data:`FRICTION`, :data:`CONDIM`):

- P001: MuJoCo refuses to compile it;
- P002: it is still moving at the end (speeds over :data:`REST_LINEAR` m/s, times the size in metres when
  over 1 m, or :data:`REST_ANGULAR` rad/s
  during the last :data:`REST_WINDOW` s), fell through the plane, or the state became non-finite;
- P003: MuJoCo counted warnings (``mjData.warning``);
- P004 / P005: mass or principal inertia outside the limits.

The thumbnail shows the asset upright on the plane from the same free camera twice: visual geoms (left)
and collision geoms (right), each 200 x 150 pixels.
"""

from __future__ import annotations

import io
import math
from pathlib import Path

import mujoco
import numpy as np
import numpy.typing as npt
from PIL import Image, ImageDraw

from meshtool.errors import MeshtoolError
from meshtool.formats import suffix
from meshtool.packfile import parse
from meshtool.validate.plugin_types import PhysicsOutcome
from meshtool.validate.rules import hit
from simrun.errors import SimrunError
from simrun.run.render import open_renderer, scene_option
from simrun.world.assets import AssetLibrary

TIMESTEP = 0.002
#: Speed limits of a body at rest, m/s and rad/s, over the last REST_WINDOW seconds.
REST_LINEAR, REST_ANGULAR, REST_WINDOW = 0.02, 0.2, 0.25
#: The drop attitude: this many degrees about the axis (1, 0.6, 0).
TILT_DEG = 20.0
#: Largest gap between the lowest point and the plane at the start, metres (5 % of the size when smaller).
DROP_HEIGHT = 0.05
#: Contact of the drop: sliding, torsional and rolling friction with condim 6, so that round shapes come to
#: rest the way real ones do (MuJoCo's default condim 3 has no rolling resistance: a ball rolls forever).
FRICTION, CONDIM = (1.0, 0.02, 0.002), 6
THUMB_W, THUMB_H = 200, 150
_gl_failure: list[str] = []  # the reason GL could not start in this process (tried once)


def check_pack(mbin: bytes, name: str, limits: dict[str, float], thumbnail: bool) -> PhysicsOutcome:
    """Check one packed asset (see the module docstring). Never raises for a bad asset."""
    outcome = PhysicsOutcome()
    try:
        packed = parse(mbin, name, verify=False)
    except MeshtoolError as exc:
        outcome.findings.append(hit("P001", f"cannot read the pack: {exc.one_line()}", name))
        return outcome
    positions = np.asarray(packed.positions, dtype=np.float64)
    lo, hi = positions.min(axis=0), positions.max(axis=0)
    size = float(np.linalg.norm(hi - lo)) or 1.0
    tilt = _tilt_quat()
    rotated = positions @ _quat_matrix(tilt).T
    drop_z = min(0.05 * size, DROP_HEIGHT) + 0.001 - float(rotated[:, 2].min())

    spec = mujoco.MjSpec()
    spec.option.timestep = TIMESTEP
    spec.add_texture(
        name="sky",
        type=mujoco.mjtTexture.mjTEXTURE_SKYBOX,
        builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT,
        width=64,
        height=64,
        rgb1=[0.96, 0.97, 0.98],
        rgb2=[0.72, 0.76, 0.82],
    )
    spec.worldbody.add_geom(
        name="floor",
        type=mujoco.mjtGeom.mjGEOM_PLANE,
        size=[3 * size, 3 * size, 0.1],
        rgba=[0.82, 0.82, 0.8, 1],
        friction=list(FRICTION),
        condim=CONDIM,
    )
    spec.worldbody.add_light(pos=[0, 0, 4 * size], dir=[0, 0, -1], diffuse=[0.6, 0.6, 0.6])
    library = AssetLibrary(spec)
    key = Path(f"{Path(name).stem or 'asset'}{suffix('mbin')}")
    library.register(key, packed)
    asset = library.mesh(key, 1.0)
    body = spec.worldbody.add_body(name="asset", pos=[0.0, 0.0, drop_z], quat=list(tilt))
    body.add_freejoint()
    for k, (mesh, material) in enumerate(asset.visual):
        geom = body.add_geom(name=f"visual{k}", type=mujoco.mjtGeom.mjGEOM_MESH, meshname=mesh)
        geom.group, geom.contype, geom.conaffinity, geom.density = 2, 0, 0, 0.0
        if material:
            geom.material = material
    collision = asset.hulls or [library.whole(key, 1.0)]
    for k, mesh in enumerate(collision):
        geom = body.add_geom(name=f"collision{k}", type=mujoco.mjtGeom.mjGEOM_MESH, meshname=mesh)
        geom.group, geom.density, geom.rgba = 3, limits["density"], [0.35, 0.55, 0.85, 1]
        geom.friction, geom.condim = list(FRICTION), CONDIM
    spec.assets = dict(library.vfs)
    try:
        model = spec.compile()
    except ValueError as exc:
        outcome.findings.append(hit("P001", str(exc).replace("\n", " "), name))
        return outcome
    finally:
        packed.close()

    mass = float(model.body_mass[1])
    inertia = np.asarray(model.body_inertia[1], dtype=np.float64)
    outcome.stats.update(mass_kg=mass, inertia_kg_m2=inertia.tolist())
    if not limits["min_mass"] <= mass <= limits["max_mass"]:
        outcome.findings.append(
            hit(
                "P004",
                f"mass {mass:.4g} kg at {limits['density']:g} kg/m^3, outside {limits['min_mass']:g} .. "
                f"{limits['max_mass']:g} kg",
                name,
            )
        )
    ratio = float(inertia.max() / inertia.min()) if inertia.min() > 0 else math.inf
    if ratio > limits["max_inertia_ratio"]:
        outcome.findings.append(
            hit(
                "P005",
                f"principal inertia {', '.join(f'{i:.3g}' for i in inertia)} kg m^2: ratio {ratio:.3g} "
                f"(limit {limits['max_inertia_ratio']:g})",
                name,
            )
        )
    _drop(model, name, size, limits["settle_time"], outcome)
    if thumbnail:
        _thumbnail(model, lo, hi, outcome)
    return outcome


def _drop(model: mujoco.MjModel, name: str, size: float, settle_time: float, outcome: PhysicsOutcome) -> None:
    messages: list[str] = []
    previous = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(messages.append)  # MuJoCo would print them to stdout, into the report
    try:
        _simulate(model, name, size, settle_time, outcome)
    finally:
        mujoco.set_mju_user_warning(previous)
    if messages:
        outcome.stats["mujoco_messages"] = sorted(set(m.strip() for m in messages))[:5]


def _simulate(model: mujoco.MjModel, name: str, size: float, settle_time: float, outcome: PhysicsOutcome) -> None:
    data = mujoco.MjData(model)
    steps = max(1, round(settle_time / TIMESTEP))
    window = max(1, round(REST_WINDOW / TIMESTEP))
    moving_until = 0.0
    worst = (0.0, 0.0)
    rest_linear = REST_LINEAR * max(1.0, size)  # m/s: big bodies settle with proportionally larger jitter
    diverged = False
    for k in range(steps):
        mujoco.mj_step(model, data)
        linear = float(np.linalg.norm(data.qvel[0:3]))
        angular = float(np.linalg.norm(data.qvel[3:6]))
        if not (math.isfinite(linear) and math.isfinite(angular)):
            diverged = True
            break
        if linear > rest_linear or angular > REST_ANGULAR:
            moving_until = (k + 1) * TIMESTEP
        if k >= steps - window:
            worst = (max(worst[0], linear), max(worst[1], angular))
    warnings = {
        mujoco.mjtWarning(i).name.removeprefix("mjWARN_"): int(w.number)
        for i, w in enumerate(data.warning)
        if w.number > 0
    }
    height = float(data.xipos[1][2])  # the centre of mass (the mesh origin may lie anywhere)
    outcome.stats.update(came_to_rest_s=round(moving_until, 4), final_height_m=height, warnings=warnings)
    if warnings:
        shown = ", ".join(f"{k} x{v}" for k, v in sorted(warnings.items()))
        outcome.findings.append(hit("P003", f"MuJoCo warnings during the drop: {shown}", name))
    if diverged or warnings.get("BADQACC"):
        outcome.findings.append(hit("P002", "the simulation diverged (non-finite state) during the drop", name))
    elif height < -0.1 * size:
        outcome.findings.append(hit("P002", f"fell through the floor (centre at z = {height:.3g} m)", name))
    elif worst[0] > rest_linear or worst[1] > REST_ANGULAR:
        outcome.findings.append(
            hit(
                "P002",
                f"still moving after {settle_time:g} s ({worst[0]:.3g} m/s, {worst[1]:.3g} rad/s)",
                name,
            )
        )


def _thumbnail(
    model: mujoco.MjModel, lo: npt.NDArray[np.float64], hi: npt.NDArray[np.float64], outcome: PhysicsOutcome
) -> None:
    if _gl_failure:
        outcome.notes.append(f"no thumbnail: {_gl_failure[0]}")
        return
    model.vis.quality.offsamples = 0
    model.vis.quality.shadowsize = 1024
    model.vis.headlight.diffuse[:] = [0.55, 0.55, 0.55]
    model.vis.headlight.ambient[:] = [0.35, 0.35, 0.35]
    try:
        renderer = open_renderer(model, THUMB_W, THUMB_H)
    except SimrunError as exc:  # one line naming the fix (simrun.run.headless)
        _gl_failure.append(str(exc).removeprefix("cannot render: "))
        outcome.notes.append(f"no thumbnail: {_gl_failure[0]}")
        return
    try:
        data = mujoco.MjData(model)
        data.qpos[0:3] = [0.0, 0.0, -float(lo[2])]
        data.qpos[3:7] = [1.0, 0.0, 0.0, 0.0]
        mujoco.mj_forward(model, data)
        camera = mujoco.MjvCamera()
        centre = (lo + hi) / 2.0
        camera.lookat[:] = [centre[0], centre[1], centre[2] - lo[2]]
        camera.distance = 1.5 * float(np.linalg.norm(hi - lo)) or 1.0
        camera.azimuth, camera.elevation = 135.0, -25.0
        views = []
        for mode in ("visual", "physics"):
            option = scene_option(mode)
            option.flags[mujoco.mjtVisFlag.mjVIS_CONTACTPOINT] = False  # the resting contact would hide the base
            option.flags[mujoco.mjtVisFlag.mjVIS_CONTACTFORCE] = False
            renderer.update_scene(data, camera=camera, scene_option=option)
            views.append(Image.fromarray(renderer.render().copy()))
    finally:
        renderer.close()
    sheet = Image.new("RGB", (2 * THUMB_W + 4, THUMB_H), (255, 255, 255))
    for k, (view, label) in enumerate(zip(views, ("visual", "collision"), strict=True)):
        sheet.paste(view, (k * (THUMB_W + 4), 0))
        ImageDraw.Draw(sheet).text((k * (THUMB_W + 4) + 5, 4), label, fill=(20, 20, 20))
    buffer = io.BytesIO()
    sheet.save(buffer, format="PNG", optimize=True)
    outcome.thumbnail = buffer.getvalue()


def _tilt_quat() -> tuple[float, float, float, float]:
    axis = np.array([1.0, 0.6, 0.0])
    axis /= np.linalg.norm(axis)
    half = math.radians(TILT_DEG) / 2.0
    return (math.cos(half), *(float(a) * math.sin(half) for a in axis))  # type: ignore[return-value]


def _quat_matrix(q: tuple[float, float, float, float]) -> npt.NDArray[np.float64]:
    matrix = np.zeros(9)
    mujoco.mju_quat2Mat(matrix, np.asarray(q, dtype=np.float64))
    return matrix.reshape(3, 3)
