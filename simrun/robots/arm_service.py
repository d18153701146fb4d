"""The arm service: commands for an articulated arm (joint targets now, or a smooth move over a duration).

:class:`ArmService` is a thin adapter over a :class:`~simrun.services.joint_service.JointService` of an
:class:`~simrun.robots.arm.ArticulatedArm` (the arms themselves and their servo design live in
:mod:`simrun.robots.arm`); :class:`JointStates` is what it reports.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import mujoco

from simrun.errors import EntityError
from simrun.robots.arm import ArticulatedArm, servo_design

if TYPE_CHECKING:  # the world imports the registry, which names this module: no import back
    from simrun.world.world import World

__all__ = ["ArmService", "JointStates"]


@dataclass(frozen=True, slots=True)
class JointStates:
    """Positions (rad or m) and velocities of an arm's joints, base to tip."""

    time: float
    names: tuple[str, ...]
    positions: tuple[float, ...]
    velocities: tuple[float, ...]


class ArmService:
    """Commands for an articulated arm: joint targets now, or a smooth move over a duration.

    A thin adapter over a :class:`~simrun.services.joint_service.JointService` of the arm (its
    :attr:`joint_service`: 50 Hz by default, ``profile = "cosine"``, ``integral = False``, ``hold = "all"``),
    which does all the work: targets, moves, ``busy``, holding, reset, snapshots. This class keeps the arm's
    own names: joints by full name, base to tip, passive ones included (:attr:`joints`), one value per joint
    (:meth:`set_joint_targets`, :meth:`move_to`), :meth:`joint_states` and :meth:`servo_design`. It is the
    world's controller (the JointService inside it is ticked by it, not by the world), so a scene saves it as
    one ``ArmService`` binding and a checkpoint holds one snapshot.

    A position-driven joint's value is its servo target (rad or m), a velocity-driven joint's its speed
    (rad/s or m/s), a passive joint's is ignored.

    Args:
        world: The world.
        entity: Full name of an :class:`ArticulatedArm` entity.
        rate: Update rate of the arm's controls and interpolated moves, Hz.

    Raises:
        EntityError: The entity is not an articulated arm; a rate that is not a positive number.
    """

    def __init__(self, world: World, entity: str, rate: float = 50.0) -> None:
        from simrun.services.joint_service import JointService  # the registry names both: import late

        arm = world.entity(entity)
        if not isinstance(arm, ArticulatedArm):
            raise EntityError(f"{entity!r} is a {arm.TYPE}, not an articulated arm")
        self.world, self.name, self.arm = world, entity, arm
        #: The commanded joints' full names, base to tip (passive ones included, mimicking ones not).
        self.joints = arm.joint_names(entity)
        service = JointService(world, entity, rate=rate, hold="all", profile="cosine", integral=False)
        world.controllers.remove(service)  # ticked by this adapter: one controller, one snapshot
        self.joint_service = service
        self.period = service.period
        self.next_time = world.time
        drives = {name: joint.drive for segment in arm.segments for name, joint in segment.dofs(entity)}
        cut = len(entity) + 1
        #: (full name, name in the JointService, drive) of every commanded joint
        self._plan = [(name, name[cut:], drives.get(name, "none")) for name in self.joints]
        world.controllers.append(self)

    @property
    def busy(self) -> bool:
        """Whether a ``move_to`` is in progress."""
        return self.joint_service.busy

    def servo_design(self) -> dict[str, dict[str, float]]:
        """Each position servo's gains, inertia bound, damping ratio and 2 % settling time (:func:`servo_design`)."""
        return servo_design(self.arm, self.name)

    def joint_states(self) -> JointStates:
        """Current joint positions and velocities (the simulator's), by full name, base to tip."""
        state = self.joint_service.state()
        index = {name: k for k, name in enumerate(state.names)}
        picked = [index[short] for _, short, _ in self._plan]
        return JointStates(
            state.time,
            tuple(self.joints),
            tuple(state.positions[k] for k in picked),
            tuple(state.velocities[k] for k in picked),
        )

    def set_joint_targets(self, targets: list[float] | tuple[float, ...]) -> None:
        """Servo targets for every commanded joint, base to tip (cancels a move); passive joints ignore theirs.

        The new controls are written before the next physics step (the service ticks then).
        """
        self._check(targets)
        positions, speeds = self._split(targets)
        service = self.joint_service
        if positions:
            service.set_positions(list(positions), list(positions.values()))
        if speeds:
            service.set_velocities(list(speeds), list(speeds.values()))
        self._tick_now()

    def move_to(self, joint_positions: list[float] | tuple[float, ...], duration: float) -> None:
        """Move smoothly (cosine profile in joint space) to ``joint_positions`` over ``duration`` seconds.

        A position-driven joint's move starts from its current servo target, not from where the joint is: a
        gripper closed on an object (held short of its target) keeps squeezing, and a joint sagging under load
        does not get a jump in its command. A velocity-driven joint gets its speed at once.
        """
        self._check(joint_positions)
        if not (math.isfinite(duration) and duration > 0):
            raise EntityError("move duration must be a positive number of seconds")
        positions, speeds = self._split(joint_positions)
        service = self.joint_service
        if positions:
            service.move_to(list(positions), list(positions.values()), float(duration))
        if speeds:
            service.set_velocities(list(speeds), list(speeds.values()))

    def check_command(self, call: str, args: tuple[Any, ...]) -> None:
        """Refuse a command before a run starts: what ``call(*args)`` would refuse, nothing applied.

        :func:`simrun.run.commands.check_commands` calls it for every command of a commands file; the
        targets are checked as the JointService inside the arm checks its own (joint ranges, servo ranges).

        Raises:
            EntityError: What the command itself would raise.
        """
        if call not in ("set_joint_targets", "move_to"):
            return
        values = args[0]
        self._check(values)
        positions, speeds = self._split(values)
        service = self.joint_service
        if call == "move_to":
            duration = float(args[1])
            if not (math.isfinite(duration) and duration > 0):
                raise EntityError("move duration must be a positive number of seconds")
            if positions:
                service.check_command("move_to", (list(positions), list(positions.values()), duration))
        elif positions:
            service.check_command("set_positions", (list(positions), list(positions.values())))
        if speeds:
            service.check_command("set_velocities", (list(speeds), list(speeds.values())))

    def tick(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Advance the move and write the arm's controls (the JointService's tick)."""
        self.joint_service.tick(model, data)

    def reset(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """After ``World.reset``: no move in progress, no targets (held where the reset put the arm)."""
        self.joint_service.reset(model, data)

    def snapshot(self) -> dict[str, Any]:
        """The move in progress and the JointService's state, as JSON-ready values (for checkpoints).

        ``move``: ``[start time, duration, start, goal]`` (the commanded joints' values, base to tip; passive
        and velocity joints at their current position) or ``None``; ``service``: the JointService's snapshot.
        """
        service = self.joint_service.snapshot()
        plan, move = service["plan"], None
        if plan is not None:
            states = self.joint_states().positions
            start, goal = list(states), list(states)
            where = {short: k for k, (_, short, _) in enumerate(self._plan)}
            for j, short in enumerate(plan["joints"]):
                start[where[short]], goal[where[short]] = plan["rows"][0][j], plan["rows"][-1][j]
            move = [plan["t0"], plan["times"][-1], [float(v) for v in start], [float(v) for v in goal]]
        return {"move": move, "next_time": self.next_time, "service": service}

    def restore(self, state: dict[str, Any]) -> None:
        """Inverse of :meth:`snapshot`.

        A state without ``service`` (``{"move": ..., "next_time": ...}``, as before the arm's service was a
        JointService) keeps the targets and replaces the move: ``None`` ends it, a move continues on the
        position-driven joints from its start time.
        """
        service = self.joint_service
        if "service" in state:
            service.restore(state["service"])
        else:
            current = service.snapshot()
            move = state["move"]
            if move is None:
                current["plan"] = None
            else:
                t0, duration, start, goal = move
                picked = [k for k, (_, _, drive) in enumerate(self._plan) if drive == "position"]
                current["plan"] = {
                    "t0": float(t0),
                    "times": [0.0, float(duration)],
                    "joints": [self._plan[k][1] for k in picked],
                    "rows": [[float(start[k]) for k in picked], [float(goal[k]) for k in picked]],
                }
            service.restore(current)
        self.next_time = float(state["next_time"])
        self.world.reschedule()  # next_time may have moved earlier

    def _check(self, values: Any) -> None:
        if len(values) != len(self.joints):
            raise EntityError(f"{self.name!r} has {len(self.joints)} joints, got {len(values)} values")
        if not all(math.isfinite(float(v)) for v in values):
            raise EntityError(f"{self.name!r}: joint targets must be finite numbers")

    def _split(self, values: Any) -> tuple[dict[str, float], dict[str, float]]:
        """The values of the joints with a servo: (position targets, speeds) by the JointService's names."""
        actuated = set(self.joint_service.joints())
        positions: dict[str, float] = {}
        speeds: dict[str, float] = {}
        for (_, short, drive), value in zip(self._plan, values, strict=True):
            if short in actuated:
                (positions if drive == "position" else speeds)[short] = float(value)
        return positions, speeds

    def _tick_now(self) -> None:
        """Tick before the next physics step, so new targets act at once (as a direct write of the controls)."""
        if self.next_time > self.world.time:
            self.next_time = self.world.time
            self.world.reschedule()
