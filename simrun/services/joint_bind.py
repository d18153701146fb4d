"""What a :class:`~simrun.services.joint_service.JointService` drives in a compiled model: found once per model.

:func:`bind` finds an entity's hinge and slide joints (``NAME/joint``, named without the prefix), the first
actuator of each that the service can command (:func:`simrun.services.joint_drives.drive_of`: read from the
compiled model, never from names), MuJoCo's mass matrix at the model's initial pose (the loops' gains do not
depend on when they are asked), the dofs of the entity's bodies and which bodies move them (for its contacts,
:func:`simrun.services.joint_inertia.with_contacts`). :func:`wheel_joints` names the joints a drive service
owns, never held.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from simrun.services.joint_drives import Drive, drive_of

_ONE_DOF = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))


@dataclass(frozen=True, slots=True)
class Binding:
    """An entity's joints and drives in one compiled model.

    Attributes:
        joints: (name without the prefix, ``qpos`` address, dof) of every hinge and slide joint, model order.
        drives: The commandable joints' drives, by name, in actuator order.
        mass: MuJoCo's mass matrix at the model's initial pose (nv x nv; kg m^2, kg).
        tree: The dofs of the entity's bodies (its root's included).
        movers: Per body (nbody): whether its chain to the world has one of those dofs.
    """

    joints: list[tuple[str, int, int]]
    drives: dict[str, Drive]
    mass: np.ndarray[Any, np.dtype[np.float64]]
    tree: np.ndarray[Any, np.dtype[np.intp]]
    movers: np.ndarray[Any, np.dtype[np.bool_]]


def bind(model: mujoco.MjModel, entity: str) -> Binding:
    """The joints, drives, initial mass matrix and dofs of the entity named ``entity`` in ``model``."""
    prefix = f"{entity}/"
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
    mine = [b for b in range(model.nbody) if model.body(b).name == entity or model.body(b).name.startswith(prefix)]
    tree = np.flatnonzero(np.isin(model.dof_bodyid, mine)).astype(np.intp)
    movers = np.zeros(model.nbody, dtype=bool)
    moved = set(tree.tolist())
    for b in range(1, model.nbody):  # a parent's id is below its children's
        start, count = int(model.body_dofadr[b]), int(model.body_dofnum[b])
        movers[b] = any(d in moved for d in range(start, start + count)) or movers[int(model.body_parentid[b])]
    return Binding(joints, drives, full, tree, movers)


def wheel_joints(entity: object) -> set[str]:
    """The entity's driven wheel joints, without the prefix: the ``DriveService``'s, never held.

    A built-in differential drive's ``left_wheel`` and ``right_wheel``, an imported robot's ``wheels``.
    """
    from simrun.robots.diff_drive import DifferentialDrive  # the registry names the services: import late

    if isinstance(entity, DifferentialDrive):
        return {"left_wheel", "right_wheel"}
    wheels = getattr(entity, "wheels", ())
    return {str(w) for w in wheels} if isinstance(wheels, tuple | list) else set()
