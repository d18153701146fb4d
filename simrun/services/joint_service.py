"""JointService: position and velocity targets, trajectories and state by joint name, over a model's actuators.

Bound to an entity (an :class:`~simrun.robots.mjcf_robot.MjcfRobot`, a :class:`~simrun.robots.urdf_robot.UrdfRobot` with
``actuators = true``, any entity whose model has actuators), it commands the entity's own actuators that
drive one hinge or slide joint each (``NAME/joint``); joints are named without the entity prefix. It runs
as a world controller at ``rate`` Hz (controls hold between ticks). How a target becomes a control depends on
the actuator (read from the compiled model, never from names):

* **position servo** (``biastype affine`` with ``biasprm[1] < 0``: a spring towards a point the control
  sets; ``<position>`` is ``gain = kp``, ``biasprm = [0, -kp, -kv]``): ``ctrl = -(b0 + b1 gear q*) / gain``,
  which is ``gear q*`` for ``<position>`` (the servo's own loop; a velocity target moves the position target
  at that speed).
* **velocity servo** (``biasprm[1] = 0``, ``biasprm[2] = -kv``): ``ctrl = gear * (v* + w (q* - q))``, a
  position loop of bandwidth ``w`` (rad/s) around the servo (``v*``: the velocity target, 0 when holding),
  damped by the servo itself: joint torque ``K (ctrl / gear - v)``, ``K = gear^2 kv``, so the loop is
  ``m s^2 + (K + b) s + K w`` (``m`` the joint's diagonal of the mass matrix, ``b`` its damping), at least
  critically damped where ``(K + b)^2 >= 4 m K w``. A servo too weak for that rings: dm_control's jumping
  ball's camera slide (``kv`` 1 on 1 kg, damping ratio 0.14) still swung 40 % of its step 5 s after the
  walker's kick. Such a servo is used as a torque source: ``ctrl = gear (v + m (w^2 e + 2 w (v* - v)) / K)``
  puts both poles at ``-w``; the ``v`` in it cancels the servo's damping explicitly, stable because
  ``K h / m < 4 w h`` there (``h`` how long a control holds, the control period or the timestep; ``K h / m``
  is required below 1).
* **integrated velocity servo** (``intvelocity``: integrator dynamics, position bias): the activation is
  the servo's position target; ``ctrl = gear v* + w (gear q* - act)`` steers it to ``gear q*``.
* **force** (a motor, or any other fixed-gain actuator with affine or no bias, with or without a filter):
  a PID loop in joint space with
  feed-forward of MuJoCo's bias, spring and gravity-compensation forces, ``tau = qfrc_bias - qfrc_spring -
  qfrc_gravcomp + S a + B a / (3 w)``, ``a = 3 w^2 e + 3 w (v* - v) + w^3 integral(e)`` per joint,
  ``e = q* - q``, ``w`` the bandwidth: the three closed-loop poles sit at ``-w`` (critically damped,
  ``(s + w)^3``). ``S`` is the inertia the commanded force joints see together, every other degree of
  freedom free: the Schur complement of MuJoCo's mass matrix (armature included) at the model's initial
  pose over the rest (a free root, passive joints, servo-driven joints). Each joint's own diagonal of the
  mass matrix (its inertia with everything else held), as before issue 29's walker roots, made the force
  loops of a floating body fight each other through it: on the CMU humanoids of dm_control with their free
  root the spine joints chattered at half the control rate between the actuators' full forces (the
  smallest inertia a spine joint sees, everything else free, is 1/66 of its diagonal); with ``S`` they
  settle (``bench/mjcf_robots.py``: 58 of 62 models reach their targets, against 56 with the diagonal and
  no regression). ``S`` is computed once per set of commanded joints. The joints' damping ``B`` (diagonal)
  is not cancelled: MuJoCo integrates it implicitly, a cancellation held over a control period is explicit
  and diverges where ``b * period / m > 2`` (light wrists and fingers); ``B / (3 w)`` is added to the
  inertia instead, so a joint whose damping dwarfs its inertia still closes its loop in about ``1 / w``
  (poles ``w (-1 +- 1.29 i) / 4`` in that limit). The integral removes what the feed-forward misses
  (friction loss, contacts) and stops growing while the control is clipped in the error's direction (no
  wind-up). The actuator's own bias is subtracted: ``ctrl = (tau / gear - b0 - b1 gear q - b2 gear v) / gain``.
  **Contacts** (issue 37): a joint whose limb touches something carries more than ``S``: a ball rolling on
  the ground carries the body along (31 times its own inertia on dm_control's jumping ball), and the loop,
  stable only while the inertia stays below 9 times its design, rang ever wider. Each tick the contacts of
  the current pose that touch the entity are taken as held (MuJoCo's soft constraint rows) and the inertia
  they add is added to ``S`` (capped at ``1 / (3 w h) - 1`` times ``S``, 5.6 at the defaults, so the loop
  still samples stably when the contact lets go; beyond the cap the integral is slowed by ``4.5 / k``, ``k``
  what is left; :func:`simrun.services.joint_inertia.with_contacts`). **Filtered actuators** (``dyntype filter`` or
  ``filterexact``, dm_control's dog: 50 ms): the force follows the activation, not the control, and a 4 Hz
  loop around a 50 ms lag is unstable (``tau w < 8 / 9`` is needed); the control is the one that brings the
  activation to the wanted value in one control period (``(u - d act) / (1 - d)``, ``d`` the part of the
  activation a held control leaves, from the filter's integration), clipped to the control range.

Muscles, user-defined gains or biases, integrator dynamics without a position bias and actuators on
tendons, sites or bodies are not commanded (:meth:`JointService.joints` leaves their joints out).

Controls are clipped to the actuator's ``ctrlrange``: a weak motor may not hold a pose. **Targets** are
refused, with one line naming the joint, the value and the range, outside what the joint and its actuator
allow (its ``jnt_range``, a position servo's ``ctrlrange``, an integrated-velocity servo's ``actrange``:
:mod:`simrun.services.joint_drives`); :meth:`JointService.check_command` refuses a commands file's command
the same way before the run starts.

**Holding.** With ``hold = "all"`` (the default) the service also holds every commandable joint it has not
been given a target for at the position it has at the service's first tick (after a :meth:`World.reset
<simrun.world.world.World.reset>` or a rebuild: at the new initial state), through the same loops, so a URDF
arm or a walker does not fold under gravity while only some of its joints are commanded. ``hold =
"commanded"`` leaves such joints to the model (their controls are whatever is in ``data.ctrl``, MuJoCo's 0 at
reset: a motor limp, a position servo pulled to 0), for code that writes those controls itself. Wheel joints
(a built-in drive's ``left_wheel``/``right_wheel``, the ``wheels`` an imported robot names) are never held:
they belong to the ``DriveService``.

Trajectories are time-stamped waypoints (seconds from the call, each at least one timestep after the one before,
at most :data:`~simrun.services.joint_trajectory.MAX_POINTS`; :mod:`simrun.services.joint_trajectory`), followed
by linear interpolation in joint
space with the segment's slope as velocity feed-forward (``profile = "cosine"``: the blend ``(1 - cos(pi u))
/ 2`` of each segment, at rest at every waypoint, with its slope as feed-forward); the joints not named hold
their targets. ``integral = False`` leaves the error integrals out of every loop.

The built-in arms (:class:`~simrun.robots.arm.ArticulatedArm`, ``KukaLBR3``, ``LynxL6``) are served by this
class too: :class:`~simrun.robots.arm.ArmService` is a JointService at 50 Hz with the cosine profile and no
integral (their servos are designed critically damped, their gravity compensated), behind the arm's own
names (``set_joint_targets``, ``move_to(joint_positions, duration)``, ``joint_states``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np

from simrun.errors import EntityError
from simrun.services.joint_drives import (
    Drive,
    check_position,
    check_speed,
    drive_of,
    filter_decay,
    servo_integral_rate,
)
from simrun.services.joint_inertia import free_inertia, with_contacts
from simrun.services.joint_trajectory import Trajectory, check_waypoints

if TYPE_CHECKING:  # the world imports the registry, which names this module: no import back
    from simrun.world.world import World

#: Default bandwidth of the position loops, rad/s (4 Hz). Issue 37: at 2 Hz the force loops of dm_control's and
#: gymnasium's walkers missed their targets under gravity (bench/mjcf_robots.py's worlds, 2 s; docs/robots.md).
BANDWIDTH = 8 * math.pi
#: What the service holds: every commandable joint (``all``) or only those given targets (``commanded``).
HOLD_MODES = ("all", "commanded")
#: How a trajectory moves between two waypoints: a straight line at constant speed (``linear``) or
#: ``a + (b - a) (1 - cos(pi u)) / 2`` (``cosine``: at rest at each waypoint; ``u`` the segment's time fraction).
PROFILES = ("linear", "cosine")
_ONE_DOF = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))


@dataclass(frozen=True, slots=True)
class JointState:
    """Joint positions and velocities of an entity.

    Attributes:
        time: Simulation time, s.
        names: Joint names without the entity prefix, in model order (hinge and slide joints).
        positions: rad (hinge) or m (slide), one per name.
        velocities: rad/s or m/s, one per name.
        targets: Current position target per name (``nan`` for joints with no actuator and for those the
            service holds without a command, ``hold = "all"``).
    """

    time: float
    names: tuple[str, ...]
    positions: tuple[float, ...]
    velocities: tuple[float, ...]
    targets: tuple[float, ...]


class JointService:
    """Joint targets and trajectories of one entity, by joint name.

    Args:
        world: The world.
        entity: Full name of the entity.
        rate: Control rate, Hz.
        bandwidth: Position-loop bandwidth ``w`` of velocity and force actuators, rad/s.
        hold: ``all``: joints without a target are held where they are (see the module); ``commanded``:
            only joints given a target are driven.
        profile: How trajectories and ``move_to`` move between waypoints (:data:`PROFILES`): ``linear``
            (constant speed on each segment) or ``cosine`` (at rest at every waypoint: the built-in arms').
        integral: Whether the loops integrate the position error (a steady load's error removed; see the
            module). ``False``: a position servo gets the target itself (``ctrl = gear q*`` for
            ``<position>``), so its own designed step response is kept (the built-in arms, whose gravity is
            compensated and whose servos are critically damped for their largest inertia).

    Raises:
        EntityError: No such entity, a rate or bandwidth that is not a positive number, an unknown ``hold``
            or ``profile``, an ``integral`` that is not a boolean.
    """

    def __init__(
        self,
        world: World,
        entity: str,
        rate: float = 500.0,
        bandwidth: float = BANDWIDTH,
        hold: str = "all",
        profile: str = "linear",
        integral: bool = True,
    ) -> None:
        world.entity(entity)
        if hold not in HOLD_MODES:
            raise EntityError(f"JointService of {entity!r}: hold must be one of {', '.join(HOLD_MODES)}, got {hold!r}")
        if profile not in PROFILES:
            raise EntityError(
                f"JointService of {entity!r}: profile must be one of {', '.join(PROFILES)}, got {profile!r}"
            )
        if not isinstance(integral, bool):
            raise EntityError(f"JointService of {entity!r}: integral must be true or false, got {integral!r}")
        self.profile, self.integral = profile, integral
        for key, value in (("rate", rate), ("bandwidth", bandwidth)):
            if (
                isinstance(value, bool)
                or not isinstance(value, int | float)
                or not (math.isfinite(value) and value > 0)
            ):
                raise EntityError(f"JointService of {entity!r}: {key} must be a positive number, got {value!r}")
        self.world, self.name, self.bandwidth = world, entity, float(bandwidth)
        self.period = 1.0 / rate
        self.next_time = world.time
        self._bound: mujoco.MjModel | None = None
        self._drives: dict[str, Drive] = {}
        self._joints: list[tuple[str, int, int]] = []  # (name, qpos, dof) of every hinge/slide joint
        self._targets: dict[str, list[float]] = {}  # joint -> [position target, velocity target]
        self.hold_mode = hold
        self._held: dict[str, float] = {}  # joint -> where it is held without a command (hold = "all")
        self._plan: Trajectory | None = None  # the trajectory being followed
        self._integral: dict[str, float] = {}  # joint -> integral of the position error (force joints), rad s
        self._scratch: _Scratch | None = None  # feed-forward forces are computed here, from the state alone
        self._mass = np.zeros((0, 0))  # MuJoCo's mass matrix at the model's initial pose (nv x nv)
        self._inertia: dict[tuple[str, ...], np.ndarray[Any, np.dtype[np.float64]]] = {}  # force joints -> S
        self._wheels: set[str] = set()  # the entity's wheel joints (the DriveService's), never held
        self._tree = np.zeros(0, dtype=np.intp)  # the dofs of the entity's bodies (its root's included)
        world.controllers.append(self)

    # -- commands ------------------------------------------------------------------------------------------

    def set_positions(self, joints: list[str] | tuple[str, ...], positions: list[float] | tuple[float, ...]) -> None:
        """Hold ``joints`` at ``positions`` (rad or m); cancels a trajectory on those joints.

        Raises:
            EntityError: An unknown joint, or a position outside what the joint and its actuator allow
                (:mod:`simrun.services.joint_drives`), naming the joint, the value and the range.
        """
        values = self._positions(joints, positions, "set_positions")
        self._cancel(joints)
        for joint, value in zip(joints, values, strict=True):
            self._targets[joint] = [value, 0.0]
            self._held.pop(joint, None)

    def set_velocities(self, joints: list[str] | tuple[str, ...], velocities: list[float] | tuple[float, ...]) -> None:
        """Run ``joints`` at ``velocities`` (rad/s or m/s): their position targets move at that speed.

        A target that reaches the end of its joint's range stops there (its velocity becomes 0).

        Raises:
            EntityError: An unknown joint, or a velocity beyond a velocity servo's ``ctrlrange / gear`` or
                :data:`~simrun.services.joint_drives.MAX_SPEED`.
        """
        values = self._speeds(joints, velocities, "set_velocities")
        self._cancel(joints)
        for joint, value in zip(joints, values, strict=True):
            self._targets[joint] = [self._target_now(joint), value]
            self._held.pop(joint, None)

    def hold(self) -> None:
        """Stop every motion: each commanded joint holds where it is now."""
        self._plan = None
        data = self.world.data
        for joint in self._targets:
            self._targets[joint] = [float(data.qpos[self._drives[joint].qpos]), 0.0]

    def trajectory(
        self,
        joints: list[str] | tuple[str, ...],
        times: list[float] | tuple[float, ...],
        positions: list[float] | tuple[float, ...] | list[list[float]],
    ) -> None:
        """Follow waypoints: at ``times[k]`` seconds from now, ``joints`` at row ``k`` of ``positions``.

        ``positions`` is ``len(times)`` rows of ``len(joints)`` values, nested or flat (row after row; a
        commands file takes flat arrays). From now to the first time the joints move from their current
        targets.

        Raises:
            EntityError: An unknown joint; more than :data:`~simrun.services.joint_trajectory.MAX_POINTS`
                points; times that are not increasing by at least one model timestep (the first: from now);
                a position outside what its joint and actuator allow (:mod:`simrun.services.joint_trajectory`).
        """
        self._follow_points(joints, times, positions, "trajectory")

    def _follow_points(self, joints: Any, times: Any, positions: Any, what: str) -> None:
        stamps, points = self._waypoints(joints, times, positions, what)
        self._cancel(joints)
        start = [self._target_now(j) for j in joints]
        self._plan = Trajectory(float(self.world.data.time), [0.0, *stamps], list(joints), [start, *points])
        for joint, value in zip(joints, start, strict=True):
            self._targets[joint] = [value, 0.0]
            self._held.pop(joint, None)

    def move_to(
        self, joints: list[str] | tuple[str, ...], positions: list[float] | tuple[float, ...], duration: float
    ) -> None:
        """Move ``joints`` to ``positions`` in a straight line over ``duration`` seconds (a one-waypoint trajectory).

        Raises:
            EntityError: As :meth:`trajectory` (``duration`` at least one timestep).
        """
        self._follow_points(joints, [duration], positions, "move_to")

    def check_command(self, call: str, args: tuple[Any, ...]) -> None:
        """Refuse a command before a run starts: what ``call(*args)`` would refuse, nothing applied.

        :func:`simrun.run.commands.check_commands` calls it for every command of a commands file, so a bad
        target or trajectory is one error line with its file and line before the first step, not mid-run.

        Raises:
            EntityError: What the command itself would raise.
        """
        if call == "set_positions":
            joints, values = args
            self._positions(joints, values, call)
        elif call == "set_velocities":
            joints, values = args
            self._speeds(joints, values, call)
        elif call == "trajectory":
            joints, times, positions = args
            self._waypoints(joints, times, positions, call)
        elif call == "move_to":
            joints, positions, duration = args
            self._waypoints(joints, [duration], positions, call)

    # -- state ---------------------------------------------------------------------------------------------

    @property
    def busy(self) -> bool:
        """Whether a trajectory is still running."""
        return self._plan is not None

    def joints(self) -> tuple[str, ...]:
        """The commandable joints (those with an actuator of their own), in model order."""
        self._lookup(self.world.model)
        return tuple(self._drives)

    def kinds(self) -> dict[str, str]:
        """How each commandable joint is driven: ``position``, ``velocity`` or ``force`` (see the module)."""
        self._lookup(self.world.model)
        return {name: drive.kind for name, drive in self._drives.items()}

    def state(self) -> JointState:
        """Positions, velocities and targets of every hinge and slide joint of the entity."""
        model, data = self.world.model, self.world.data
        self._lookup(model)
        names = tuple(n for n, _, _ in self._joints)
        return JointState(
            float(data.time),
            names,
            tuple(float(data.qpos[q]) for _, q, _ in self._joints),
            tuple(float(data.qvel[d]) for _, _, d in self._joints),
            tuple(self._targets[n][0] if n in self._targets else math.nan for n in names),
        )

    # -- controller hooks ----------------------------------------------------------------------------------

    def tick(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Advance the trajectory and the velocity targets, then set every commanded actuator's control."""
        self._lookup(model)
        if self._plan is not None:
            self._follow(float(data.time))
        if self.hold_mode == "all":
            for joint, drive in self._drives.items():
                if joint not in self._targets and joint not in self._held and joint not in self._wheels:
                    self._held[joint] = float(data.qpos[drive.qpos])
        goals = {**{j: [q, 0.0] for j, q in self._held.items()}, **self._targets}  # held ones: copies
        w, h = self.bandwidth, self.period
        force = [j for j in goals if self._drives[j].kind == "force"]
        wanted = self._computed_torque(model, data, force, goals) if force else {}
        for joint, target in goals.items():
            drive = self._drives[joint]
            position, velocity = target
            if velocity and (self._plan is None or joint not in self._plan.joints):
                position = target[0] = min(drive.highest, max(drive.lowest, position + velocity * h))
                if position in (drive.lowest, drive.highest):  # at the end of its range: it stops there
                    velocity = target[1] = 0.0
            q, v = float(data.qpos[drive.qpos]), float(data.qvel[drive.dof])
            error = position - q
            integral = self._integral.get(joint, 0.0) + error * h if self.integral else 0.0  # rad s (m s)
            if (
                drive.kind == "position"
            ):  # force = g u + b0 + b1 gear q (+ b2 speed): at rest where g u = -b0 - b1 gear q
                bias = model.actuator_biasprm[drive.actuator]
                shift = servo_integral_rate(model, drive, w) * integral if self.integral else 0.0
                if bias[0] == 0 and bias[1] == -drive.gain:  # <position>: ctrl = gear q*, exactly
                    ctrl = drive.gear * (position + shift)
                else:
                    ctrl = -(bias[0] + bias[1] * drive.gear * (position + shift)) / drive.gain
            elif drive.kind == "velocity":
                servo = drive.gear * drive.gear * drive.gain  # joint torque per rad/s of speed error
                hold = max(h, float(model.opt.timestep))  # how long a control stays
                weak = (servo + drive.damping) ** 2 < 4.0 * drive.mass * servo * w and servo * hold < drive.mass
                if weak:  # its own damping cannot damp the loop: command the torque (see the module)
                    torque = drive.mass * (w * w * (position - q) + 2.0 * w * (velocity - v))
                    ctrl = drive.gear * (v + torque / servo)
                else:
                    rate = min(w * w / 3.0, 0.5 * (servo + drive.damping) * w / drive.mass)
                    ctrl = drive.gear * (velocity + w * error + rate * integral)
                    self._keep_integral(joint, drive, ctrl, error * drive.gear, integral)
            elif drive.kind == "intvelocity":  # the servo's target is the activation: steer it to gear * q*
                act = float(data.act[model.actuator_actadr[drive.actuator]])
                shift = servo_integral_rate(model, drive, w) * integral
                ctrl = drive.gear * velocity + w * (drive.gear * (position + shift) - act)
            else:
                tau, error, integral = wanted[joint]
                bias = model.actuator_biasprm[drive.actuator]  # force = gain ctrl + b0 + b1 length + b2 speed
                offset = float(bias[0] + bias[1] * drive.gear * q + bias[2] * drive.gear * v)
                ctrl = (tau / drive.gear - offset) / drive.gain  # the activation that gives the torque
                if drive.lag > 0:  # a filtered actuator: the control that brings the activation there in one hold
                    self._keep_integral(joint, drive, ctrl, error * drive.gear, integral)
                    act = float(data.act[model.actuator_actadr[drive.actuator]])
                    decay = filter_decay(model, drive, h)
                    data.ctrl[drive.actuator] = min(drive.high, max(drive.low, (ctrl - decay * act) / (1.0 - decay)))
                    continue
            if drive.kind != "velocity":
                self._keep_integral(joint, drive, ctrl, error * drive.gear, integral)
            data.ctrl[drive.actuator] = min(drive.high, max(drive.low, ctrl))

    def _keep_integral(self, joint: str, drive: Drive, ctrl: float, push: float, integral: float) -> None:
        """Store the new error integral unless the control is clipped in the direction it pushes (no wind-up)."""
        if self.integral and not ((ctrl > drive.high and push > 0) or (ctrl < drive.low and push < 0)):
            self._integral[joint] = integral

    def reset(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """After ``World.reset``: no targets, no trajectory (the actuators' controls are MuJoCo's reset ones).

        With ``hold = "all"`` the joints are held again from where the reset put them, at the next tick.
        """
        self._targets, self._plan, self._integral, self._held = {}, None, {}, {}

    def snapshot(self) -> dict[str, Any]:
        """Targets, trajectory and clock, JSON-ready (for checkpoints)."""
        plan = None if self._plan is None else self._plan.state()
        return {
            "targets": {k: list(v) for k, v in self._targets.items()},
            "plan": plan,
            "integral": dict(self._integral),
            "held": dict(self._held),
            "next_time": self.next_time,
        }

    def restore(self, state: dict[str, Any]) -> None:
        """Inverse of :meth:`snapshot` (bound to the world's model first: the next tick must not hold again)."""
        self._lookup(self.world.model)
        self._targets = {str(k): [float(v[0]), float(v[1])] for k, v in state["targets"].items()}
        self._plan = None if state["plan"] is None else Trajectory.from_state(state["plan"])
        self._integral = {str(k): float(v) for k, v in state.get("integral", {}).items()}
        self._held = {str(k): float(v) for k, v in state.get("held", {}).items()}
        self.next_time = float(state["next_time"])
        self.world.reschedule()

    # -- internals -----------------------------------------------------------------------------------------

    def _computed_torque(
        self, model: mujoco.MjModel, data: mujoco.MjData, joints: list[str], goals: dict[str, list[float]]
    ) -> dict[str, tuple[float, float, float]]:
        """Joint torque, position error and the error's new integral of each force-driven joint (see the module).

        ``goals``: joint to [position target, velocity target], the commanded and the held joints.
        """
        w, h = self.bandwidth, self.period
        dofs = [self._drives[j].dof for j in joints]
        feed = self._feed_forward(model, data)[dofs]
        free = self._joint_inertia(tuple(joints), dofs)
        work = None if self._scratch is None else self._scratch.data
        inertia, slower = with_contacts(model, work, self._tree, dofs, free, self.bandwidth, self.period)
        rates, damped, errors, integrals = [], [], [], []
        for joint in joints:
            drive, (position, velocity) = self._drives[joint], goals[joint]
            error = position - float(data.qpos[drive.qpos])
            integral = self._integral.get(joint, 0.0) + error * h if self.integral else 0.0
            rate = (
                3.0 * w * w * error
                + 3.0 * w * (velocity - float(data.qvel[drive.dof]))
                + slower * (w * w * w * integral)
            )
            rates.append(rate)
            damped.append(drive.damping / (3.0 * w) * rate)
            errors.append(error)
            integrals.append(integral)
        torque = inertia @ np.asarray(rates) + np.asarray(damped) + feed
        return {j: (float(torque[k]), errors[k], integrals[k]) for k, j in enumerate(joints)}

    def _joint_inertia(self, joints: tuple[str, ...], dofs: list[int]) -> np.ndarray[Any, np.dtype[np.float64]]:
        """The inertia matrix the force joints ``joints`` (dofs ``dofs``) see with every other dof free."""
        found = self._inertia.get(joints)
        if found is None:
            found = self._inertia[joints] = free_inertia(self._mass, dofs)
        return found

    def _follow(self, now: float) -> None:
        plan = self._plan
        assert plan is not None
        targets = plan.targets(now, self.profile)
        if targets is None:  # at its last point: held there
            for joint, value in zip(plan.joints, plan.rows[-1], strict=True):
                self._targets[joint] = [float(value), 0.0]
            self._plan = None
            return
        for joint, (position, velocity) in zip(plan.joints, targets, strict=True):
            self._targets[joint] = [position, velocity]

    def _feed_forward(self, model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray[Any, np.dtype[np.float64]]:
        """``qfrc_bias - qfrc_spring - qfrc_gravcomp`` (per dof) at the current ``qpos``, ``qvel``.

        Computed in a scratch ``MjData`` from the state alone: the derived fields of ``data`` between steps
        belong to the state before the last step, and a run resumed from a checkpoint has other ones, so a
        control that read them would not replay bit for bit.
        """
        scratch = self._scratch
        if scratch is None or scratch.model is not model:
            scratch = self._scratch = _Scratch(model)
        work = scratch.data
        work.qpos[:] = data.qpos
        work.qvel[:] = data.qvel
        mujoco.mj_kinematics(model, work)
        mujoco.mj_comPos(model, work)
        mujoco.mj_tendon(model, work)
        mujoco.mj_comVel(model, work)
        mujoco.mj_passive(model, work)
        mujoco.mj_rne(model, work, 0, scratch.bias)
        feed: np.ndarray[Any, np.dtype[np.float64]] = scratch.bias - work.qfrc_spring - work.qfrc_gravcomp
        return feed

    def _target_now(self, joint: str) -> float:
        """The joint's current position target, or where it is when it has none."""
        if joint in self._targets:
            return self._targets[joint][0]
        if joint in self._held:
            return self._held[joint]
        return float(self.world.data.qpos[self._drives[joint].qpos])

    def _cancel(self, joints: list[str] | tuple[str, ...]) -> None:
        """End a trajectory that moves any of ``joints`` (its other joints hold their current targets).

        Joints running at a velocity target (:meth:`set_velocities`) outside the trajectory keep running.
        """
        if self._plan is not None and set(joints) & set(self._plan.joints):
            for joint in self._plan.joints:
                if joint in self._targets:
                    self._targets[joint][1] = 0.0
            self._plan = None

    def _values(self, joints: Any, values: Any, what: str) -> list[float]:
        """One finite number per joint of ``joints`` (known, each named once)."""
        self._lookup(self.world.model)
        self._check_joints(joints)
        if isinstance(values, str) or not hasattr(values, "__len__") or len(values) != len(joints):
            raise EntityError(f"{what}: give one value per joint ({len(joints)}), got {values!r}")
        out = []
        for value in values:
            if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
                raise EntityError(f"{what}: {value!r} is not a finite number")
            out.append(float(value))
        return out

    def _positions(self, joints: Any, positions: Any, what: str) -> list[float]:
        """Position targets (rad or m), each within its joint's range (:func:`~.joint_drives.check_position`)."""
        values = self._values(joints, positions, what)
        for joint, value in zip(joints, values, strict=True):
            check_position(joint, self._drives[joint], value, what)
        return values

    def _speeds(self, joints: Any, velocities: Any, what: str) -> list[float]:
        """Velocity targets (rad/s or m/s), each within its drive's speeds (:func:`~.joint_drives.check_speed`)."""
        values = self._values(joints, velocities, what)
        for joint, value in zip(joints, values, strict=True):
            check_speed(joint, self._drives[joint], value, what)
        return values

    def _waypoints(self, joints: Any, times: Any, positions: Any, what: str) -> tuple[list[float], list[list[float]]]:
        """Checked times and rows of a trajectory (:func:`~.joint_trajectory.check_waypoints`)."""
        model = self.world.model
        self._lookup(model)
        self._check_joints(joints)
        return check_waypoints(joints, self._drives, times, positions, float(model.opt.timestep), what)

    def _check_joints(self, joints: Any) -> None:
        if isinstance(joints, str) or not isinstance(joints, list | tuple) or not joints:
            raise EntityError(f"give a list of joint names, got {joints!r}")
        for joint in joints:
            if joint not in self._drives:
                known = ", ".join(self._drives) or "none"
                raise EntityError(f"{self.name!r} has no actuated joint {joint!r} (actuated joints: {known})")
        if len(set(joints)) != len(joints):
            raise EntityError(f"a joint is named twice in {list(joints)!r}")

    def _lookup(self, model: mujoco.MjModel) -> None:
        """Find the entity's joints and actuators in ``model`` (again after a rebuild)."""
        if self._bound is model:
            return
        prefix = f"{self.name}/"
        data = mujoco.MjData(model)  # the mass matrix at the initial pose: gains independent of when asked
        mujoco.mj_forward(model, data)
        full = np.zeros((model.nv, model.nv))
        mujoco.mj_fullM(model, data, full)
        joints: list[tuple[str, int, int]] = []
        for j in range(model.njnt):
            name = model.joint(j).name
            if name.startswith(prefix) and int(model.jnt_type[j]) in _ONE_DOF:
                joints.append((name[len(prefix) :], int(model.jnt_qposadr[j]), int(model.jnt_dofadr[j])))
        by_id = {int(model.joint(prefix + n).id): (n, q, d) for n, q, d in joints}
        drives: dict[str, Drive] = {}
        for a in range(model.nu):
            joint = int(model.actuator_trnid[a, 0])
            if int(model.actuator_trntype[a]) != int(mujoco.mjtTrn.mjTRN_JOINT) or joint not in by_id:
                continue
            name, qpos, dof = by_id[joint]
            if name in drives:
                continue  # the first actuator of a joint commands it
            drive = drive_of(model, a, joint, qpos, dof, full)
            if drive is not None:
                drives[name] = drive
        self._joints, self._drives, self._bound = joints, drives, model
        self._mass, self._inertia = full, {}
        self._targets = {k: v for k, v in self._targets.items() if k in drives}
        self._held = {}  # a new model starts at its initial state: held again from there at the next tick
        self._wheels = self._wheel_joints()
        mine = [
            b for b in range(model.nbody) if model.body(b).name in (self.name,) or model.body(b).name.startswith(prefix)
        ]
        self._tree = np.flatnonzero(np.isin(model.dof_bodyid, mine)).astype(np.intp)

    def _wheel_joints(self) -> set[str]:
        """The entity's driven wheel joints, without the prefix: the ``DriveService``'s, never held.

        A built-in differential drive's ``left_wheel`` and ``right_wheel``, an imported robot's ``wheels``.
        """
        from simrun.robots.diff_drive import DifferentialDrive  # the registry names this module: import late

        entity = self.world.entity(self.name)
        if isinstance(entity, DifferentialDrive):
            return {"left_wheel", "right_wheel"}
        wheels = getattr(entity, "wheels", ())
        return {str(w) for w in wheels} if isinstance(wheels, tuple | list) else set()


class _Scratch:
    """A private ``MjData`` of one model and the bias-force buffer."""

    def __init__(self, model: mujoco.MjModel) -> None:
        self.model = model
        self.data = mujoco.MjData(model)
        self.bias = np.zeros(model.nv)
