"""DriveService: MSRS's drive service for a differential-drive entity, closed loop on simulated time.

Bound to a robot by name, it runs as a world controller: before every physics step it turns the current
command (power, wheel speeds, a distance to drive, an angle to turn, or a ROS-style ``cmd_vel``) into motor
controls; after every step it integrates odometry from the wheel encoders. Commands return at once;
``busy`` tells whether a distance or rotation is still running (``World.run_until(lambda: not s.busy, t)``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np

from simrun.errors import EntityError
from simrun.robots.contract import drive_wheels

if TYPE_CHECKING:  # the world imports the registry, which names this module: no import back
    from simrun.world.world import World

#: Closed-loop pole of the wheel-speed loop per control period (see DriveService._speed_loop).
POLE = 0.8
#: Control periods a robot must rest on its wheels before a distance or turn starts (none once it has).
SETTLED_TICKS = 5


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
        max_linear_accel: m/s^2 (also the ramp of every wheel-speed target; 0.3 is ARIA's default ``TransAccel``
            for the Pioneer, gentle enough that no ready robot's tyres slip).
        max_angular_accel: rad/s^2.
        command_timeout: Seconds without a new ``cmd_vel`` after which the robot stops.
    """

    max_linear: float = 0.5
    max_angular: float = 3.0
    max_linear_accel: float = 0.3
    max_angular_accel: float = 6.0
    command_timeout: float = 0.5


class DriveService:
    """The drive service of one differential-drive entity.

    Args:
        world: The world holding the robot.
        entity: Full name of a robot with wheels (:func:`simrun.robots.contract.drive_wheels`: a
            ``DifferentialDrive``, a catalogue robot, an ``MjcfRobot`` or ``UrdfRobot`` naming ``wheels``).
        limits: ``cmd_vel`` limits.
        radius_scale: Odometry calibration: effective / nominal wheel radius.
        separation_scale: Odometry calibration: effective / nominal wheel separation.
        gain: Proportional gain of wheel-speed control, power per rad/s; ``None``: derived from the robot's
            motor and inertia (:meth:`speed_loop`).
        integral_gain: Integral gain of wheel-speed control, power per rad; ``None``: derived.
        rate: Control and odometry rate, Hz (controls hold between updates).

    Raises:
        EntityError: The entity is not a robot with wheels (the message says how to name them), or a number
            is not positive and finite.
    """

    def __init__(
        self,
        world: World,
        entity: str,
        limits: DriveLimits | None = None,
        radius_scale: float = 1.0,
        separation_scale: float = 1.0,
        gain: float | None = None,
        integral_gain: float | None = None,
        rate: float = 50.0,
    ) -> None:
        wheels = drive_wheels(world, entity)
        _finite("drive service", radius_scale=radius_scale, separation_scale=separation_scale, rate=rate)
        _finite("drive service", positive=False, gain=gain, integral_gain=integral_gain)
        self.world, self.name, self.robot = world, entity, world.entity(entity)
        #: The wheels and motors driven (the robot contract's), and the body carrying the robot (full names)
        self.wheels = wheels
        self._joint_names = (wheels.left, wheels.right)
        self._base = wheels.base
        self.limits = limits or DriveLimits()
        self.radius = wheels.radius * radius_scale
        self.separation = wheels.track * separation_scale
        self._fixed_gains = (gain, integral_gain)
        self.gain, self.ki = 0.0, 0.0  # set from the compiled model on the first tick (speed_loop)
        self._design: dict[str, float] = {}
        self._free = -1  # first dof of the robot's free joint (-1: none)
        self._timestep = world.options.timestep
        self._rested = False  # has stood still on its wheels since the start (or reset)
        self.max_wheel_speed = wheels.motor.no_load_speed
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
        self._bound: mujoco.MjModel | None = None  # the model the cached ids are for (held: a freed id is reused)
        self._encoder_zero = (0.0, 0.0)  # raw wheel angles (rad) at the last reset
        self._last = (0.0, 0.0)  # wheel travel (m) at the last odometry update
        #: Odometry fields as a plain tuple (time, x, y, theta, linear, angular): built into an Odometry on request
        self._odom: tuple[float, float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        self.period = 1.0 / rate
        self.next_time = world.time
        world.controllers.append(self)

    # -- commands ------------------------------------------------------------------------------------------

    def set_drive_power(self, left: float, right: float) -> None:
        """Open-loop motor power per wheel in [-1, 1]: the fraction of the motor's full voltage.

        At power 1 a wheel without load turns at the robot's ``no_load_speed``; held still it pushes with the
        motor's ``stall_torque`` (the DC-motor model of :mod:`simrun.robots.diff_drive`).
        """
        self._require_enabled()
        _finite("set_drive_power", positive=False, left=left, right=right)
        self._mode, self._power = "power", (_clip(left), _clip(right))

    def drive_speed(self, left: float, right: float) -> None:
        """Closed-loop wheel surface speeds, m/s (beyond the motor's top speed the wheel runs at full power)."""
        self._require_enabled()
        _finite("drive_speed", positive=False, left=left, right=right)
        self._start("speed")
        self._speed = (float(left), float(right))

    def drive_distance(self, metres: float, power: float = 0.5) -> None:
        """Drive straight ``metres`` (negative: backwards) and stop, closed loop on the encoders.

        ``power`` in (0, 1] sets the cruising speed: that fraction of the robot's top speed (at most
        ``limits.max_linear``).
        """
        self._require_enabled()
        _finite("drive_distance", positive=False, metres=metres)
        _finite("drive_distance", power=power)
        self._start("distance")
        self._goal = {"start": 0.0, "distance": float(metres), "speed": self._top_speed(power), "started": 0.0}

    def rotate_degrees(self, degrees: float, power: float = 0.5) -> None:
        """Turn in place by ``degrees`` (positive: counter-clockwise seen from above) and stop.

        The wheels run at half the speed ``power`` gives :meth:`drive_distance`.
        """
        self._require_enabled()
        _finite("rotate_degrees", positive=False, degrees=degrees)
        _finite("rotate_degrees", power=power)
        self._start("rotate")
        self._goal = {
            "start": 0.0,
            "arc": math.radians(degrees) * self.separation / 2,
            "speed": self._top_speed(power) * 0.5,
            "started": 0.0,
        }

    def cmd_vel(self, linear: float, angular: float) -> None:
        """ROS-style velocity command (m/s, rad/s).

        Limited in value and acceleration by ``limits``; it expires after ``limits.command_timeout`` seconds
        without a new command.
        """
        self._require_enabled()
        _finite("cmd_vel", positive=False, linear=linear, angular=angular)
        if self._mode != "cmd_vel":
            self._start("cmd_vel")
            self._vel = self._measured_velocity()
        self._mode, self._cmd, self._cmd_time = "cmd_vel", (float(linear), float(angular)), self._time()

    def all_stop(self) -> None:
        """Cancel any command and brake the wheels to a stop."""
        self._start("stop")
        self._goal, self._vel = {}, (0.0, 0.0)

    def enable(self, on: bool) -> None:
        """Enable or disable the drive; disabled motors get no power and commands are refused.

        Unpowered DC motors still brake by their back EMF (the driver shorts them, as an idle H-bridge).
        """
        self.enabled = bool(on)
        if not on:
            self._mode = "idle"

    def reset_encoders(self) -> None:
        """Encoders read 0 from now on (odometry restarts at the origin)."""
        model, data = self.world.model, self.world.data
        self._encoder_zero, self._last = self._raw_encoders(model, data), (0.0, 0.0)
        self._odom = (float(data.time), 0.0, 0.0, 0.0, 0.0, 0.0)

    # -- state ---------------------------------------------------------------------------------------------

    @property
    def busy(self) -> bool:
        """Whether a ``drive_distance`` or ``rotate_degrees`` is still running."""
        return self._mode in ("distance", "rotate")

    def encoders(self) -> tuple[float, float]:
        """Wheel travel since the last reset, metres (left, right)."""
        model, data = self.world.model, self.world.data
        (left, right), (zero_left, zero_right) = self._raw_encoders(model, data), self._encoder_zero
        return (left - zero_left) * self.radius, (right - zero_right) * self.radius

    def odometry(self) -> Odometry:
        """The latest odometry estimate: the body origin (the axle midpoint) in the frame of the last reset."""
        return Odometry(*self._odom)

    def speed_loop(self) -> dict[str, float]:
        """The wheel-speed loop's design, from the compiled model (see docs/robots.md, "Speed loop").

        Returns:
            ``inertia`` (kg m^2, a wheel's share of the robot's inertia), ``time_constant`` (s, the motor's
            mechanical time constant under that load), ``gain`` (power per rad/s), ``integral_gain`` (power
            per rad) and ``pole`` (the closed loop's slowest discrete pole per control period).
        """
        model = self.world.model
        self._lookup(model)
        return dict(self._design)

    # -- controller hooks ----------------------------------------------------------------------------------

    def tick(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Update odometry from the encoders, then turn the current command into motor controls."""
        left_act, right_act, left_dof, right_dof = self._lookup(model)
        self._integrate(model, data)
        if not self.enabled or self._mode == "idle":
            data.ctrl[left_act] = data.ctrl[right_act] = 0.0
            return
        if self._mode == "power":
            data.ctrl[left_act], data.ctrl[right_act] = self._power
            return
        targets = self._ramp(self._targets(data), self.period)
        top, gain, ki, h, radius = self.max_wheel_speed, self.gain, self.ki, self.period, self.radius
        qvel, ctrl, integrals = data.qvel, data.ctrl, self._integral
        for k, act, dof in ((0, left_act, left_dof), (1, right_act, right_dof)):
            wanted = targets[k] / radius
            error = wanted - qvel.item(dof)
            # feed-forward (the motor's steady state) plus PI on wheel speed; the integral stops while the
            # output is saturated in the error's direction (no wind-up)
            integral = integrals[k] + error * h
            power = wanted / top + gain * error + ki * integral
            if (power > 1.0 and error > 0) or (power < -1.0 and error < 0):
                integral = integrals[k]
                power = wanted / top + gain * error + ki * integral
            integrals[k] = integral
            ctrl[act] = 1.0 if power > 1.0 else -1.0 if power < -1.0 else power

    def _integrate(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Odometry: integrate the encoder change since the last update (midpoint heading)."""
        ids, qpos, radius = self._ids, data.qpos, self.radius
        assert ids is not None
        zero_left, zero_right = self._encoder_zero
        last_left, last_right = self._last
        left = (qpos.item(ids[4]) - zero_left) * radius
        right = (qpos.item(ids[5]) - zero_right) * radius
        dl, dr = left - last_left, right - last_right
        self._last = (left, right)
        ds, dtheta = (dl + dr) / 2, (dr - dl) / self.separation
        then, x, y, theta = self._odom[:4]
        heading = theta + dtheta / 2
        now = data.time
        dt = max(now - then, self._timestep)
        self._odom = (now, x + ds * math.cos(heading), y + ds * math.sin(heading), theta + dtheta, ds / dt, dtheta / dt)

    def reset(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """After ``World.reset``: idle, encoders and odometry at zero."""
        self._mode, self._goal, self._rested = "idle", {}, False
        self._integral, self._wheel_targets, self._vel = [0.0, 0.0], (0.0, 0.0), (0.0, 0.0)
        self._encoder_zero = self._raw_encoders(model, data)
        self._last = (0.0, 0.0)
        self._odom = (float(data.time), 0.0, 0.0, 0.0, 0.0, 0.0)

    # -- recording ------------------------------------------------------------------------------------------

    def snapshot(self) -> dict[str, Any]:
        """Everything that shapes future controls, as JSON-ready values (for checkpoints)."""
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
            "odom": list(self._odom),
            "next_time": self.next_time,
            "rested": self._rested,
        }

    def restore(self, state: dict[str, Any]) -> None:
        """Inverse of :meth:`snapshot`."""
        self.enabled, self._mode = bool(state["enabled"]), str(state["mode"])
        self._power, self._speed = (state["power"][0], state["power"][1]), (state["speed"][0], state["speed"][1])
        self._goal, self._cmd = dict(state["goal"]), (state["cmd"][0], state["cmd"][1])
        self._cmd_time, self._vel = float(state["cmd_time"]), (state["vel"][0], state["vel"][1])
        self._wheel_targets = (state["wheel_targets"][0], state["wheel_targets"][1])
        self._integral = [float(v) for v in state["integral"]]
        self._encoder_zero = (float(state["encoder_zero"][0]), float(state["encoder_zero"][1]))
        self._last = (float(state["last"][0]), float(state["last"][1]))
        t, x, y, theta, linear, angular = (float(v) for v in state["odom"])
        self._odom = (t, x, y, theta, linear, angular)
        self.next_time = float(state["next_time"])
        self.world.reschedule()  # next_time may have moved earlier
        self._rested = bool(state.get("rested", True))

    # -- internals -----------------------------------------------------------------------------------------

    def _start(self, mode: str) -> None:
        """Switch to a closed-loop mode: the speed ramp starts from the wheels' measured speeds."""
        if self._mode in ("idle", "power"):
            self._integral = [0.0, 0.0]
            self._wheel_targets = self._measured_wheel_speeds()
        self._mode = mode

    def _settled(self, data: mujoco.MjData) -> bool:
        """Whether a free robot rests on its wheels: vertical, roll and pitch speeds below 5 mm/s, 0.05 rad/s."""
        if self._free < 0:
            return True
        v = data.qvel[self._free : self._free + 6]
        return bool(abs(v[2]) < 0.005 and abs(v[3]) < 0.05 and abs(v[4]) < 0.05)

    def _measured_wheel_speeds(self) -> tuple[float, float]:
        model, data = self.world.model, self.world.data
        _, _, left, right = self._lookup(model)
        return (float(data.qvel[left]) * self.radius, float(data.qvel[right]) * self.radius)

    def _measured_velocity(self) -> tuple[float, float]:
        left, right = self._measured_wheel_speeds()
        return ((left + right) / 2, (right - left) / self.separation)

    def _targets(self, data: mujoco.MjData) -> tuple[float, float]:
        """Wheel surface speed targets (m/s) for the current mode."""
        if self._mode == "speed":
            return self._speed
        if self._mode == "stop":
            return (0.0, 0.0)
        if self._mode in ("distance", "rotate"):
            left, right = self.encoders()
            if not self._goal["started"]:
                if not self._rested:
                    # a distance or turn counts from when the robot stands on its wheels: one given while it is
                    # still settling (a scene's command at t = 0) waits for that, then runs as it would later
                    self._goal["still"] = self._goal.get("still", 0.0) + 1.0 if self._settled(data) else 0.0
                    if self._goal["still"] < SETTLED_TICKS:
                        return (0.0, 0.0)
                    self._rested = True
                self._goal["started"] = 1.0
                self._goal["start"] = (left + right) / 2 if self._mode == "distance" else (right - left) / 2
            if self._mode == "distance":
                remaining = self._goal["distance"] - ((left + right) / 2 - self._goal["start"])
                tolerance = 0.0005
            else:
                remaining = self._goal["arc"] - ((right - left) / 2 - self._goal["start"])
                tolerance = 0.0002
            speed = _approach(remaining, self._goal["speed"], self.limits.max_linear_accel)
            assert self._ids is not None
            still = max(abs(data.qvel[self._ids[2]]), abs(data.qvel[self._ids[3]])) * self.radius < 0.005
            if abs(remaining) < tolerance and still:
                self._mode = "stop"
                return (0.0, 0.0)
            return (speed, speed) if self._mode == "distance" else (-speed, speed)
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
        """Cruising wheel surface speed (m/s) for a power level: that fraction of the robot's top speed."""
        return abs(_clip(power)) * min(self.limits.max_linear, self.max_wheel_speed * self.radius)

    def _lookup(self, model: mujoco.MjModel) -> tuple[int, int, int, int]:
        if self._ids is None or self._bound is not model:
            rebuilt = self._bound is not None  # a new model: the world restarted at time 0 from the initial poses
            left, right = self._joint_names
            self._ids = (
                model.actuator(self.wheels.left_motor).id,
                model.actuator(self.wheels.right_motor).id,
                int(model.joint(left).dofadr[0]),
                int(model.joint(right).dofadr[0]),
                int(model.joint(left).qposadr[0]),
                int(model.joint(right).qposadr[0]),
            )
            self._bound = model
            self._timestep = float(model.opt.timestep)
            self._design = self._speed_loop(model)
            fixed_gain, fixed_ki = self._fixed_gains
            self.gain = self._design["gain"] if fixed_gain is None else fixed_gain
            self.ki = self._design["integral_gain"] if fixed_ki is None else fixed_ki
            if rebuilt:  # so do the encoders and odometry (the command in progress carries on)
                self._encoder_zero = (float(model.qpos0[self._ids[4]]), float(model.qpos0[self._ids[5]]))
                self._last, self._odom = (0.0, 0.0), (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        ids = self._ids
        return ids[0], ids[1], ids[2], ids[3]

    def _speed_loop(self, model: mujoco.MjModel) -> dict[str, float]:
        """Gains of the wheel-speed loop from the motor and the inertia each wheel drives.

        The plant per wheel is ``J dw/dt = stall (u - w / w0)``: first order with the time constant
        ``T = J w0 / stall``; held for a control period ``h`` it is ``w[k+1] = a w[k] + (1 - a) w0 u[k]`` with
        ``a = exp(-h / T)``. With the feed-forward ``u = w* / w0`` plus PI, the error obeys
        ``z^2 - (1 + a - g Kp - g Ki h) z + (a - g Kp)`` (``g = (1 - a) w0``); both poles go to
        ``p = POLE`` (0.8) per period (a critically damped loop with a time constant of 4.5 periods: slow
        enough that the chassis rocking, which the encoders see, does not excite it), or, where the motor alone
        is faster than that, ``Kp = 0`` and the integral puts the slower pole at ``p``.
        """
        # always at the model's initial pose: the gains must not depend on when the first tick happens (a run
        # resumed from a checkpoint or a saved current state designs the same loop, so it replays bit for bit)
        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)
        full = np.zeros((model.nv, model.nv))
        mujoco.mj_fullM(model, data, full)
        dof = self._ids[2] if self._ids is not None else 0
        inertia = float(full[dof, dof])  # the wheel, its armature
        body = model.body(self._base).id
        jnt = int(model.body_jntadr[body])
        self._free = -1
        if jnt >= 0 and model.jnt_type[jnt] == mujoco.mjtJoint.mjJNT_FREE:
            base = self._free = int(model.jnt_dofadr[jnt])
            mass, yaw = float(full[base, base]), float(full[base + 5, base + 5])
            r, s = self.wheels.radius, self.wheels.track
            # a wheel's share of the robot: half its mass going straight, its yaw inertia turning in place
            inertia += max(mass * r * r / 2, 2 * yaw * r * r / (s * s))
        motor, h, pole = self.wheels.motor, self.period, POLE
        w0 = motor.no_load_speed
        tau = inertia * w0 / motor.stall_torque
        a = math.exp(-h / tau)
        g = (1 - a) * w0
        if a >= pole * pole:
            kp, ki = (a - pole * pole) / g, (1 - pole) ** 2 / (g * h)
        else:
            kp, ki = 0.0, (1 - pole) * (1 - a / pole) / (g * h)
        return {"inertia": inertia, "time_constant": tau, "gain": kp, "integral_gain": ki, "pole": pole}

    def _raw_encoders(self, model: mujoco.MjModel, data: mujoco.MjData) -> tuple[float, float]:
        """Wheel joint angles (rad): left, right."""
        self._lookup(model)
        assert self._ids is not None
        return data.qpos.item(self._ids[4]), data.qpos.item(self._ids[5])

    def _time(self) -> float:
        return float(self.world.data.time)

    def _require_enabled(self) -> None:
        if not self.enabled:
            raise EntityError(f"the drive of {self.name!r} is disabled; call enable(True) first")


def _finite(what: str, positive: bool = True, **values: float | None) -> None:
    """Raise :class:`EntityError` for a value that is not a finite number (or not positive, when asked)."""
    for key, value in values.items():
        if value is None:
            continue
        if isinstance(value, bool) or not isinstance(value, int | float | np.floating | np.integer):
            raise EntityError(f"{what}: {key} must be a number, got {value!r}")
        if not math.isfinite(value) or (positive and value <= 0):
            kind = "a positive finite number" if positive else "a finite number"
            raise EntityError(f"{what}: {key} must be {kind}, got {value!r}")


def _limit(value: float, low: float, high: float) -> float:
    """Scalar clip (numpy's costs microseconds per call on a Python float)."""
    return low if value < low else high if value > high else value


def _clip(value: float) -> float:
    return float(min(1.0, max(-1.0, value)))


def _approach(remaining: float, top: float, accel: float, gain: float = 4.0) -> float:
    """Speed (m/s) towards a goal ``remaining`` metres away.

    Capped at ``top``, slow enough to stop at half the acceleration limit ``accel`` (m/s^2), and proportional
    (``gain``, 1/s) in the last centimetres.
    """
    distance = abs(remaining)
    speed = min(top, math.sqrt(accel * distance), gain * distance)
    return math.copysign(speed, remaining)
