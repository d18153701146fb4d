"""Carrying a running world's state across a recompile (:mod:`simrun.world.edit`), by name.

:func:`carry_state` copies MuJoCo's integration state (time, joints, actuators, mocap, wrenches, equality
activations) from the running ``MjData`` into the one of the new model, matching joints, actuators, bodies
and equalities by name; :func:`carry_kinematics` copies the bodies' derived frames as the last step left
them. Bodies named *fresh* (an inserted entity, one given a new pose) keep the new model's initial values.
Services and sensors cross too: :func:`bind_now` binds a service to the new model before it is restored,
:func:`rebuild_service` / :func:`rebuild_sensor` build one again in its place, restored from its snapshot.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import mujoco

from simrun.errors import SimrunError
from simrun.world.edit_errors import EditError

if TYPE_CHECKING:
    from simrun.world.world import World


def _bound_to(target: Any, names_: set[str]) -> bool:
    """Whether a binding's target (an entity, ``RIG/left``) is one of ``names_`` or below one."""
    return isinstance(target, str) and any(target == n or target.startswith(n + "/") for n in names_)


def carry_state(
    old_model: mujoco.MjModel,
    old: mujoco.MjData,
    model: mujoco.MjModel,
    data: mujoco.MjData,
    fresh: set[str] = frozenset(),  # type: ignore[assignment]
) -> None:
    """Copy the integration state of ``old`` into ``data`` by name: what ``model`` shares with ``old_model``.

    Time; each joint's ``qpos``, ``qvel``, ``qacc_warmstart`` and ``qfrc_applied`` (same name and type);
    each actuator's ``ctrl`` and ``act``; each body's ``xfrc_applied`` and, for mocap bodies, its mocap pose;
    each equality's ``eq_active``. Joints and mocap poses of bodies named in ``fresh`` (or below them,
    ``NAME/...``) are not copied: they keep ``model``'s initial values (``qpos0``, at rest).
    """
    data.time = old.time

    def is_fresh(body: str) -> bool:
        return _bound_to(body, fresh)

    sizes = {0: (7, 6), 1: (4, 3), 2: (1, 1), 3: (1, 1)}
    for j in range(model.njnt):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j)
        k = mujoco.mj_name2id(old_model, mujoco.mjtObj.mjOBJ_JOINT, name) if name else -1
        if k < 0 or old_model.jnt_type[k] != model.jnt_type[j]:
            continue
        if is_fresh(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, int(model.jnt_bodyid[j])) or ""):
            continue
        nq, nv = sizes[int(model.jnt_type[j])]
        a, b = int(model.jnt_qposadr[j]), int(old_model.jnt_qposadr[k])
        data.qpos[a : a + nq] = old.qpos[b : b + nq]
        a, b = int(model.jnt_dofadr[j]), int(old_model.jnt_dofadr[k])
        for target, source in ((data.qvel, old.qvel), (data.qacc_warmstart, old.qacc_warmstart)):
            target[a : a + nv] = source[b : b + nv]
        data.qfrc_applied[a : a + nv] = old.qfrc_applied[b : b + nv]
    for i in range(model.nu):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, i)
        k = mujoco.mj_name2id(old_model, mujoco.mjtObj.mjOBJ_ACTUATOR, name) if name else -1
        if k < 0:
            continue
        data.ctrl[i] = old.ctrl[k]
        n = int(model.actuator_actnum[i])
        if n and n == int(old_model.actuator_actnum[k]):
            a, b = int(model.actuator_actadr[i]), int(old_model.actuator_actadr[k])
            data.act[a : a + n] = old.act[b : b + n]
    for i in range(1, model.nbody):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, i)
        k = mujoco.mj_name2id(old_model, mujoco.mjtObj.mjOBJ_BODY, name) if name else -1
        if k < 0:
            continue
        data.xfrc_applied[i] = old.xfrc_applied[k]
        m, o = int(model.body_mocapid[i]), int(old_model.body_mocapid[k])
        if m >= 0 and o >= 0 and not is_fresh(name or ""):
            data.mocap_pos[m], data.mocap_quat[m] = old.mocap_pos[o], old.mocap_quat[o]
    for i in range(model.neq):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_EQUALITY, i)
        k = mujoco.mj_name2id(old_model, mujoco.mjtObj.mjOBJ_EQUALITY, name) if name else -1
        if k >= 0:
            data.eq_active[i] = old.eq_active[k]
    if model.nuserdata == old_model.nuserdata:
        data.userdata[:] = old.userdata


#: Body quantities MuJoCo derives from the state (``mj_forward``), which a stepped ``MjData`` holds one step old.
_KINEMATICS = ("xpos", "xquat", "xmat", "xipos", "ximat", "subtree_com", "cinert", "cvel")


def carry_kinematics(
    old_model: mujoco.MjModel,
    old: mujoco.MjData,
    model: mujoco.MjModel,
    data: mujoco.MjData,
    fresh: set[str] = frozenset(),  # type: ignore[assignment]
) -> None:
    """Copy the bodies' derived positions and frames (:data:`_KINEMATICS`) of ``old`` by body name.

    After a step, ``MjData`` holds them for the state *before* that step (``mj_step`` computes them, then
    integrates); a hook reading them before the next step (an arm's weight carry reads the links' ``xipos``)
    must see those, not ones computed afresh at the new state, to continue bit for bit. Bodies in ``fresh``
    (and below) keep what ``mj_forward`` gave them at their new pose.
    """
    for i in range(1, model.nbody):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, i) or ""
        k = mujoco.mj_name2id(old_model, mujoco.mjtObj.mjOBJ_BODY, name) if name else -1
        if k < 0 or _bound_to(name, fresh):
            continue
        above_fresh = any(f.startswith(name + "/") for f in fresh)  # its subtree changed: its centre of mass too
        for field in _KINEMATICS:
            if not (above_fresh and field == "subtree_com"):
                getattr(data, field)[i] = getattr(old, field)[k]


def bind_now(service: Any, model: Any) -> None:
    """Bind a service (and the JointService an ArmService wraps) to ``model`` now, before it is restored.

    A service meeting a model at its next tick takes it for a restart at time 0 (a ``DriveService`` zeroes
    its odometry, a ``JointService`` forgets what it holds); bound now (their ``_lookup``, the services' own
    binding step) and then restored from a snapshot, it continues as it was.
    """
    for target in (service, getattr(service, "joint_service", None)):
        lookup = getattr(target, "_lookup", None)
        if callable(lookup):
            lookup(model)


def rebuild_service(world: World, kind: str, entity: str, snapshot: dict[str, Any] | None = None) -> Any:
    """Build a bound service again from its binding, in its place among the controllers, restored.

    ``snapshot``: the state to restore (taken before the model changed); ``None``: the old service's now.
    """
    old = world._bound.pop((kind, entity), None)
    if old is None:
        return world.service(kind, entity)
    index = next(k for k, c in enumerate(world.controllers) if c is old)
    world.controllers.pop(index)
    try:
        new = world.service(kind, entity)
    except SimrunError as exc:
        message = f"{kind} of {entity!r} cannot drive the edited entity: {exc.message or exc}"
        raise EditError(message, key="entity") from None
    world.controllers.remove(new)
    world.controllers.insert(index, new)
    bind_now(new, world.model)
    new.restore(old.snapshot() if snapshot is None else snapshot)
    return new


def rebuild_sensor(world: World, name: str, spec: dict[str, Any], keep_noise: bool = True) -> Any:
    """Build a sensor again from ``spec`` in its place (sensors, specs, controllers), restored from its snapshot.

    ``keep_noise``: the noise generator continues its stream (else it starts from the spec's ``seed``).
    """
    old = world.sensors[name]
    order = list(world.sensors)
    spec_index = next(k for k, s in enumerate(world.sensor_specs) if s.get("name") == name)
    index = next(k for k, c in enumerate(world.controllers) if c is old)
    del world.sensors[name]
    world.sensor_specs.pop(spec_index)
    world.controllers.pop(index)
    snapshot = old.snapshot()
    try:
        new = world.add_sensor(spec)
    except (SimrunError, TypeError, ValueError) as exc:
        raise EditError(str(exc).removeprefix(f"sensor {name!r}: "), key=None, entity=name) from None
    world.controllers.remove(new)
    world.controllers.insert(index, new)
    world.sensor_specs.insert(spec_index, world.sensor_specs.pop())
    sensors = dict(world.sensors)
    world.sensors.clear()
    world.sensors.update({n: sensors[n] for n in order})
    if not keep_noise:
        snapshot["rng"] = new.snapshot()["rng"]
    new.restore(snapshot)
    new.reading = old.reading
    return new
