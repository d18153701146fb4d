"""The inertia a JointService's force loops see: the joints' own, every other dof free, and their contacts'.

:func:`free_inertia` is ``S`` of :mod:`simrun.services.joint_service` (the Schur complement of MuJoCo's mass
matrix over the dofs the loops do not command), :func:`with_contacts` what the contacts of the current pose
add to it (issue 37). Shapes: dof counts of the model (``nv``) and of the commanded force joints.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import mujoco
import numpy as np

#: A float matrix or vector.
Matrix = np.ndarray[Any, np.dtype[np.float64]]
#: MuJoCo's first contact constraint type: the types from it on (frictionless, pyramidal, elliptic, the last
#: three of ``mjtConstraint``) are contacts'.
_FIRST_CONTACT = int(mujoco.mjtConstraint.mjCNSTR_CONTACT_FRICTIONLESS)


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
    whitening: Matrix,
    bandwidth: float,
    period: float,
    movers: np.ndarray[Any, np.dtype[np.bool_]] | None = None,
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
    entity (or ``H`` not positive definite): ``(free, 1.0)``.

    ``whitening``: :func:`whiten` of ``free``; ``movers``: per body, whether it moves a dof of ``tree`` (a
    world whose contacts are all elsewhere is skipped after the collision). Cost (issue 41): two LAPACK calls
    (``D`` by one solve with ``H``, and the eigenvalue only when the cap binds, of ``W D W'``, k x k); whether
    ``H`` and ``room F - D`` are positive definite is MuJoCo's Cholesky (``mju_cholFactor``).
    """
    hold = max(period, float(model.opt.timestep))
    room = 1.0 / (3.0 * bandwidth * hold) - 1.0
    if room <= 0 or work is None or not tree.size:
        return free, 1.0
    mujoco.mj_collision(model, work)
    ncon = int(work.ncon)
    if not ncon:
        return free, 1.0
    nv = model.nv
    whole = tree.size == nv  # the entity moves every dof: every contact row that moves anything is its
    if not whole and movers is not None and not movers[model.geom_bodyid[work.contact.geom[:ncon]]].any():
        return free, 1.0  # no contact on a body that moves a dof of the entity: no row of it can move one
    mujoco.mj_makeConstraint(model, work)
    rows = int(work.nefc)
    if not rows:  # contacts that make no constraint rows (disabled, or beyond their margins)
        return free, 1.0
    if mujoco.mj_isSparse(model):
        jac = np.zeros((rows, nv))
        mujoco.mju_sparse2dense(jac, work.efc_J, work.efc_J_rownnz, work.efc_J_rowadr, work.efc_J_colind)
    else:
        jac = work.efc_J[: rows * nv].reshape(rows, nv)  # a view: read only here
    moving = jac != 0
    touching = (work.efc_type[:rows] >= _FIRST_CONTACT) & (moving if whole else moving[:, tree]).any(axis=1)
    if touching.all():
        regulariser = work.efc_R[:rows]
    elif touching.any():
        jac, regulariser = np.ascontiguousarray(jac[touching]), work.efc_R[:rows][touching]
    else:
        return free, 1.0
    mujoco.mj_crb(model, work)
    mujoco.mj_factorM(model, work)
    solved = np.empty_like(jac)
    mujoco.mj_solveM(model, work, solved, jac)  # rows: M^-1 j
    columns = solved[:, dofs]
    coupling = columns @ free  # C F
    locked = jac @ solved.T + np.diag(regulariser) - coupling @ columns.T  # H = G - C F C'
    locked = 0.5 * (locked + locked.T)
    if not _definite(locked.copy()):
        return free, 1.0
    try:
        added = coupling.T @ np.linalg.solve(locked, coupling)  # D = F C' H^-1 C F
    except np.linalg.LinAlgError:
        return free, 1.0
    added = 0.5 * (added + added.T)
    if _definite(room * free - added):  # its largest eigenvalue relative to F is below the cap: D whole
        return free + added, 1.0
    largest = float(np.linalg.eigvalsh(whitening @ added @ whitening.T).max())  # that of F^-1 D
    if not largest > 0:
        return free, 1.0
    result: Matrix = free + added * min(1.0, room / largest)
    left = (1.0 + largest) / (1.0 + min(largest, room))  # k: the inertia beyond the design, in its direction
    return result, min(1.0, 4.5 / left)


def whiten(free: Matrix) -> Matrix:
    """``W = L^-1`` of ``free = L L'`` (Cholesky): ``W D W'`` has the eigenvalues of ``D`` relative to ``free``.

    ``free``: ``F`` (k x k, symmetric positive definite), the result k x k.
    """
    lower = np.linalg.cholesky(0.5 * (free + free.T))
    found: Matrix = np.linalg.inv(lower)
    return found


#: Smallest pivot a Cholesky factor may have for its matrix to count as positive definite.
_PIVOT = 1e-15


def _definite(matrix: Matrix) -> bool:
    """Whether the symmetric ``matrix`` is positive definite.

    MuJoCo's Cholesky of it (in place) has full rank (every pivot at least :data:`_PIVOT`) and is finite
    (``matrix`` is 1 x 1 or larger).
    """
    full = mujoco.mju_cholFactor(matrix, _PIVOT) == matrix.shape[0]
    return bool(full) and math.isfinite(matrix[-1, -1])  # a NaN or inf anywhere reaches the last pivot
