"""DriveService: MSRS's drive service for a differential-drive entity, closed loop on simulated time.

Bound to a robot by name, it runs as a world controller: before every physics step it turns the current
command (power, wheel speeds, a distance to drive, an angle to turn, or a ROS-style ``cmd_vel``) into motor
controls; after every step it integrates odometry from the wheel encoders. Commands return at once;
``busy`` tells whether a distance or rotation is still running (``World.run_until(lambda: not s.busy, t)``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from simrun.drive import DifferentialDrive
from simrun.errors import EntityError
from simrun.world import World


@dataclass(frozen=True, slots=True)
class Odometry:
    """Pose and twist estimated from the wheel encoders.

    Attributes:
        time: Simulation time, s.
        x: Metres, in the odometry frame (the robot's pose at the last reset).
        y: Metres.
        theta: Heading, radians.
        linear: Forward speed, m/s.
        angular: Turn rate, rad/s.
    """

    time: float
    x: float
    y: float
    theta: float
    linear: float
    angular: float


@dataclass(frozen=True, slots=True)
class DriveLimits:
    """Limits of ``cmd_vel`` and speed control.

    Attributes:
        max_linear: m/s.
        max_angular: rad/s.
        max_linear_accel: m/s^2.
        max_angular_accel: rad/s^2.
        command_timeout: Seconds without a new ``cmd_vel`` after which the robot stops.
    """

    max_linear: float = 0.5
    max_angular: float = 3.0
    max_linear_accel: float = 1.0
    max_angular_accel: float = 6.0
    command_timeout: float = 0.5


class DriveService:
    """The drive service of one differential-drive entity.

    Args:
        world: The world holding the robot.
        entity: Full name of a :class:`~simrun.drive.DifferentialDrive` entity.
        limits: ``cmd_vel`` limits.
        radius_scale: Odometry calibration: effective / nominal wheel radius.
        separation_scale: Odometry calibration: effective / nominal wheel separation.
        gain: Proportional gain of wheel-speed control, power per rad/s.
        integral_gain: Integral gain of wheel-speed control, power per rad.
        rate: Control and odometry rate, Hz (controls hold between updates).
    """

    def __init__(
        self,
        world: World,
        entity: str,
        limits: DriveLimits | None = None,
        radius_scale: float = 1.0,
        separation_scale: float = 1.0,
        gain: float = 0.2,
        integral_gain: float = 0.5,
        rate: float = 50.0,
    ) -> None:
        robot = world.entity(entity)
        if not isinstance(robot, DifferentialDrive):
            raise EntityError(f"{entity!r} is a {robot.TYPE}, not a differential-drive robot")
        self.world, self.name, self.robot = world, entity, robot
        self.limits = limits or DriveLimits()
        self.radius = robot.wheel_radius * radius_scale
        self.separation = robot.track * separation_scale
        self.gain, self.ki = gain, integral_gain
        self.enabled = True
        self._mode = "idle"
        self._power = (0.0, 0.0)
        self._speed = (0.0, 0.0)  # wheel surface speeds, m/s
        self._goal: dict[str, float] = {}
        self._cmd = (0.0, 0.0)
        self._cmd_time = -math.inf
        self._vel = (0.0, 0.0)  # limited (linear, angular) actually commanded
        self._wheel_targets = (0.0, 0.0)
        self._integral = [0.0, 0.0]
        self._ids: tuple[int, ...] | None = None
        self._model_id = 0
        self._encoder_zero = np.zeros(2)
        self._last = np.zeros(2)
        self._odom = Odometry(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        self.period = 1.0 / rate
        self.next_time = world.time
        world.controllers.append(self)

    # -- commands ------------------------------------------------------------------------------------------

    def set_drive_power(self, left: float, right: float) -> None:
        """Open-loop power per wheel in [-1, 1] (torque = power x MotorTorqueScaling)."""
        self._require_enabled()
        self._mode, self._power = "power", (_clip(left), _clip(right))

    def drive_speed(self, left: float, right: float) -> None:
        """Closed-loop wheel surface speeds, m/s."""
        self._require_enabled()
        self._mode, self._speed = "speed", (float(left), float(right))

    def drive_distance(self, metres: float, power: float = 0.5) -> None:
        """Drive straight ``metres`` (negative: backwards) and stop, closed loop on the encoders."""
        self._require_enabled()
        left, right = self.encoders()
        self._mode = "distance"
        self._goal = {"start": (left + right) / 2, "distance": float(metres), "speed": self._top_speed(power)}

    def rotate_degrees(self, degrees: float, power: float = 0.5) -> None:
        """Turn in place by ``degrees`` (positive: counter-clockwise seen from above) and stop."""
        self._require_enabled()
        left, right = self.encoders()
        self._mode = "rotate"
        self._goal = {
            "start": (right - left) / 2,
            "arc": math.radians(degrees) * self.separation / 2,
            "speed": self._top_speed(power) * 0.5,
        }

    def cmd_vel(self, linear: float, angular: float) -> None:
        """ROS-style velocity command (m/s, rad/s).

        Limited in value and acceleration by ``limits``; it expires after ``limits.command_timeout`` seconds
        without a new command.
        """
        self._require_enabled()
        self._mode, self._cmd, self._cmd_time = "cmd_vel", (float(linear), float(angular)), self._time()

    def all_stop(self) -> None:
        """Cancel any command and brake the wheels to a stop."""
        self._mode, self._goal, self._vel = "stop", {}, (0.0, 0.0)

    def enable(self, on: bool) -> None:
        """Enable or disable the drive; disabled motors are unpowered and commands are refused."""
        self.enabled = bool(on)
        if not on:
            self._mode = "idle"

    def reset_encoders(self) -> None:
        """Encoders read 0 from now on (odometry restarts at the origin)."""
        model, data = self.world.model, self.world.data
        raw = self._raw_encoders(model, data)
        self._encoder_zero, self._last = raw.copy(), np.zeros(2)
        self._odom = Odometry(float(data.time), 0.0, 0.0, 0.0, 0.0, 0.0)

    # -- state ---------------------------------------------------------------------------------------------

    @property
    def busy(self) -> bool:
        """Whether a ``drive_distance`` or ``rotate_degrees`` is still running."""
        return self._mode in ("distance", "rotate")

    def encoders(self) -> tuple[float, float]:
        """Wheel travel since the last reset, metres (left, right)."""
        model, data = self.world.model, self.world.data
        travel = (self._raw_encoders(model, data) - self._encoder_zero) * self.radius
        return float(travel[0]), float(travel[1])

    def odometry(self) -> Odometry:
        """The latest odometry estimate."""
        return self._odom

    # -- controller hooks ----------------------------------------------------------------------------------

    def tick(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Update odometry from the encoders, then turn the current command into motor controls."""
        self._integrate(model, data)
        left_act, right_act, left_dof, right_dof = self._lookup(model)
        if not self.enabled or self._mode == "idle":
            data.ctrl[left_act] = data.ctrl[right_act] = 0.0
            return
        if self._mode == "power":
            data.ctrl[left_act], data.ctrl[right_act] = self._power
            return
        targets = self._ramp(self._targets(model, data), self.period)
        for k, (act, dof, target) in enumerate(((left_act, left_dof, targets[0]), (right_act, right_dof, targets[1]))):
            error = target / self.radius - data.qvel[dof]
            # PI control on wheel speed; the integral is clamped so it cannot wind up past full power
            self._integral[k] = _limit(self._integral[k] + error * self.period, -1.0 / self.ki, 1.0 / self.ki)
            data.ctrl[act] = _clip(self.gain * error + self.ki * self._integral[k])

    def _integrate(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Odometry: integrate the encoder change since the last update (midpoint heading)."""
        raw = (self._raw_encoders(model, data) - self._encoder_zero) * self.radius
        dl, dr = raw - self._last
        self._last = raw
        ds, dtheta = (dl + dr) / 2, (dr - dl) / self.separation
        o = self._odom
        heading = o.theta + dtheta / 2
        dt = max(float(data.time) - o.time, model.opt.timestep)
        self._odom = Odometry(
            float(data.time),
            o.x + ds * math.cos(heading),
            o.y + ds * math.sin(heading),
            o.theta + dtheta,
            ds / dt,
            dtheta / dt,
        )

    def reset(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """After ``World.reset``: idle, encoders and odometry at zero."""
        self._mode, self._goal = "idle", {}
        self._encoder_zero = self._raw_encoders(model, data)
        self._last = np.zeros(2)
        self._odom = Odometry(float(data.time), 0.0, 0.0, 0.0, 0.0, 0.0)

    # -- recording ------------------------------------------------------------------------------------------

    def snapshot(self) -> dict[str, Any]:
        """Everything that shapes future controls, as JSON-ready values (for checkpoints)."""
        o = self._odom
        return {
            "enabled": self.enabled,
            "mode": self._mode,
            "power": list(self._power),
            "speed": list(self._speed),
            "goal": dict(self._goal),
            "cmd": list(self._cmd),
            "cmd_time": self._cmd_time,
            "vel": list(self._vel),
            "wheel_targets": list(self._wheel_targets),
            "integral": list(self._integral),
            "encoder_zero": [float(v) for v in self._encoder_zero],
            "last": [float(v) for v in self._last],
            "odom": [o.time, o.x, o.y, o.theta, o.linear, o.angular],
            "next_time": self.next_time,
        }

    def restore(self, state: dict[str, Any]) -> None:
        """Inverse of :meth:`snapshot`."""
        self.enabled, self._mode = bool(state["enabled"]), str(state["mode"])
        self._power, self._speed = (state["power"][0], state["power"][1]), (state["speed"][0], state["speed"][1])
        self._goal, self._cmd = dict(state["goal"]), (state["cmd"][0], state["cmd"][1])
        self._cmd_time, self._vel = float(state["cmd_time"]), (state["vel"][0], state["vel"][1])
        self._wheel_targets = (state["wheel_targets"][0], state["wheel_targets"][1])
        self._integral = [float(v) for v in state["integral"]]
        self._encoder_zero, self._last = np.asarray(state["encoder_zero"]), np.asarray(state["last"])
        self._odom = Odometry(*(float(v) for v in state["odom"]))
        self.next_time = float(state["next_time"])

    # -- internals -----------------------------------------------------------------------------------------

    def _targets(self, model: mujoco.MjModel, data: mujoco.MjData) -> tuple[float, float]:
        """Wheel surface speed targets (m/s) for the current mode."""
        if self._mode == "speed":
            return self._speed
        if self._mode == "stop":
            return (0.0, 0.0)
        left, right = self.encoders()
        if self._mode == "distance":
            remaining = self._goal["distance"] - ((left + right) / 2 - self._goal["start"])
            speed = _approach(remaining, self._goal["speed"])
            if abs(remaining) < 0.0005 and abs(data.qvel[self._ids[2]]) * self.radius < 0.005:  # type: ignore[index]
                self._mode = "stop"
            return (speed, speed)
        if self._mode == "rotate":
            remaining = self._goal["arc"] - ((right - left) / 2 - self._goal["start"])
            speed = _approach(remaining, self._goal["speed"])
            if abs(remaining) < 0.0001 and abs(data.qvel[self._ids[2]]) * self.radius < 0.005:  # type: ignore[index]
                self._mode = "stop"
            return (-speed, speed)
        # cmd_vel, with timeout and value/acceleration limits
        lim = self.limits
        linear, angular = self._cmd
        if data.time - self._cmd_time > lim.command_timeout:
            linear = angular = 0.0
        linear = _limit(linear, -lim.max_linear, lim.max_linear)
        angular = _limit(angular, -lim.max_angular, lim.max_angular)
        dt = self.period
        v = self._vel[0] + _limit(linear - self._vel[0], -lim.max_linear_accel * dt, lim.max_linear_accel * dt)
        w = self._vel[1] + _limit(angular - self._vel[1], -lim.max_angular_accel * dt, lim.max_angular_accel * dt)
        self._vel = (v, w)
        half = w * self.separation / 2
        return (v - half, v + half)

    def _ramp(self, targets: tuple[float, float], dt: float) -> tuple[float, float]:
        """Limit how fast wheel speed targets change (the linear acceleration limit), so tyres do not slip."""
        step = self.limits.max_linear_accel * dt
        previous = self._wheel_targets
        ramped = (
            previous[0] + _limit(targets[0] - previous[0], -step, step),
            previous[1] + _limit(targets[1] - previous[1], -step, step),
        )
        self._wheel_targets = ramped
        return ramped

    def _top_speed(self, power: float) -> float:
        """Wheel surface speed (m/s) for a power level: a fraction of the robot's speed at full power."""
        return abs(_clip(power)) * self.limits.max_linear

    def _lookup(self, model: mujoco.MjModel) -> tuple[int, ...]:
        if self._ids is None or self._model_id != id(model):
            n = self.name
            self._ids = (
                model.actuator(f"{n}/left_motor").id,
                model.actuator(f"{n}/right_motor").id,
                int(model.joint(f"{n}/left_wheel").dofadr[0]),
                int(model.joint(f"{n}/right_wheel").dofadr[0]),
                int(model.joint(f"{n}/left_wheel").qposadr[0]),
                int(model.joint(f"{n}/right_wheel").qposadr[0]),
            )
            self._model_id = id(model)
        return self._ids[:4]

    def _raw_encoders(self, model: mujoco.MjModel, data: mujoco.MjData) -> Any:
        self._lookup(model)
        assert self._ids is not None
        return data.qpos[[self._ids[4], self._ids[5]]]

    def _time(self) -> float:
        return float(self.world.data.time)

    def _require_enabled(self) -> None:
        if not self.enabled:
            raise EntityError(f"the drive of {self.name!r} is disabled; call enable(True) first")


def _limit(value: float, low: float, high: float) -> float:
    """Scalar clip (numpy's costs microseconds per call on a Python float)."""
    return low if value < low else high if value > high else value


def _clip(value: float) -> float:
    return float(min(1.0, max(-1.0, value)))


def _approach(remaining: float, top: float, gain: float = 4.0) -> float:
    """Speed towards a goal: proportional near it, capped at ``top`` (m/s)."""
    return _limit(gain * remaining, -top, top)
