"""Warnings about a world at its initial state, for ``simrun check`` and the library alike (issue 37).

:func:`scene_warnings` returns them as lines, in a fixed order: option overrides first
(:meth:`World.option_choice <simrun.world.world.World.option_choice>`), then initial penetrations, then
ground contacts that hold a fixed robot, each group sorted by geom names. They are warnings, not errors: the
scene still runs. Measured on a fresh ``MjData`` at the initial state (``qpos0``, after ``mj_forward``), so
the result does not depend on how far the world has run.

- **Initial penetration**: two geoms in contact more than :data:`PENETRATION` (5 mm) inside each other at
  the start (MuJoCo's contact distance ``dist < -PENETRATION``; pairs MuJoCo filters, a body and its
  parent among them, are never in contact). MuJoCo pushes such geoms apart at the first steps, a kick the
  model did not mean (dm_control's ``ant.xml`` welded where it is put starts with 8 self-contacts up to
  16 cm deep). One line per pair of geoms, its deepest contact.
- **Ground that holds a fixed robot**: a geom on a jointed body of a robot whose root cannot translate
  (its topmost jointed body has no free joint and no slide: an arm on a fixed base) touching simrun's
  ground (a ``Ground`` or ``HeightField``) at the start, touching or inside (MuJoCo's contact distance
  ``dist <= TOUCH``, 0; contacts MuJoCo excludes through ``gap`` are not counted): its joints then push
  against the ground's friction (a planar arm such as dm_control's ``reacher`` lying on the floor never
  reaches its target). A walker's feet on the floor are no warning: its root is free.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import mujoco

if TYPE_CHECKING:
    from simrun.world.world import World

#: Depth (m) beyond which two geoms in contact at the start are reported as an initial penetration.
PENETRATION = 0.005
#: Depth (m) from which a fixed robot's jointed geom counts as touching the ground (0: resting on it).
TOUCH = 0.0
#: Entity types that are simrun's ground.
GROUNDS = ("Ground", "HeightField")


def scene_warnings(world: World) -> list[str]:
    """Every warning about ``world`` at its initial state (see the module), one line each, in a fixed order."""
    model = world.model
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    ground_names = [full for full, entity in world if entity.TYPE in GROUNDS]
    lines = list(world.option_choice()[1])
    deep: dict[tuple[str, str], float] = {}
    held: dict[tuple[str, str], float] = {}
    for c in data.contact[: data.ncon]:
        if c.exclude:  # in the margin's gap: MuJoCo applies no force
            continue
        g1, g2 = int(c.geom1), int(c.geom2)
        names = sorted((_geom_name(model, g1), _geom_name(model, g2)))
        pair = (names[0], names[1])
        dist = float(c.dist)
        if dist < -PENETRATION:
            deep[pair] = min(dist, deep.get(pair, 0.0))
        grounded = [g for g in (g1, g2) if _owner(model, g, ground_names)]
        if len(grounded) == 1 and dist <= TOUCH:
            other = g2 if grounded[0] == g1 else g1
            if _held_by_ground(model, other):
                held[pair] = min(dist, held.get(pair, 0.0))
    for (a, b), dist in sorted(deep.items()):
        lines.append(
            f"initial penetration: geoms {a!r} and {b!r} start {-dist * 100:.1f} cm inside each other "
            f"(over {PENETRATION * 1000:g} mm); MuJoCo pushes them apart at the first steps"
        )
    for (a, b), dist in sorted(held.items()):
        lines.append(
            f"ground holds a fixed robot: geoms {a!r} and {b!r} touch ({-dist * 1000:.1f} mm inside) at the start; "
            "the ground's friction acts against its joints: raise the robot or remove the ground"
        )
    return lines


def _geom_name(model: mujoco.MjModel, g: int) -> str:
    return model.geom(g).name or f"geom {g} (unnamed, body {model.body(int(model.geom_bodyid[g])).name!r})"


def _owner(model: mujoco.MjModel, g: int, entities: list[str]) -> bool:
    """Whether geom ``g`` belongs to one of the ``entities`` (by full name: ``NAME/...`` or its body)."""
    name = model.geom(g).name
    body = model.body(int(model.geom_bodyid[g])).name
    return any(n in (name, body) or name.startswith(n + "/") or body.startswith(n + "/") for n in entities)


def _held_by_ground(model: mujoco.MjModel, g: int) -> bool:
    """Whether geom ``g`` is on a body moved by joints of a robot whose root cannot translate.

    The root is the topmost body with joints on the way from ``g``'s body to the world: a free joint or a
    slide there (a walker, ``root_slides``, a planar walker's ``rootx``) lets the robot move on the ground.
    """
    body = int(model.geom_bodyid[g])
    if int(model.body_weldid[body]) == 0:  # welded to the world: no joint to hold
        return False
    chain = []
    while body > 0:
        chain.append(body)
        body = int(model.body_parentid[body])
    root = next(b for b in reversed(chain) if int(model.body_jntnum[b]) > 0)
    first = int(model.body_jntadr[root])
    moving = (int(mujoco.mjtJoint.mjJNT_FREE), int(mujoco.mjtJoint.mjJNT_SLIDE))
    return not any(int(model.jnt_type[j]) in moving for j in range(first, first + int(model.body_jntnum[root])))
