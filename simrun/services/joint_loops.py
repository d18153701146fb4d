"""The control laws of the :class:`~simrun.services.joint_service.JointService`, over arrays of joints.

How a position or velocity target becomes a control depends on the actuator (read from the compiled model,
never from names; :func:`simrun.services.joint_drives.actuator_kind`):

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
tendons, sites or bodies are not commanded (:meth:`~simrun.services.joint_service.JointService.joints`
leaves their joints out).


**Cost per tick** (issue 41). A :class:`Layout` is built once per set of driven joints (in the order the
service drives them): their ``qpos``/``dof``/actuator addresses and every constant of their laws as numpy
arrays (gains, biases, the servos' integral rates, the filters' decays, ``S``), so a tick is a few array
operations per kind of actuator rather than a Python loop over joints. The arithmetic is the loop's, term for
term in the same order (IEEE: the same bits), so the controls are the ones the per-joint loop gave. The
feed-forward forces are computed in a :class:`Scratch` ``MjData`` from the state alone (``qpos``, ``qvel``):
the derived fields of the world's data between steps belong to the state before the last step, and a run
resumed from a checkpoint has other ones, so a control that read them would not replay bit for bit.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import mujoco
import numpy as np

from simrun.services.joint_drives import Drive, filter_decay, servo_integral_rate
from simrun.services.joint_inertia import Matrix, free_inertia, whiten, with_contacts

#: An index array (addresses in ``qpos``, ``qvel``, ``ctrl``, ``act``, or places in a layout).
Index = np.ndarray[Any, np.dtype[np.intp]]
#: A boolean array, one per joint.
Mask = np.ndarray[Any, np.dtype[np.bool_]]


_EMPTY = np.zeros(0)


class Scratch:
    """A private ``MjData`` of one model, where the feed-forward forces (and the contacts) are computed."""

    def __init__(self, model: mujoco.MjModel) -> None:
        self.model = model
        self.data = mujoco.MjData(model)
        self.bias = np.zeros(model.nv)

    def feed_forward(self, data: mujoco.MjData) -> Matrix:
        """``qfrc_bias - qfrc_spring - qfrc_gravcomp`` (per dof, nv) at ``data``'s ``qpos``, ``qvel`` (see the module).

        Leaves the scratch data posed there (kinematics, com, tendons, velocities), as the contacts need it.
        """
        model, work = self.model, self.data
        work.qpos[:] = data.qpos
        work.qvel[:] = data.qvel
        mujoco.mj_kinematics(model, work)
        mujoco.mj_comPos(model, work)
        mujoco.mj_tendon(model, work)
        mujoco.mj_comVel(model, work)
        mujoco.mj_passive(model, work)
        mujoco.mj_rne(model, work, 0, self.bias)
        feed: Matrix = self.bias - work.qfrc_spring - work.qfrc_gravcomp
        return feed


def _floats(values: Sequence[float]) -> Matrix:
    return np.array(values, dtype=np.float64)


class _Group:
    """The joints of one kind in a layout: their places in it and their drives' constants (arrays, one per joint)."""

    def __init__(self, places: list[int], drives: list[Drive], count: int) -> None:
        self.places: Index = np.asarray(places, dtype=np.intp)
        self.whole = places == list(range(count))  # every joint of the layout, in its order: no indexing
        self.size = len(places)
        self.gear = _floats([d.gear for d in drives])
        self.gain = _floats([d.gain for d in drives])
        self.mass = _floats([d.mass for d in drives])
        self.damping = _floats([d.damping for d in drives])

    def take(self, values: Matrix) -> Matrix:
        """``values`` (one per joint of the layout) at this group's joints."""
        return values if self.whole else values[self.places]


class Layout:
    """The joints one tick drives (``names``, in that order) and their laws' constants (see the module).

    Args:
        model: The compiled model.
        drives: Every commandable joint's drive (:func:`~simrun.services.joint_drives.drive_of`).
        names: The driven joints, in the service's order.
        mass: MuJoCo's mass matrix at the model's initial pose (nv x nv), for ``S``.
        bandwidth: ``w``, rad/s.
        period: ``h``, the control period, s.
        integral: Whether the loops integrate the position error.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        drives: Mapping[str, Drive],
        names: tuple[str, ...],
        mass: Matrix,
        bandwidth: float,
        period: float,
        integral: bool,
    ) -> None:
        w, h = bandwidth, period
        self.names, self.bandwidth, self.period, self.integral = names, w, h, integral
        #: Where each joint's targets are in the service's list of held then commanded ones (set by the service;
        #: ``None``: in that order, no joint both held and commanded).
        self.take: Index | None = None
        chosen = [drives[n] for n in names]
        count = len(chosen)
        self.qpos: Index = np.array([d.qpos for d in chosen], dtype=np.intp)
        self.dof: Index = np.array([d.dof for d in chosen], dtype=np.intp)
        self.actuator: Index = np.array([d.actuator for d in chosen], dtype=np.intp)
        self.low = _floats([d.low for d in chosen])
        self.high = _floats([d.high for d in chosen])
        self.gear = _floats([d.gear for d in chosen])
        bias = model.actuator_biasprm[self.actuator] if count else np.zeros((0, 3))
        kinds: dict[str, list[int]] = {"position": [], "velocity": [], "intvelocity": [], "force": []}
        for k, d in enumerate(chosen):
            kinds[d.kind].append(k)

        def group(kind: str) -> _Group | None:
            places = kinds[kind]
            return _Group(places, [chosen[k] for k in places], count) if places else None

        keepable = np.full(count, integral)  # whose integral is kept (unless clipped towards its error)
        self.position = group("position")
        if self.position is not None:
            g = self.position
            rows = bias[g.places]
            self.position_exact: Mask = (rows[:, 0] == 0) & (rows[:, 1] == -g.gain)  # <position>: ctrl = gear q*
            self.position_b0: Matrix = rows[:, 0].copy()
            self.position_b1: Matrix = rows[:, 1] * g.gear
            self.position_rate = _floats([servo_integral_rate(model, chosen[k], w) for k in kinds["position"]])
        self.velocity = group("velocity")
        if self.velocity is not None:
            g = self.velocity
            hold = max(h, float(model.opt.timestep))  # how long a control stays
            servo = g.gear * g.gear * g.gain  # joint torque per rad/s of speed error
            self.velocity_servo: Matrix = servo
            weak = [
                (s + b) ** 2 < 4.0 * m * s * w and s * hold < m
                for s, b, m in zip(servo.tolist(), g.damping.tolist(), g.mass.tolist(), strict=True)
            ]
            self.velocity_weak: Mask = np.array(weak, dtype=bool)  # its own damping cannot damp the loop
            self.velocity_rate = _floats(
                [
                    min(w * w / 3.0, 0.5 * (s + b) * w / m)
                    for s, b, m in zip(servo.tolist(), g.damping.tolist(), g.mass.tolist(), strict=True)
                ]
            )
            keepable[g.places[self.velocity_weak]] = False
        self.intvelocity = group("intvelocity")
        if self.intvelocity is not None:
            g = self.intvelocity
            self.intvelocity_act: Index = model.actuator_actadr[self.actuator[g.places]].astype(np.intp)
            self.intvelocity_rate = _floats([servo_integral_rate(model, chosen[k], w) for k in kinds["intvelocity"]])
        self.force = group("force")
        if self.force is not None:
            g = self.force
            rows = bias[g.places]
            self.force_b0: Matrix = rows[:, 0].copy()
            self.force_b1: Matrix = rows[:, 1] * g.gear
            self.force_b2: Matrix = rows[:, 2] * g.gear
            self.force_damped: Matrix = g.damping / (3.0 * w)  # B / (3 w): the damping added to the inertia
            self.force_dofs: Index = self.dof[g.places]
            self.force_free = free_inertia(mass, self.force_dofs.tolist())  # S
            self.force_whitening = whiten(self.force_free)
            lagged = [j for j, k in enumerate(kinds["force"]) if chosen[k].lag > 0]
            self.force_lagged: Index = np.asarray(lagged, dtype=np.intp)  # filtered actuators, places in the group
            self.force_act: Index = model.actuator_actadr[self.actuator[g.places[self.force_lagged]]].astype(np.intp)
            self.force_decay = _floats([filter_decay(model, chosen[kinds["force"][j]], h) for j in lagged])
        self.keepable: Mask = keepable
        groups = [g for g in (self.position, self.velocity, self.intvelocity, self.force) if g is not None]
        self.single = len(groups) == 1 and groups[0].whole

    def controls(
        self,
        data: mujoco.MjData,
        scratch: Scratch,
        tree: Index,
        movers: Mask,
        before: tuple[Matrix, Matrix],
        after: tuple[Matrix, Matrix],
        integrals: Matrix,
    ) -> tuple[Matrix, Mask, Matrix]:
        """The clipped controls of :attr:`actuator`, which integrals to keep, and the new integrals (rad s or m s).

        ``before``/``after``: position (rad or m) and velocity (rad/s or m/s) targets of :attr:`names` before
        and after this tick moved the velocity-driven ones (the force loops use ``before``, the servos
        ``after``, as the per-joint loop did); ``integrals``: the error integrals so far (0 without one);
        ``tree``: the entity's dofs, ``movers``: per body, whether it moves one of them (for its contacts).
        """
        w, h = self.bandwidth, self.period
        count = len(self.names)
        q, v = data.qpos[self.qpos], data.qvel[self.dof]
        single = self.single  # one kind, every joint: its arrays are the results, nothing scattered
        raw = out = push = new = _EMPTY
        if not single:
            raw, out, push, new = np.empty(count), np.empty(count), np.empty(count), np.empty(count)
        position, velocity = after
        if self.position is not None:
            g = self.position
            p = g.places
            target, here = g.take(position), g.take(q)
            error = target - here
            integral = g.take(integrals) + error * h if self.integral else np.zeros(g.size)
            shift = self.position_rate * integral if self.integral else np.zeros(g.size)
            aim = target + shift
            ctrl = np.where(self.position_exact, g.gear * aim, -(self.position_b0 + self.position_b1 * aim) / g.gain)
            if single:
                raw, out, push, new = ctrl, ctrl, error * g.gear, integral
            else:
                raw[p], out[p], push[p], new[p] = ctrl, ctrl, error * g.gear, integral
        if self.velocity is not None:
            g = self.velocity
            p = g.places
            target, speed, here, rate_now = g.take(position), g.take(velocity), g.take(q), g.take(v)
            error = target - here
            integral = g.take(integrals) + error * h if self.integral else np.zeros(g.size)
            torque = g.mass * (w * w * (target - here) + 2.0 * w * (speed - rate_now))
            weak = g.gear * (rate_now + torque / self.velocity_servo)
            loop = g.gear * (speed + w * error + self.velocity_rate * integral)
            ctrl = np.where(self.velocity_weak, weak, loop)
            if single:
                raw, out, push, new = ctrl, ctrl, error * g.gear, integral
            else:
                raw[p], out[p], push[p], new[p] = ctrl, ctrl, error * g.gear, integral
        if self.intvelocity is not None:
            g = self.intvelocity
            p = g.places
            target, speed = g.take(position), g.take(velocity)
            error = target - g.take(q)
            integral = g.take(integrals) + error * h if self.integral else np.zeros(g.size)
            act = data.act[self.intvelocity_act]
            shift = self.intvelocity_rate * integral
            ctrl = g.gear * speed + w * (g.gear * (target + shift) - act)
            if single:
                raw, out, push, new = ctrl, ctrl, error * g.gear, integral
            else:
                raw[p], out[p], push[p], new[p] = ctrl, ctrl, error * g.gear, integral
        if self.force is not None:
            g = self.force
            p = g.places
            target, speed = before
            here, rate_now = g.take(q), g.take(v)
            error = g.take(target) - here
            integral = g.take(integrals) + error * h if self.integral else np.zeros(g.size)
            feed = scratch.feed_forward(data)[self.force_dofs]
            inertia, slower = with_contacts(
                scratch.model, scratch.data, tree, self.force_dofs, self.force_free, self.force_whitening, w, h, movers
            )
            rates = 3.0 * w * w * error + 3.0 * w * (g.take(speed) - rate_now) + slower * (w * w * w * integral)
            torque = inertia @ rates + self.force_damped * rates + feed
            offset = self.force_b0 + self.force_b1 * here + self.force_b2 * rate_now
            ctrl = (torque / g.gear - offset) / g.gain  # the activation that gives the torque
            if single:
                raw, push, new = ctrl, error * g.gear, integral
            else:
                raw[p], push[p], new[p] = ctrl, error * g.gear, integral
            if self.force_lagged.size:  # filtered: the control that brings the activation there in one hold
                act = data.act[self.force_act]
                lagged = self.force_lagged
                ctrl = ctrl.copy()
                ctrl[lagged] = (ctrl[lagged] - self.force_decay * act) / (1.0 - self.force_decay)
            if single:
                out = ctrl
            else:
                out[p] = ctrl
        clipped: Matrix = np.fmin(self.high, np.fmax(self.low, out))
        keep: Mask = self.keepable & ~(((raw > self.high) & (push > 0)) | ((raw < self.low) & (push < 0)))
        return clipped, keep, new
