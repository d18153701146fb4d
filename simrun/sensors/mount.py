"""Where a sensor or camera sits: a body of a robot by its full name, the robot's root by default.

Every sensor and camera kind takes ``body = "NAME/link"`` (a body of the entity's model, by its full name)
and is attached to that body, so MuJoCo moves it: ray and state sensors read the body's pose from
``data.xpos``/``data.xmat`` each sample, ``Camera`` and ``StereoRig`` put their MuJoCo cameras into that body
of the spec. Without ``body`` a sensor sits on :func:`root_body`: the entity's own body, or, where that is a
marker the robot leaves at its spawn point, the body that moves (the body carrying the robot's root joints).

What "the robot" is (:func:`robot_mask`): every body named ``TOP`` or ``TOP/...`` (``TOP``: the top-level
entity of the mount) and every body below one of them, so an MJCF model attached in the world (a free-base
walker, whose trunk is not a child of the entity's body), its wheels, a mounted arm and a camera entity are
all one robot. These functions read the compiled model (and, for the cameras, the spec being built) under the
entity's name prefix; a robot contract may later answer the same questions.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt

from simrun.errors import EntityError, did_you_mean

BoolArray = npt.NDArray[np.bool_]

_FREE, _SLIDE = int(mujoco.mjtJoint.mjJNT_FREE), int(mujoco.mjtJoint.mjJNT_SLIDE)
#: Most body names an unknown-body error lists (the rest are counted).
MAX_LISTED = 12


def check_body_name(entity: str, body: Any, key: str = "body") -> str | None:
    """``body`` as given, refused at once unless it is ``None`` or a string naming a body under ``entity/``.

    A sensor's body is one of its entity's (a sensor of ``base/arm`` names ``base/arm/wrist``; one on the
    base's wheel binds to ``base``).

    Raises:
        EntityError: Not a string, or not of the entity (the message says how to name a link).
    """
    if body is None:
        return None
    if not isinstance(body, str) or not body.startswith(f"{entity}/"):
        raise EntityError(f"{body!r} is not a body of {entity!r}; name one of its links as '{entity}/LINK'", key=key)
    return body


def top_entity(entity: str) -> str:
    """The top-level entity of a full entity name (``base`` for ``base/arm``)."""
    return entity.split("/", 1)[0]


def _moves_alone(joint_types: Iterable[int]) -> bool:
    """Whether a body with these joints translates on its own: a free joint, or two or more slides."""
    types = list(joint_types)
    return _FREE in types or types.count(_SLIDE) >= 2


def _pick_root(own: str, own_moves: bool, candidates: Iterable[tuple[str, list[int]]]) -> str:
    """The rule of :func:`root_body` over (body name, joint types) of the candidate bodies, in model order."""
    if own_moves:
        return own
    return next((name for name, joints in candidates if _moves_alone(joints)), own)


def _body_names(model: mujoco.MjModel) -> list[str]:
    return [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) or "" for b in range(model.nbody)]


def root_body(model: mujoco.MjModel, entity: str) -> int:
    """The body a sensor of ``entity`` sits on when no ``body`` is given: the body that moves with the robot.

    The entity's own body when it moves itself (a free joint: the built-in robots, ``free = true``; mocap:
    ``kinematic``), or when it is a child entity; else the first top-level body of its model (a body of the
    world named ``NAME/...``: an MJCF model with a free base, or a child of the entity's body: a welded
    model) that carries a free joint or two or more slide joints (``root_slides``; dm_control's planar
    walkers' ``rootx``/``rootz``); else the entity's own body (a welded arm's base, a static object).

    Raises:
        EntityError: The entity has no body in the model.
    """
    names = _body_names(model)
    try:
        own = names.index(entity)
    except ValueError:
        raise EntityError(f"{entity!r} has no body in the model", entity=entity) from None
    own_moves = (
        int(model.body_jntnum[own]) > 0 or int(model.body_mocapid[own]) >= 0 or int(model.body_parentid[own]) != 0
    )
    prefix = f"{entity}/"

    def joints(b: int) -> list[int]:
        first = int(model.body_jntadr[b])
        return [int(t) for t in model.jnt_type[first : first + int(model.body_jntnum[b])]]

    parents = model.body_parentid
    world = [(names[b], joints(b)) for b in range(1, model.nbody) if parents[b] == 0 and names[b].startswith(prefix)]
    under = [(names[b], joints(b)) for b in range(1, model.nbody) if parents[b] == own]
    return names.index(_pick_root(entity, own_moves, [*world, *under]))


def spec_root_body(spec: mujoco.MjSpec, entity: str) -> Any:
    """:func:`root_body` in a spec being built (for cameras, which must be put into the body before compiling).

    Raises:
        EntityError: The entity has no body in the spec (not yet built).
    """
    own = spec.body(entity)
    if own is None:
        raise EntityError(f"{entity!r} has no body (yet): insert it before what mounts on it", entity=entity)
    own_joints = list(own.joints)
    own_moves = bool(own_joints) or bool(own.mocap) or own.parent.name != "world"
    prefix = f"{entity}/"

    def joints(body: Any) -> list[int]:
        return [int(j.type) for j in body.joints]

    world = [(b.name, joints(b)) for b in spec.worldbody.bodies if b.name.startswith(prefix)]
    under = [(b.name, joints(b)) for b in own.bodies]
    return spec.body(_pick_root(entity, own_moves, [*world, *under]))


def robot_mask(model: mujoco.MjModel, entity: str) -> BoolArray:
    """(nbody,) True for every body of the robot ``entity`` belongs to (see the module): what ray sensors ignore."""
    top = top_entity(entity)
    prefix = f"{top}/"
    members = [b for b, name in enumerate(_body_names(model)) if b and (name == top or name.startswith(prefix))]
    roots = {int(r) for r in model.body_rootid[members]} - {0}
    mask: BoolArray = np.isin(model.body_rootid, sorted(roots))
    mask[0] = False
    return mask


def _unknown(body: str, names: Iterable[str], key: str, robot: str) -> EntityError:
    """The one-line error for a ``body`` that names no body: the closest name and the bodies of ``robot``."""
    known = [n for n in names if n == robot or n.startswith(f"{robot}/")]
    hint = did_you_mean(body, known)
    listed = ", ".join(known[:MAX_LISTED]) or "none"
    if len(known) > MAX_LISTED:
        listed += f" and {len(known) - MAX_LISTED} more"
    return EntityError(f"{body!r} is not a body of {robot!r}{hint}", key=key, hint=f"bodies of {robot!r}: {listed}")


def resolve_body(model: mujoco.MjModel, entity: str, body: str | None, key: str = "body") -> int:
    """The id of the body a sensor of ``entity`` sits on: ``body`` (a full name), or :func:`root_body`.

    Raises:
        EntityError: ``body`` names no body of the model: one line naming the entity, the key, the closest
            body ("did you mean") and the robot's bodies.
    """
    if body is None:
        return root_body(model, entity)
    found = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body)
    if found < 0:
        raise _unknown(body, _body_names(model), key, entity)
    return int(found)


def camera_mount(
    spec: mujoco.MjSpec,
    own: Any,
    entity: str,
    parent: str | None,
    body: Any,
    pose: tuple[Iterable[float], Iterable[float]],
) -> tuple[Any, Callable[[Iterable[float], Iterable[float]], tuple[list[float], list[float]]]]:
    """Where a camera entity puts its MuJoCo cameras: a spec body, and the map from the entity's frame into it.

    ``body`` (a full body name, any robot's) wins; else a camera entity that is a child of a robot goes on the
    robot's root body (:func:`spec_root_body`: the trunk of a free-base model, not the marker it leaves at
    its spawn point); else it stays on its own body ``own``. Off its own body, the entity's ``pose``
    ((x, y, z), (w, x, y, z)) is its frame in the mounting body's frame.

    Returns:
        The spec body (``MjsBody``) and ``place(pos, quat)``: a position and orientation in the entity's frame
        turned into the mounting body's frame.

    Raises:
        EntityError: ``body`` is not a string or names no body built so far (``entity``: the camera's full name).
    """
    if body is not None:
        if not isinstance(body, str):
            raise EntityError(f"{body!r} is not a body name; name a link as 'ROBOT/LINK'", key="body", entity=entity)
        mount = spec.body(body)
        if mount is None:
            raise _unknown(body, (b.name for b in spec.bodies), "body", top_entity(body))
    elif parent is not None:
        mount = spec_root_body(spec, parent)
    else:
        mount = own
    stays = mount.name == own.name or (body is None and mount.name == parent)  # on the parent's moving body
    if stays:

        def here(pos: Iterable[float], quat: Iterable[float]) -> tuple[list[float], list[float]]:
            return [float(v) for v in pos], [float(v) for v in quat]

        return own, here
    position, orientation = (np.asarray(list(v), dtype=float) for v in pose)

    def place(pos: Iterable[float], quat: Iterable[float]) -> tuple[list[float], list[float]]:
        turned, combined = np.zeros(3), np.zeros(4)
        mujoco.mju_rotVecQuat(turned, np.asarray(list(pos), dtype=float), orientation)
        mujoco.mju_mulQuat(combined, orientation, np.asarray(list(quat), dtype=float))
        return (position + turned).tolist(), combined.tolist()

    return mount, place


def top_of(model: mujoco.MjModel, body: int, robot: BoolArray | None = None) -> float:
    """Height of the highest point of a body's geoms above its origin, along its Z, metres (initial pose).

    The default mount height of a laser: the top of the chassis for the built-in robots, of a torso or link for
    an imported one. It is measured in the compiled model at ``qpos0`` from each geom's bounding box
    (``geom_aabb``, turned into the body frame); planes are left out. A body without geoms of its own (the
    marker of a welded MJCF model, a ``free = true`` model's root frame) takes the highest point of the
    robot's geoms (``robot``: a :func:`robot_mask`) instead; 0 when there are none.
    """
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    planes = model.geom_type == int(mujoco.mjtGeom.mjGEOM_PLANE)
    geoms = np.flatnonzero((model.geom_bodyid == body) & ~planes)
    if not geoms.size and robot is not None:
        geoms = np.flatnonzero(robot[model.geom_bodyid] & ~planes)
    if not geoms.size:
        return 0.0
    frame = data.xmat[body].reshape(3, 3)
    up = frame[:, 2]
    tops = []
    for g in geoms:
        rotation = data.geom_xmat[g].reshape(3, 3)
        centre, half = model.geom_aabb[g, :3], model.geom_aabb[g, 3:]
        axis = rotation.T @ up  # the body's Z in the geom's frame
        centre_up = float(np.dot(data.geom_xpos[g] + rotation @ centre - data.xpos[body], up))
        tops.append(centre_up + float(np.abs(axis) @ half))
    return float(max(tops))


class Mount:
    """The body a sensor sits on, resolved once per compiled model (:func:`resolve_body`).

    Args:
        entity: Full name of the entity carrying the sensor.
        body: Full name of the body (``NAME/link``), or ``None``: the robot's root body
            (:func:`root_body`).

    Attributes:
        name: Full name of the body: ``body`` as given, else the entity's name until the first bind, then the
            root body's name.
        id: Its body id in the last model bound (-1 before).
    """

    def __init__(self, entity: str, body: str | None = None) -> None:
        self.entity, self.body = entity, check_body_name(entity, body)
        self.name = body if body is not None else entity
        self.id = -1
        self._bound: mujoco.MjModel | None = None  # the model the id is for (held: a freed id is reused)

    def bind(self, model: mujoco.MjModel) -> int:
        """The body's id in ``model`` (:attr:`name` follows it)."""
        if self._bound is not model:
            self.id = resolve_body(model, self.entity, self.body)
            self.name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, self.id) or self.name
            self._bound = model
        return self.id
