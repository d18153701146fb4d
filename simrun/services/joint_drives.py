"""How the :class:`~simrun.services.joint_service.JointService` drives one joint, and what the joint can do.

:func:`drive_of` reads one actuator of the compiled model (never names): what its gain, bias and dynamics make
it (:func:`actuator_kind`: a position, velocity or integrated-velocity servo, or a force; see
:mod:`simrun.services.joint_service` for the loop each gets), its control range, its filter, and the **range of
targets** the joint and the actuator allow (issue 42): a position target must lie within

* the joint's range, when MuJoCo limits it (``jnt_limited``, ``jnt_range``: rad for a hinge, m for a slide);
* what the actuator can reach: a position servo at rest holds ``gain ctrl + b0 + b1 gear q = 0``, so its
  ``ctrlrange`` (when ``ctrllimited``) bounds ``q`` to ``-(gain ctrl + b0) / (b1 gear)`` over it
  (``ctrl / gear`` for ``<position>``); an integrated-velocity servo's ``actrange`` (``actlimited``) bounds
  ``gear q``;
* +-:data:`MAX_TARGET` otherwise (a joint and an actuator with no limits);

and a velocity target within a velocity servo's ``ctrlrange / gear`` and +-:data:`MAX_SPEED`. A command
outside is refused (:func:`check_position`, :func:`check_speed`: one line naming the joint, the value and the
range, and what sets it); a target that a velocity moves reaches the range's end and stops there.

A joint at the end of its range reads a hair outside it (MuJoCo's limits are soft: ``-4e-21`` m for a finger
closed at 0), so a position target within :func:`range_slack` of the range is taken as the range's end
(clamped), and such positions can be sent back as they are read. Further out is still refused, also when the
joint itself is there (measured on ../shared/robots after 1 s: panda's finger pressed 0.8 mm past 0, and
panda joint4, a1's calves and kinova's joint 2, whose zero pose lies outside their ranges, 0.01 to 0.25 rad
out).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from simrun.errors import EntityError

#: Largest position target of a joint with no range of its own or from its actuator, rad or m (docs/limits.md).
MAX_TARGET = 1e6
#: Largest velocity target, rad/s or m/s (docs/limits.md).
MAX_SPEED = 1e6
#: A position target this fraction of its range's width (at most this many rad or m) past an end is clamped.
RANGE_SLACK = 1e-3


@dataclass(frozen=True, slots=True)
class Drive:
    """One commandable joint: its ids, how its actuator turns a target into a control, and its target range.

    Attributes:
        kind: ``position``, ``velocity``, ``intvelocity`` or ``force``.
        actuator: The actuator's id.
        qpos: The joint's address in ``qpos``.
        dof: The joint's degree of freedom.
        gear: The actuator's gear (first component).
        gain: The actuator's fixed gain (``gainprm[0]``).
        mass: The joint's diagonal of the mass matrix at the initial pose, kg m^2 or kg.
        damping: The joint's damping, N m s/rad or N s/m.
        low: Lowest control (``ctrlrange``; ``-inf`` when not limited).
        high: Highest control.
        lag: Time constant of a filtered force actuator's activation, s (0: the control is the force).
        exact: The filter is integrated exactly (``filterexact``), else by the integrator's Euler step.
        lowest: Lowest position target, rad or m (see the module).
        highest: Highest position target, rad or m.
        source: What sets ``lowest``/``highest``, for messages.
        slowest: Lowest velocity target, rad/s or m/s.
        fastest: Highest velocity target, rad/s or m/s.
        unit: ``rad`` (a hinge) or ``m`` (a slide).
    """

    kind: str
    actuator: int
    qpos: int
    dof: int
    gear: float
    gain: float
    mass: float
    damping: float
    low: float
    high: float
    lag: float = 0.0
    exact: bool = False
    lowest: float = -MAX_TARGET
    highest: float = MAX_TARGET
    source: str = f"the bound of {MAX_TARGET:g} on targets of unlimited joints"
    slowest: float = -MAX_SPEED
    fastest: float = MAX_SPEED
    unit: str = "rad"


def drive_of(
    model: mujoco.MjModel,
    a: int,
    joint: int,
    qpos: int,
    dof: int,
    full: np.ndarray[Any, np.dtype[np.float64]],
) -> Drive | None:
    """How actuator ``a`` drives hinge or slide ``joint`` (its ``qpos`` address and ``dof``), or ``None``.

    ``full`` is MuJoCo's mass matrix at the initial pose (nv x nv). ``None``: the actuator is not commandable
    (a zero gear, a muscle, user gains or biases: :func:`actuator_kind`).
    """
    gear, gain = float(model.actuator_gear[a, 0]), float(model.actuator_gainprm[a, 0])
    kind = actuator_kind(model, a)
    if gear == 0 or kind is None:
        return None
    low, high = _ctrl_range(model, a)
    lowest, highest, source = _position_range(model, a, joint, kind, gear, gain)
    slowest, fastest = -MAX_SPEED, MAX_SPEED
    if kind == "velocity" and model.actuator_ctrllimited[a]:
        ends = sorted((low / gear, high / gear))
        slowest, fastest = max(slowest, ends[0]), min(fastest, ends[1])
    return Drive(
        kind,
        a,
        qpos,
        dof,
        gear,
        gain,
        float(full[dof, dof]),
        float(model.dof_damping[dof]),
        low,
        high,
        *_lag(model, a, kind),
        lowest,
        highest,
        source,
        slowest,
        fastest,
        "m" if int(model.jnt_type[joint]) == int(mujoco.mjtJoint.mjJNT_SLIDE) else "rad",
    )


def _position_range(
    model: mujoco.MjModel, a: int, joint: int, kind: str, gear: float, gain: float
) -> tuple[float, float, str]:
    """(lowest, highest, what sets them) of a position target (see the module)."""
    bounds = [(-MAX_TARGET, MAX_TARGET, f"the bound of {MAX_TARGET:g} on targets of unlimited joints")]
    if model.jnt_limited[joint]:
        low, high = (float(x) for x in model.jnt_range[joint])
        bounds.append((low, high, f"the joint's range [{_num(low)}, {_num(high)}]"))
    reach = None
    if kind == "position" and model.actuator_ctrllimited[a]:
        bias = model.actuator_biasprm[a]
        controls = [float(c) for c in model.actuator_ctrlrange[a]]
        if bias[0] == 0 and bias[1] == -gain:  # <position>: ctrl = gear q
            ends = [c / gear for c in controls]
        else:
            ends = [-(gain * c + float(bias[0])) / (float(bias[1]) * gear) for c in controls]
        reach = (
            min(ends),
            max(ends),
            f"what its actuator's ctrlrange [{_num(controls[0])}, {_num(controls[1])}] reaches",
        )
    elif kind == "intvelocity" and model.actuator_actlimited[a]:
        acts = [float(c) for c in model.actuator_actrange[a]]
        ends = [c / gear for c in acts]
        reach = (min(ends), max(ends), f"what its actuator's actrange [{_num(acts[0])}, {_num(acts[1])}] reaches")
    if reach is not None:
        bounds.append(reach)
    lowest = max(bounds, key=lambda b: b[0])
    highest = min(bounds, key=lambda b: b[1])
    if lowest[0] > highest[1]:  # an actuator that cannot reach inside the joint's range: the joint's range
        bounds = bounds[:2]
        lowest, highest = max(bounds, key=lambda b: b[0]), min(bounds, key=lambda b: b[1])
    source = lowest[2] if lowest[2] == highest[2] else f"{lowest[2]} and {highest[2]}"
    return lowest[0], highest[1], source


def range_slack(drive: Drive) -> float:
    """How far past an end of its range a position target is still clamped to it, rad or m.

    :data:`RANGE_SLACK` of the range's width, at most :data:`RANGE_SLACK` rad or m (a finger 0.0159 m wide:
    1.6e-5 m; a hinge of 2 pi or an unlimited joint: 1e-3 rad), and at least 1e-9.
    """
    return max(1e-9, RANGE_SLACK * min(drive.highest - drive.lowest, 1.0))


def check_position(joint: str, drive: Drive, value: float, what: str) -> float:
    """A position target within the drive's range: ``value`` (rad or m), clamped when within :func:`range_slack`.

    Raises:
        EntityError: ``value`` is further outside ``[drive.lowest, drive.highest]`` (one line naming the joint,
            the value and the range).
    """
    slack = range_slack(drive)
    if not drive.lowest - slack <= value <= drive.highest + slack:
        raise EntityError(
            f"{what}: joint {joint!r} target {_num(value)} {drive.unit} is outside [{_num(drive.lowest)}, "
            f"{_num(drive.highest)}] {drive.unit} ({drive.source}); give a target within it"
        )
    return min(drive.highest, max(drive.lowest, value))


def check_speed(joint: str, drive: Drive, value: float, what: str) -> None:
    """Refuse a velocity target outside the drive's speeds (one line naming the joint, the value and the range).

    Raises:
        EntityError: ``value`` (rad/s or m/s) is outside ``[drive.slowest, drive.fastest]``.
    """
    if not drive.slowest <= value <= drive.fastest:
        limit = "its actuator's ctrlrange / gear" if drive.fastest < MAX_SPEED else f"the bound of {MAX_SPEED:g}"
        raise EntityError(
            f"{what}: joint {joint!r} velocity {_num(value)} {drive.unit}/s is outside [{_num(drive.slowest)}, "
            f"{_num(drive.fastest)}] {drive.unit}/s ({limit}); give a velocity within it"
        )


def _num(value: float) -> str:
    """A number as a message shows it: up to 10 significant digits."""
    return f"{value:.10g}"


def actuator_kind(model: mujoco.MjModel, a: int) -> str | None:
    """What the actuator's gain, bias and dynamics make it, or ``None``: not commandable.

    See :mod:`simrun.services.joint_service` for each kind.
    """
    gain, bias = model.actuator_gainprm[a], model.actuator_biasprm[a]
    biastype, dyntype = int(model.actuator_biastype[a]), int(model.actuator_dyntype[a])
    if int(model.actuator_gaintype[a]) != int(mujoco.mjtGain.mjGAIN_FIXED) or gain[0] == 0:
        return None  # muscles, user gains: the control is not a force, a position or a speed
    if biastype not in (int(mujoco.mjtBias.mjBIAS_NONE), int(mujoco.mjtBias.mjBIAS_AFFINE)):
        return None
    affine = biastype == int(mujoco.mjtBias.mjBIAS_AFFINE)
    servo = affine and bias[1] < 0 and gain[0] > 0  # a spring towards a point the control sets
    if dyntype == int(mujoco.mjtDyn.mjDYN_INTEGRATOR):
        return "intvelocity" if servo and model.actuator_actadr[a] >= 0 else None
    if dyntype not in (
        int(mujoco.mjtDyn.mjDYN_NONE),
        int(mujoco.mjtDyn.mjDYN_FILTER),
        int(mujoco.mjtDyn.mjDYN_FILTEREXACT),
    ):
        return None
    if servo:
        return "position"
    if affine and bias[0] == 0 and bias[1] == 0 and bias[2] == -gain[0] and gain[0] > 0:
        return "velocity"
    return "force"


def servo_integral_rate(model: mujoco.MjModel, drive: Drive, w: float) -> float:
    """How fast (1/s) a position servo's target is shifted by the integral of its error (see the JointService).

    The servo (joint stiffness ``kp = -b1 gear^2``, damping ``kv = -b2 gear^2``) with the joint's damping
    ``b`` and inertia ``m`` closes ``m s^3 + (kv + b) s^2 + kp s + kp r`` around the integral's rate ``r``,
    stable while ``r < (kv + b) / m`` (Routh): half that, and at most ``w / 3``. A servo with no damping at
    all gets none (its own loop would ring).
    """
    bias = model.actuator_biasprm[drive.actuator]
    damping = -float(bias[2]) * drive.gear * drive.gear + drive.damping
    if damping <= 0 or drive.mass <= 0:
        return 0.0
    return min(w / 3.0, 0.5 * damping / drive.mass)


def _lag(model: mujoco.MjModel, a: int, kind: str) -> tuple[float, bool]:
    """A force actuator's filter time constant (s, 0 without a filter) and whether it is ``filterexact``."""
    dyntype = int(model.actuator_dyntype[a])
    filters = (int(mujoco.mjtDyn.mjDYN_FILTER), int(mujoco.mjtDyn.mjDYN_FILTEREXACT))
    if kind != "force" or dyntype not in filters or model.actuator_actadr[a] < 0:
        return 0.0, False
    lag = float(model.actuator_dynprm[a, 0])
    return (lag, dyntype == filters[1]) if lag > 0 else (0.0, False)


def filter_decay(model: mujoco.MjModel, drive: Drive, hold: float) -> float:
    """How much of a filtered actuator's activation is left after a control held ``hold`` s (0 to 1).

    MuJoCo's ``filter`` is ``act' = (ctrl - act) / lag``: one Euler step of ``dt`` keeps ``1 - dt / lag``
    (``filterexact``, or the RK4 integrator: ``exp(-dt / lag)``); a control is held for
    ``max(1, round(hold / dt))`` steps.
    """
    dt = float(model.opt.timestep)
    steps = max(1, round(hold / dt))
    if drive.exact or int(model.opt.integrator) == int(mujoco.mjtIntegrator.mjINT_RK4):
        return math.exp(-steps * dt / drive.lag)
    return max(0.0, 1.0 - dt / drive.lag) ** steps


def _ctrl_range(model: mujoco.MjModel, a: int) -> tuple[float, float]:
    if model.actuator_ctrllimited[a]:
        low, high = model.actuator_ctrlrange[a]
        return float(low), float(high)
    return -math.inf, math.inf
