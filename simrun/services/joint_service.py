"""JointService: position and velocity targets, trajectories and state by joint name, over a model's actuators.

Bound to an entity (an :class:`~simrun.robots.mjcf_robot.MjcfRobot`, a :class:`~simrun.robots.urdf_robot.UrdfRobot` with
``actuators = true``, any entity whose model has actuators), it commands the entity's own actuators that
drive one hinge or slide joint each (``NAME/joint``); joints are named without the entity prefix. It runs
as a world controller at ``rate`` Hz (controls hold between ticks).

How a target becomes a control depends on the actuator (a position, velocity or integrated-velocity servo, or
a force with or without a filter; read from the compiled model, never from names): the control laws, and the
inertia the force loops design for (issue 29's ``S``, issue 37's contacts), are those of
:mod:`simrun.services.joint_loops`
(vectorised over the driven joints, issue 41). Muscles, user-defined gains or biases, integrator dynamics
without a position bias and actuators on tendons, sites or bodies are not commanded
(:meth:`JointService.joints` leaves their joints out).

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
class too: :class:`~simrun.robots.arm_service.ArmService` is a JointService at 50 Hz with the cosine profile and no
integral (their servos are designed critically damped, their gravity compensated), behind the arm's own
names (``set_joint_targets``, ``move_to(joint_positions, duration)``, ``joint_states``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from itertools import compress
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np

from simrun.errors import EntityError
from simrun.services.joint_bind import bind, wheel_joints
from simrun.services.joint_drives import Drive, check_position, check_speed
from simrun.services.joint_loops import Layout, Scratch
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
#: Most layouts (sets of driven joints) a service keeps; more are built again when next driven.
_LAYOUTS = 64


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
        self._scratch: Scratch | None = None  # feed-forward forces are computed here, from the state alone
        self._mass = np.zeros((0, 0))  # MuJoCo's mass matrix at the model's initial pose (nv x nv)
        self._layouts: dict[tuple[Any, ...], Layout] = {}  # (driven joints, w, h, integral) -> their laws' arrays
        self._holdable: list[tuple[str, int]] = []  # (joint, qpos) of every commandable joint but the wheels
        self._wheels: set[str] = set()  # the entity's wheel joints (the DriveService's), never held
        self._tree = np.zeros(0, dtype=np.intp)  # the dofs of the entity's bodies (its root's included)
        self._movers = np.zeros(0, dtype=bool)  # per body: whether it moves one of those dofs (its chain has one)
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
        """Advance the trajectory and the velocity targets, then set every driven actuator's control.

        The laws are :class:`~simrun.services.joint_loops.Layout`'s, over arrays of the driven joints: the held
        ones (in the order they were first held), then the commanded ones (in the order first commanded).
        """
        self._lookup(model)
        plan = self._plan
        if plan is not None:
            self._follow(float(data.time))
            plan = self._plan
        held, targets = self._held, self._targets
        if self.hold_mode == "all":
            for joint, qpos in self._holdable:
                if joint not in targets and joint not in held:
                    held[joint] = float(data.qpos[qpos])
        names = (*held, *targets)
        if not names:
            return
        layout = self._layout(model, names)
        names = layout.names
        before = [*held.values(), *(t[0] for t in targets.values())]
        speeds = [0.0] * len(held) + [t[1] for t in targets.values()]
        after = before
        if any(speeds):
            h, moved = self.period, False
            for joint, target in targets.items():
                position, velocity = target
                if velocity and (plan is None or joint not in plan.joints):
                    drive = self._drives[joint]
                    position = target[0] = min(drive.highest, max(drive.lowest, position + velocity * h))
                    if position in (drive.lowest, drive.highest):  # at the end of its range: it stops there
                        target[1] = 0.0
                    moved = True
            if moved:
                after = [*held.values(), *(t[0] for t in targets.values())]
                speeds_after = [0.0] * len(held) + [t[1] for t in targets.values()]
            else:
                speeds_after = speeds
        else:
            speeds_after = speeds
        take = layout.take  # None: the held and the commanded joints are all different (always, but after a restore)
        old = (np.array(before), np.array(speeds)) if take is None else (np.array(before)[take], np.array(speeds)[take])
        if after is before:
            new = old
        else:
            new = (np.array(after), np.array(speeds_after))
            new = new if take is None else (new[0][take], new[1][take])
        integral = self._integral
        sums = np.array([integral.get(j, 0.0) for j in names]) if self.integral else np.zeros(len(names))
        scratch = self._scratch
        if scratch is None or scratch.model is not model:
            scratch = self._scratch = Scratch(model)
        ctrl, keep, sums = layout.controls(data, scratch, self._tree, self._movers, old, new, sums)
        data.ctrl[layout.actuator] = ctrl
        if self.integral:  # in the joints' order: a new one is added to the snapshot's dict as the loop added it
            integral.update(compress(zip(names, sums.tolist(), strict=True), keep.tolist()))

    def _layout(self, model: mujoco.MjModel, names: tuple[str, ...]) -> Layout:
        """The :class:`~simrun.services.joint_loops.Layout` of the driven joints ``names`` (held, then commanded).

        Built once per set (and order) of joints, bandwidth, period and ``integral``; a joint both held and
        commanded is driven once, at its held place, to its commanded target.
        """
        key = (names, self.bandwidth, self.period, self.integral)
        found = self._layouts.get(key)
        if found is None:
            if len(self._layouts) >= _LAYOUTS:
                self._layouts.clear()
            places: dict[str, int] = {}
            for k, joint in enumerate(names):  # {**held, **targets}: the first place, the last value
                places[joint] = places.get(joint, k)
            unique = tuple(places)
            last = {joint: k for k, joint in enumerate(names)}
            found = Layout(model, self._drives, unique, self._mass, self.bandwidth, self.period, self.integral)
            if len(unique) < len(names):
                found.take = np.array([last[j] for j in unique], dtype=np.intp)
            self._layouts[key] = found
        return found

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
        """Position targets (rad or m), each within its joint's range (a hair outside: clamped to it).

        See :func:`~.joint_drives.check_position`.
        """
        values = self._values(joints, positions, what)
        return [check_position(j, self._drives[j], value, what) for j, value in zip(joints, values, strict=True)]

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
        found = bind(model, self.name)
        self._joints, self._drives, self._bound = found.joints, found.drives, model
        self._mass, self._layouts, self._tree, self._movers = found.mass, {}, found.tree, found.movers
        self._targets = {k: v for k, v in self._targets.items() if k in found.drives}
        self._held = {}  # a new model starts at its initial state: held again from there at the next tick
        self._wheels = wheel_joints(self.world.entity(self.name))
        self._holdable = [(j, d.qpos) for j, d in found.drives.items() if j not in self._wheels]
