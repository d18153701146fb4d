"""Wheels and their DC motors: the one description a drive reads, whatever robot carries them.

A robot drives on two wheel joints (hinges), each turned by a DC motor: torque =
``stall_torque * (power - speed / no_load_speed)`` (power in [-1, 1], speed in rad/s), clamped to
``[-stall_torque, stall_torque]`` (the motor driver's current limit). At full power a wheel without load turns
at ``no_load_speed``; held still it pushes with ``stall_torque``. :meth:`DCMotor.add_to` builds that actuator
(MuJoCo: fixed gain ``stall_torque``, affine bias ``-stall_torque / no_load_speed`` times the joint speed,
which the implicit integrators treat as damping); it is the only place simrun builds a wheel motor.

:class:`Wheels` is what :class:`~simrun.services.drive_service.DriveService`, teleoperation, recordings and the
dashboard read (through the robot contract, :mod:`simrun.robots.contract`). A wheel's radius is given, or
measured by :func:`wheel_radius` from the compiled model: the largest distance from the wheel joint's axis of
any point of the collision geometry rigidly attached to the wheel's body (spheres, capsules and cylinders
exactly, boxes by their corners, meshes by their compiled vertices, ellipsoids exactly when one semi-axis lies
along the joint axis). The track is the distance between the two wheel bodies along the left wheel's axis at
the model's initial pose.

:class:`WheelFields` declares the scene keys of robots that name their wheels among the joints of a model
(:class:`~simrun.robots.mjcf_robot.MjcfRobot`, :class:`~simrun.robots.urdf_robot.UrdfRobot`):
``wheels = ["left", "right"]`` and optionally ``wheel_radius``, ``track``, ``stall_torque``, ``no_load_speed``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from simrun.errors import EntityError

#: Points per rim circle where a cylinder's axis is not the wheel's (a tilted cylinder is sampled).
RIM_POINTS = 720
#: Points on an ellipsoid sampled where none of its semi-axes lies along the wheel's axis.
ELLIPSOID_POINTS = 4096
_ALIGNED = 1e-9  # |cos| within this of 1: parallel; offsets below this times the size: on the axis


@dataclass(frozen=True, slots=True)
class DCMotor:
    """A DC motor after its gearbox.

    Attributes:
        stall_torque: Torque at power 1 with the wheel held still, N m.
        no_load_speed: Wheel speed at power 1 without load, rad/s.
    """

    stall_torque: float
    no_load_speed: float

    def check(self, who: str) -> None:
        """Raise :class:`EntityError` naming ``who`` unless both numbers are positive and finite."""
        for key, value in (("stall_torque", self.stall_torque), ("no_load_speed", self.no_load_speed)):
            if isinstance(value, bool) or not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise EntityError(f"{who}: {key} must be a positive number, got {value!r}", key=key)

    def torque(self, power: float, speed: float) -> float:
        """Joint torque, N m, at ``power`` (clipped to [-1, 1]) and wheel ``speed`` (rad/s), clamped to the stall."""
        p = min(1.0, max(-1.0, float(power)))
        tau = self.stall_torque * (p - float(speed) / self.no_load_speed)
        return min(self.stall_torque, max(-self.stall_torque, tau))

    def add_to(self, spec: mujoco.MjSpec, name: str, joint: str) -> Any:
        """Add this motor as the actuator ``name`` on the hinge ``joint`` of ``spec`` (full names); returns it."""
        motor = spec.add_actuator(name=name, target=joint, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        motor.gaintype, motor.biastype = mujoco.mjtGain.mjGAIN_FIXED, mujoco.mjtBias.mjBIAS_AFFINE
        motor.gainprm[0] = self.stall_torque
        motor.biasprm[:3] = [0.0, 0.0, -self.stall_torque / self.no_load_speed]
        motor.ctrllimited = motor.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
        motor.ctrlrange = [-1.0, 1.0]
        motor.forcerange = [-self.stall_torque, self.stall_torque]
        return motor


@dataclass(frozen=True, slots=True)
class Wheels:
    """The two driven wheels of a robot, as a drive sees them (full names in the world's model).

    Attributes:
        left: The left wheel's hinge joint.
        right: The right wheel's hinge joint.
        left_motor: The left wheel's motor (actuator).
        right_motor: The right wheel's motor.
        radius: Wheel radius, m (given, or measured by :func:`wheel_radius`).
        track: Distance between the wheels along their axis, m.
        motor: Both wheels' motor.
        base: The body that carries the robot (its root: the free joint's body for a mobile robot), whose
            pose odometry estimates.
    """

    left: str
    right: str
    left_motor: str
    right_motor: str
    radius: float
    track: float
    motor: DCMotor
    base: str

    @property
    def top_speed(self) -> float:
        """Surface speed of a wheel at full power without load, m/s."""
        return self.motor.no_load_speed * self.radius


@dataclass(kw_only=True)
class WheelFields:
    """The wheel keys of a robot that names two of its model's joints as wheels.

    Attributes:
        wheels: Left and right wheel joints (names inside the model); empty: the robot does not drive.
            Each gets simrun's DC motor (``NAME/left_motor``, ``NAME/right_motor``), replacing the model's
            own actuators on that joint.
        wheel_radius: Metres; ``None``: measured from the left wheel's collision geometry (:func:`wheel_radius`).
        track: Metres; ``None``: the distance between the two wheel bodies at the initial pose.
        stall_torque: Wheel torque at power 1 held still, N m.
        no_load_speed: Wheel speed at power 1 without load, rad/s.
    """

    wheels: tuple[str, ...] = ()
    wheel_radius: float | None = None
    track: float | None = None
    stall_torque: float = 1.0
    no_load_speed: float = 10.0

    @property
    def motor(self) -> DCMotor:
        """The wheels' DC motor."""
        return DCMotor(self.stall_torque, self.no_load_speed)

    def add_wheel_motors(self, child: mujoco.MjSpec, who: str, file: str) -> None:
        """Give the two wheel joints of the model ``child`` their motors ``left_motor``, ``right_motor``.

        Raises:
            EntityError: Not two joints of the model (``file``), or a motor number that is not positive.
        """
        if len(self.wheels) != 2:
            raise EntityError(f"{who}: wheels names 2 joints (left, right), got {len(self.wheels)}", key="wheels")
        self.motor.check(who)
        for key, value in (("wheel_radius", self.wheel_radius), ("track", self.track)):
            if value is not None and not (math.isfinite(value) and value > 0):
                raise EntityError(f"{who}: {key} must be a positive number, got {value!r}", key=key)
        joints = {j.name for j in child.joints}
        for wheel in self.wheels:
            if wheel not in joints:
                known = ", ".join(sorted(n for n in joints if n)) or "none"
                raise EntityError(
                    f"{who}: wheels names {wheel!r}, not a joint of {file} (joints: {known})", key="wheels"
                )
        for actuator in list(child.actuators):
            if int(actuator.trntype) == int(mujoco.mjtTrn.mjTRN_JOINT) and actuator.target in self.wheels:
                child.delete(actuator)
        for side, joint in zip(("left", "right"), self.wheels, strict=True):
            self.motor.add_to(child, f"{side}_motor", joint)

    def named_wheels(self, full_name: str, model: mujoco.MjModel, base: str) -> Wheels | None:
        """The wheels in the world's compiled ``model`` (``None`` without ``wheels``); ``base``: the root body."""
        if not self.wheels:
            return None
        left, right = (f"{full_name}/{w}" for w in self.wheels)
        measured_radius, measured_track = measure(model, left, right)
        return Wheels(
            left,
            right,
            f"{full_name}/left_motor",
            f"{full_name}/right_motor",
            self.wheel_radius if self.wheel_radius is not None else measured_radius,
            self.track if self.track is not None else measured_track,
            self.motor,
            base,
        )


def measure(model: mujoco.MjModel, left: str, right: str) -> tuple[float, float]:
    """(radius of the left wheel, track) of two wheel joints of a compiled model, metres, at its initial pose."""
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    joint = model.joint(left).id
    radius = wheel_radius(model, data, joint)
    bodies = [int(model.jnt_bodyid[joint]), int(model.jnt_bodyid[model.joint(right).id])]
    axis = data.xaxis[joint]
    track = abs(float(np.dot(data.xpos[bodies[1]] - data.xpos[bodies[0]], axis)))
    return radius, track


def wheel_radius(model: mujoco.MjModel, data: mujoco.MjData, joint: int) -> float:
    """The largest distance (m) of the wheel's collision geometry from the hinge ``joint``'s axis.

    The geometry is every geom that collides (``contype`` or ``conaffinity`` set) on the joint's body and the
    bodies welded to it, placed as ``data`` (after ``mj_kinematics``) says.

    Raises:
        EntityError: The wheel has no collision geometry (give ``wheel_radius``).
    """
    body = int(model.jnt_bodyid[joint])
    anchor, axis = np.array(data.xanchor[joint]), np.array(data.xaxis[joint])
    axis /= np.linalg.norm(axis)
    weld = int(model.body_weldid[body])
    best = -1.0
    for g in range(model.ngeom):
        collides = model.geom_contype[g] or model.geom_conaffinity[g]
        if int(model.body_weldid[model.geom_bodyid[g]]) != weld or not collides:
            continue
        extent = _extent(model, g, np.array(data.geom_xpos[g]), data.geom_xmat[g].reshape(3, 3), anchor, axis)
        best = max(best, extent)
    if best <= 0:
        name = model.joint(joint).name
        raise EntityError(
            f"wheel joint {name!r}: its body has no collision geometry to measure a radius from; give wheel_radius",
            key="wheel_radius",
        )
    return best


def _extent(
    model: mujoco.MjModel,
    g: int,
    centre: np.ndarray[Any, np.dtype[np.float64]],
    rotation: np.ndarray[Any, np.dtype[np.float64]],
    anchor: np.ndarray[Any, np.dtype[np.float64]],
    axis: np.ndarray[Any, np.dtype[np.float64]],
) -> float:
    """Largest distance from the axis of geom ``g`` (world frame centre and rotation), m; 0 for planes."""

    def radial(points: np.ndarray[Any, np.dtype[np.float64]]) -> float:
        offsets = np.atleast_2d(points) - anchor
        perpendicular = offsets - np.outer(offsets @ axis, axis)
        return float(np.linalg.norm(perpendicular, axis=1).max())

    kind, size = int(model.geom_type[g]), model.geom_size[g]
    geom = mujoco.mjtGeom
    scale = float(np.max(np.abs(size))) or 1.0
    on_axis = radial(centre) <= _ALIGNED * scale
    if kind == geom.mjGEOM_SPHERE:
        return radial(centre) + float(size[0])
    if kind == geom.mjGEOM_CAPSULE:
        ends = np.array([centre + rotation[:, 2] * size[1], centre - rotation[:, 2] * size[1]])
        return radial(ends) + float(size[0])
    if kind == geom.mjGEOM_CYLINDER:
        if on_axis and abs(abs(float(rotation[:, 2] @ axis)) - 1.0) <= _ALIGNED:
            return float(size[0])
        angles = np.linspace(0.0, 2 * math.pi, RIM_POINTS, endpoint=False)
        ring = np.outer(np.cos(angles), rotation[:, 0]) + np.outer(np.sin(angles), rotation[:, 1])
        rims = [centre + sign * size[1] * rotation[:, 2] + size[0] * ring for sign in (1.0, -1.0)]
        return radial(np.vstack(rims))
    if kind == geom.mjGEOM_ELLIPSOID:
        along = [k for k in range(3) if abs(abs(float(rotation[:, k] @ axis)) - 1.0) <= _ALIGNED]
        if on_axis and along:
            return float(max(size[k] for k in range(3) if k != along[0]))
        k = np.arange(ELLIPSOID_POINTS) + 0.5
        z = 1.0 - 2.0 * k / ELLIPSOID_POINTS
        turn = math.pi * (3.0 - math.sqrt(5.0)) * k
        unit = np.column_stack([np.sqrt(1 - z * z) * np.cos(turn), np.sqrt(1 - z * z) * np.sin(turn), z])
        return radial(centre + (unit * size[:3]) @ rotation.T)
    if kind == geom.mjGEOM_BOX:
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * size[:3]
        return radial(centre + corners @ rotation.T)
    if kind == geom.mjGEOM_MESH:
        mesh = int(model.geom_dataid[g])
        first, count = int(model.mesh_vertadr[mesh]), int(model.mesh_vertnum[mesh])
        vertices = np.asarray(model.mesh_vert[first : first + count], dtype=float)
        return radial(centre + vertices @ rotation.T)
    return 0.0
