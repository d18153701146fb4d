"""The inertia a JointService's force loops see: the joints' own, every other dof free, and their contacts'.

:func:`free_inertia` is ``S`` of :mod:`simrun.services.joint_service` (the Schur complement of MuJoCo's mass
matrix over the dofs the loops do not command), :func:`with_contacts` what the contacts of the current pose
add to it (issue 37). Shapes: dof counts of the model (``nv``) and of the commanded force joints.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import mujoco
import numpy as np

#: A float matrix or vector.
Matrix = np.ndarray[Any, np.dtype[np.float64]]
#: MuJoCo's contact constraint types (a constraint row of one of them is a contact's).
_CONTACTS = (
    int(mujoco.mjtConstraint.mjCNSTR_CONTACT_FRICTIONLESS),
    int(mujoco.mjtConstraint.mjCNSTR_CONTACT_PYRAMIDAL),
    int(mujoco.mjtConstraint.mjCNSTR_CONTACT_ELLIPTIC),
)


def free_inertia(mass: Matrix, dofs: list[int]) -> Matrix:
    """The inertia matrix the force joints of ``dofs`` see with every other dof free (``S``: a Schur complement).

    ``mass``: MuJoCo's mass matrix (nv x nv) at the model's initial pose; the result is len(dofs) x len(dofs).
    """
    mine = np.asarray(dofs, dtype=np.intp)
    rest = np.setdiff1d(np.arange(mass.shape[0]), mine)
    found: Matrix = mass[np.ix_(mine, mine)]
    if rest.size:
        found = found - mass[np.ix_(mine, rest)] @ np.linalg.solve(mass[np.ix_(rest, rest)], mass[np.ix_(rest, mine)])
    return found


def with_contacts(
    model: mujoco.MjModel,
    work: mujoco.MjData | None,
    tree: np.ndarray[Any, np.dtype[np.intp]],
    dofs: Sequence[int] | np.ndarray[Any, np.dtype[np.intp]],
    free: Matrix,
    bandwidth: float,
    period: float,
) -> tuple[Matrix, float]:
    """``free`` (the force joints' inertia ``F``, every other dof free) plus what the entity's contacts add now.

    The contacts of the current pose (MuJoCo's collision and constraint rows, computed in the scratch data
    ``work``, which the service has just posed; ``None``: no scratch data yet) that move any of the entity's
    dofs (``tree``) are taken as held, as MuJoCo's soft constraints hold them (regulariser ``efc_R``). With
    ``X = J M^-1`` (their Jacobian ``J``, the mass matrix ``M`` now), ``C`` its columns of the joints' dofs
    and ``G = J X' + R`` (the contacts' inverse inertia), the joints' inverse inertia becomes
    ``F^-1 - C' G^-1 C``, whose inverse is ``F + D``, ``D = F C' H^-1 C F``, ``H = G - C F C'`` (Woodbury;
    ``H``: the contacts' inverse inertia with the joints locked). A ball rolling on the ground moves the whole
    body with it: its roll joint sees 31 times its own inertia, and a loop designed for its own rang ever
    wider (``(s + w)^3`` stays stable up to 9 times the design). ``D`` is added scaled down to at most
    ``1 / (3 w h) - 1`` times ``F`` (its largest eigenvalue
    relative to ``F``, that of ``H^-1 C F C'``; ``h`` the control hold): a loop that much stiffer than the
    free limb still samples stably when the contact lets go. What the cap leaves out, ``k`` times the
    design's inertia, slows the integral by ``min(1, 4.5 / k)`` (the second value returned), so the loop
    keeps half the Routh margin (``(s + w)^3``'s gains are stable while ``k < 9``). No contact on the
    entity: ``(free, 1.0)``.
    """
    hold = max(period, float(model.opt.timestep))
    room = 1.0 / (3.0 * bandwidth * hold) - 1.0
    if room <= 0 or work is None or not tree.size:
        return free, 1.0
    mujoco.mj_collision(model, work)
    if not work.ncon:
        return free, 1.0
    mujoco.mj_makeConstraint(model, work)
    rows = int(work.nefc)
    nv = model.nv
    jac = np.zeros((rows, nv))
    if mujoco.mj_isSparse(model):
        mujoco.mju_sparse2dense(jac, work.efc_J, work.efc_J_rownnz, work.efc_J_rowadr, work.efc_J_colind)
    else:
        jac[:] = work.efc_J[: rows * nv].reshape(rows, nv)
    touching = np.isin(work.efc_type[:rows], _CONTACTS) & (jac[:, tree] != 0).any(axis=1)
    if not touching.any():
        return free, 1.0
    jac = np.ascontiguousarray(jac[touching])
    mujoco.mj_crb(model, work)
    mujoco.mj_factorM(model, work)
    solved = np.empty_like(jac)
    mujoco.mj_solveM(model, work, solved, jac)  # rows: M^-1 j
    coupling = solved[:, dofs] @ free  # C F
    through = coupling @ solved[:, dofs].T  # C F C'
    locked = jac @ solved.T + np.diag(work.efc_R[:rows][touching]) - through  # H
    try:
        lower = np.linalg.cholesky(0.5 * (locked + locked.T))
    except np.linalg.LinAlgError:
        return free, 1.0
    scaled = np.linalg.solve(lower, coupling)  # L^-1 C F: D = scaled' scaled
    largest = float(np.linalg.eigvalsh(np.linalg.solve(lower, np.linalg.solve(lower, through).T)).max())
    if not largest > 0:
        return free, 1.0
    result: Matrix = free + (scaled.T @ scaled) * min(1.0, room / largest)
    left = (1.0 + largest) / (1.0 + min(largest, room))  # k: the inertia beyond the design, in its direction
    return result, min(1.0, 4.5 / left)
