"""MjcfRobot: any MuJoCo MJCF model in a world, attached through ``MjSpec`` under the entity's name.

The model is read by MuJoCo itself (:meth:`mujoco.MjSpec.from_file`: its ``<include>`` files, defaults
and compiler settings, angles in degrees or radians as the file says) and attached with
:meth:`mujoco.MjSpec.attach` under the prefix ``NAME/``: the joint ``elbow`` of the entity ``arm`` is
``arm/elbow``, its keyframe ``home`` is ``arm/home``, its default class ``main`` is ``arm/main``. Bodies,
joints, geoms, sites, cameras, lights, actuators, sensors, tendons, contact pairs and excludes,
equalities and keyframes all come along (MuJoCo's attach carries them); keyframes are widened to the whole
world, other entities' joints at their initial values, and follow the entity's pose: a keyframe's free-joint
and mocap poses are composed with it (:func:`place_keys`), so two robots of one model reset to its ``home``
(``World.reset("a/home")``) each land where their entity stands; a welded root is at the entity's pose anyway.

Files: the model, its ``<include>`` files, meshes, textures, height fields, skins and flexcomp files are read
by the project, not by MuJoCo (:mod:`simrun.robots.mjcf_read`, issue 42): found as MuJoCo would find them
(``compiler meshdir``, ``texturedir``, ``assetdir``), bounded, race-free and only inside the scene's folder, the
model's own folder and the folders ``allow_roots`` (or ``--allow-root DIR``) allows; counted and checked
against docs/limits.md before MuJoCo parses anything. MuJoCo gets one include-free document and the bytes
(:meth:`mujoco.MjSpec.from_string`), under names unique to the entity (MuJoCo caches meshes by file name);
the world's in-memory file system keeps them, so ``simrun export --mjcf`` writes them into its folder, and
every file read is recorded (``World.files_read``), so ``simrun test`` bundles them. MuJoCo's messages name
the file and line the element came from (an included file's own line).

Where the model goes: a model whose top-level bodies are welded to its world (an arm) is attached under
the entity's body at the entity's pose, so ``free``, ``kinematic`` and ``parent`` work as for any entity
(an arm on a mobile base). A model with free joints on top-level bodies (a walker, a loose object) or top-level mocap
bodies keeps them; MuJoCo allows those only on bodies of the world itself, so such a model is attached in the
world at the entity's pose (the entity must then be top level, neither ``free`` nor ``kinematic``), and
the entity's own body stays an empty marker there.

A model with no free joint of its own (dm_control's locomotion walkers: their Python adds the root joints
when it puts a walker into an arena) is welded where it is put unless given one of two roots:

- ``free = true`` (every entity's key): the entity's body gets a free joint ``NAME/free`` and the model
  hangs from it, as dm_control's ``Walker.create_root_joints`` adds a ``freejoint`` to the walker's
  attachment frame (``dm_control/locomotion/walkers/base.py``): the model falls, lands and can walk. The
  entity's body has no mass and MuJoCo refuses a moving body without mass, so one of the model's top-level
  bodies must have no joint of its own (the CMU humanoid's ``root``); the entity must be top level.
- ``root_slides = true``: three slide joints ``NAME/root_x``, ``NAME/root_y``, ``NAME/root_z`` along the
  axes of the entity's frame on the model's one top-level body, before its own joints, without limits,
  springs, damping or armature: the body translates but keeps its orientation (its own hinges still turn
  it). dm_control's ball walkers get exactly these (``create_root_joints`` of ``BoxHead``,
  ``dm_control/locomotion/soccer/boxhead.py``, and ``JumpingBall``, ``.../walkers/jumping_ball.py``:
  slides ``root_x``, ``root_y``, ``root_z`` of class ``root`` on the attachment frame); here they sit on the
  top-level body itself, which has the mass MuJoCo wants (same motion: a massless frame adds nothing).
  The model's keyframes get the slides at 0.

A world has one option set: the model's own ``<option>`` (timestep, integrator, solver, tolerances, fluid
density and viscosity...) is the world's where the scene did not set that option explicitly and no earlier
robot set it otherwise (the rule and its warnings: :mod:`simrun.world.options`); the model's ``<option>`` is
then replaced by the world's before the attach (MuJoCo's attach keeps the parent's anyway, with a printed
warning per difference), and its ``<size>`` is not carried over. Unnamed keyframes are named
``keyK`` (K: their index), so the attached ones are ``NAME/keyK``.

Wheels: naming two wheel joints (``wheels = ["left", "right"]``) gives them simrun's DC motors
``NAME/left_motor`` and ``NAME/right_motor`` (:class:`simrun.robots.wheels.DCMotor`, ``stall_torque`` and
``no_load_speed``), replacing the model's own actuators on those joints, so :class:`~simrun.services.drive_service
.DriveService` drives the model as it drives the built-in robots; the wheel radius (from the wheel's collision
geometry about its axis) and track are measured from the compiled model unless given
(:mod:`simrun.robots.wheels`).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import mujoco
import numpy as np

from simrun.errors import EntityError
from simrun.robots.contract import Robot
from simrun.robots.mjcf_limits import DEFAULT_LIMITS
from simrun.robots.mjcf_read import MjcfModel, MjcfReadError, allowed_roots, read_mjcf
from simrun.robots.wheels import WheelFields, Wheels, measure
from simrun.world.entity import BuildContext, Entity
from simrun.world.options import own_options

#: Largest MJCF file read, bytes (its includes and assets: :class:`simrun.robots.mjcf_limits.Limits`).
MAX_MJCF_BYTES = DEFAULT_LIMITS.xml_bytes
_LINE = re.compile(r"[Ll]ine(?: number)?[ =](\d+)")
_ELEMENT = re.compile(r"Element '([^']*)'|XMLElement name=(\w+)")
#: Size settings copied from the world into the model before attaching (the world's govern).
_SIZES = (
    "memory",
    "nconmax",
    "nemax",
    "njmax",
    "nkey",
    "nstack",
    "nuserdata",
    *(f"nuser_{k}" for k in ("actuator", "body", "cam", "geom", "jnt", "sensor", "site", "tendon")),
)
_NAMED = re.compile(r"Element name '([^']*)'")
_PARSE = re.compile(r"Error=(XML_ERROR_\w+)")


@dataclass(frozen=True, slots=True)
class WheelGeometry:
    """Wheels of an MJCF model as a drive sees them.

    Attributes:
        joints: Full names of the left and right wheel joints (``NAME/joint``).
        radius: Wheel radius, metres.
        track: Distance between the wheel centres along the wheel axis, metres.
        base: Full name of the body that carries the robot's free joint (the entity's body otherwise).
    """

    joints: tuple[str, str]
    radius: float
    track: float
    base: str


@dataclass(kw_only=True)
class MjcfRobot(WheelFields, Entity, Robot):
    """A robot (or any model) from an MJCF file.

    Attributes:
        file: Path of the MJCF ``.xml`` (relative to the world folder).
        wheels: Left and right wheel joints (names inside the model) for a drive; empty: none
            (:class:`~simrun.robots.wheels.WheelFields`: ``wheel_radius``, ``track``, ``stall_torque``,
            ``no_load_speed`` too).
        root_slides: Three slide joints on the model's top-level body (see the module); not with ``free``
            or ``kinematic``.
        allow_roots: Folders (relative to the world folder, or absolute) the model may read files from besides
            the scene's folder and its own (docs/scene-format.md); ``--allow-root DIR`` adds more.
    """

    TYPE: ClassVar[str] = "MjcfRobot"
    #: Sensors may mount on any of its bodies (``body = "NAME/link"``).
    BODY_MOUNTS: ClassVar[bool] = True

    file: str
    root_slides: bool = False
    allow_roots: tuple[str, ...] = ()

    # -- building ------------------------------------------------------------------------------------------

    def build(self, body: Any, ctx: BuildContext) -> None:
        """Read the model, move its files into memory and attach it under ``body`` (or at the pose in the world)."""
        path = ctx.base_dir / self.file
        tag = "".join(c if c.isalnum() else "_" for c in ctx.full_name)
        model, child = self._read(ctx.base_dir, f"mjcf_{tag}_")
        if self.wheels:
            self._add_motors(child)
        if self.root_slides:  # before any compile of the model: a compile ties its keyframes to its joints
            self._add_root_slides(child, path, model)
        elif self.free:
            self._check_free(child, path)
        _scale_total_mass(child, lambda: self._compiled(child, model))
        alone = self._compiled(child, model)  # MuJoCo must take the model alone first: its message names the element
        for k, key in enumerate(child.keys):
            if not key.name:  # attach names an unnamed key after the prefix alone: two would clash
                key.name = f"key{k}"
        _keep_flags(child)
        if not self.free:
            _massless_world_geoms(child)
        _take_settings(child, ctx.spec)
        world_only = [b.name or "(unnamed)" for b in child.worldbody.bodies if _world_only(b)]
        if world_only:
            if ctx.full_name != self.name or self.free or self.kinematic:
                raise EntityError(
                    f"MjcfRobot {self.name!r}: top-level bodies {', '.join(world_only)} have free joints or are "
                    "mocap bodies, which MuJoCo allows only on bodies of the world: make the entity top level, "
                    "not free, not kinematic"
                )
            pose = self.body_pose()
            place_keys(child, alone, pose.position, pose.orientation)
            frame = ctx.spec.worldbody.add_frame(pos=list(pose.position), quat=list(pose.orientation))
        else:
            frame = body.add_frame()
        try:
            ctx.spec.attach(child, prefix=f"{ctx.full_name}/", frame=frame)
        except ValueError as exc:
            raise self._fail(model, str(exc), "MuJoCo cannot attach it; rename the clashing element") from None
        ctx.assets.vfs.update(model.files)
        ctx.assets.sources.update(model.sources())

    def own_options(self, base_dir: Path) -> dict[str, Any]:
        """The options the model's ``<option>`` sets (those differing from MuJoCo's defaults), by ``MjSpec`` name.

        Args:
            base_dir: The world's folder (``file`` is relative to it).
        """
        return own_options(self._read(Path(base_dir), "options_", assets=False)[1])

    def _read(self, base_dir: Path, prefix: str, assets: bool = True) -> tuple[MjcfModel, mujoco.MjSpec]:
        """The model as :func:`~simrun.robots.mjcf_read.read_mjcf` reads it and MuJoCo parses it from the bytes.

        Args:
            base_dir: The world's folder (``file`` is relative to it; the scene's root).
            prefix: Start of the in-memory file names.
            assets: ``False``: the asset files are found and checked, not read (enough for the options).
        """
        path = base_dir / self.file
        try:
            st = path.stat()
        except OSError as exc:
            raise EntityError(
                f"MjcfRobot {self.name!r}: {path}: cannot read the MJCF file ({exc.strerror}); check 'file'"
            ) from None
        if not path.is_file():
            raise EntityError(f"MjcfRobot {self.name!r}: {path}: not a regular file; 'file' names an MJCF .xml")
        if st.st_size > MAX_MJCF_BYTES:
            raise EntityError(f"MjcfRobot {self.name!r}: {path}: {st.st_size} bytes, over {MAX_MJCF_BYTES}")
        try:
            model = read_mjcf(path, allowed_roots(base_dir, self.allow_roots), prefix, assets=assets)
        except MjcfReadError as exc:
            raise EntityError(f"MjcfRobot {self.name!r}: {exc}") from None
        try:
            return model, model.spec()
        except ValueError as exc:
            raise self._fail(model, str(exc), "fix that element (MuJoCo's XML reader refused it)") from None

    def _compiled(self, child: mujoco.MjSpec, model: MjcfModel) -> mujoco.MjModel:
        try:
            return child.compile()
        except ValueError as exc:
            raise self._fail(model, str(exc), "fix that element (MuJoCo refuses the model)") from None

    def _fail(self, model: MjcfModel, message: str, hint: str) -> EntityError:
        """A one-line error from MuJoCo's message: file, line and element first, then MuJoCo's words, then the hint.

        MuJoCo's line is one of the document the reader handed it; the message names the file and line the
        element came from instead (the model's or an included file's).
        """
        lines = [part.strip() for part in message.strip().splitlines() if part.strip()]
        text = " ".join(lines)
        line = _LINE.search(text)
        element, named, parse = _ELEMENT.search(text), _NAMED.search(text), _PARSE.search(text)
        origin = model.origin(int(line.group(1))) if line else None
        where = f"{origin[0]}:{origin[1]}" if origin is not None else str(model.path)
        first = parse.group(1) if parse else lines[0] if lines else "unreadable"
        for prefix in ("XML Error: ", "Error: "):
            first = first.removeprefix(prefix)
        what = ""
        if element:
            what = f" <{element.group(1) or element.group(2)}>:"
        elif named:
            what = f" element named {named.group(1)!r}:"
        return EntityError(f"MjcfRobot {self.name!r}: {where}:{what} {first}; {hint}")

    def _add_root_slides(self, child: mujoco.MjSpec, path: Path, model: MjcfModel) -> None:
        """Slides ``root_x``, ``root_y``, ``root_z`` (the entity frame's axes) first on the one top-level body."""
        who = f"MjcfRobot {self.name!r}"
        if self.free or self.kinematic:
            raise EntityError(f"{who}: root_slides moves the model's root; it cannot also be free or kinematic")
        tops = list(child.worldbody.bodies)
        if len(tops) != 1 or _world_only(tops[0]):
            found = ", ".join(b.name or "(unnamed)" for b in tops) or "none"
            raise EntityError(
                f"{who}: root_slides needs one top-level body without a free joint, not mocap, in {path} "
                f"(top-level bodies: {found}); drop root_slides"
            )
        top = tops[0]
        rotation = np.zeros(9)
        mujoco.mju_quat2Mat(rotation, self._compiled(child.copy(), model).body_quat[1])  # its frame in the entity's
        names = {j.name for j in child.joints}
        clash = sorted(n for n in ("root_x", "root_y", "root_z") if n in names)
        if clash:
            raise EntityError(f"{who}: root_slides adds {', '.join(clash)}, already a joint of {path}")
        own = [(_joint_fields(j), j.frame) for j in top.joints]
        for joint in list(top.joints):
            child.delete(joint)
        blank = _joint_fields(mujoco.MjSpec().worldbody.add_body().add_joint())  # MuJoCo's defaults, not the model's
        for k, axis in enumerate(rotation.reshape(3, 3)):  # row k of R = R^T e_k: entity axis k in the body's
            slide = top.add_joint()
            for key, value in blank.items():
                setattr(slide, key, value)
            slide.name, slide.type, slide.axis = f"root_{'xyz'[k]}", mujoco.mjtJoint.mjJNT_SLIDE, list(axis)
            slide.limited = slide.actfrclimited = mujoco.mjtLimited.mjLIMITED_FALSE
        for fields, frame in own:
            joint = top.add_joint()
            for key, value in fields.items():
                setattr(joint, key, value)
            if frame is not None:
                joint.set_frame(frame)
        for key in child.keys:  # the top-level body's joints come first in qpos and qvel
            if len(key.qpos):
                key.qpos = [0.0, 0.0, 0.0, *key.qpos]
            if len(key.qvel):
                key.qvel = [0.0, 0.0, 0.0, *key.qvel]

    def _check_free(self, child: mujoco.MjSpec, path: Path) -> None:
        """Refuse ``free`` where every top-level body has joints of its own: nothing with mass under the free joint."""
        tops = list(child.worldbody.bodies)
        if not tops or any(_world_only(b) for b in tops) or any(not list(b.joints) for b in tops):
            return
        jointed = ", ".join(
            f"{b.name or '(unnamed)'} ({', '.join(j.name or 'unnamed' for j in b.joints)})" for b in tops
        )
        raise EntityError(
            f"MjcfRobot {self.name!r}: free = true hangs {path} from a free joint on the entity's body, which "
            f"has no mass, and every top-level body has joints of its own: {jointed}; MuJoCo refuses a moving "
            "body without mass: use root_slides = true (translation only, as dm_control's ball walkers)"
        )

    def _add_motors(self, child: mujoco.MjSpec) -> None:
        self.add_wheel_motors(child, f"MjcfRobot {self.name!r}", self.file)

    # -- wheels (DriveService) -----------------------------------------------------------------------------

    def driven_wheels(self, full_name: str, model: mujoco.MjModel, base: str) -> Wheels | None:
        """The named wheels in the world's model (:meth:`~simrun.robots.wheels.WheelFields.named_wheels`)."""
        return self.named_wheels(full_name, model, base)

    def wheel_geometry(self, base_dir: Path) -> WheelGeometry:
        """Wheel joints, radius and track (measured from the model compiled alone where not given).

        Args:
            base_dir: The world's folder (``file`` is relative to it).
        """
        model, child = self._read(Path(base_dir), "wheels_")
        self._add_motors(child)
        return wheel_geometry(self, self._compiled(child, model))


def wheel_geometry(entity: Any, model: mujoco.MjModel) -> WheelGeometry:
    """The wheels of ``entity`` (:class:`~simrun.robots.wheels.WheelFields`) in its model compiled alone."""
    radius, track = measure(model, entity.wheels[0], entity.wheels[1])
    root = int(model.body_rootid[model.jnt_bodyid[model.joint(entity.wheels[0]).id]])
    jnt = int(model.body_jntadr[root])
    free = jnt >= 0 and int(model.jnt_type[jnt]) == int(mujoco.mjtJoint.mjJNT_FREE)
    return WheelGeometry(
        (f"{entity.name}/{entity.wheels[0]}", f"{entity.name}/{entity.wheels[1]}"),
        entity.wheel_radius if entity.wheel_radius is not None else radius,
        entity.track if entity.track is not None else track,
        f"{entity.name}/{model.body(root).name}" if free else entity.name,
    )


def place_keys(child: mujoco.MjSpec, alone: mujoco.MjModel, position: Any, orientation: Any) -> None:
    """Put the keyframes of a model attached in the world at a pose where the entity is (issue 37).

    A keyframe's free-joint positions and quaternions (``qpos``) and mocap poses (``mpos``, ``mquat``) are
    in the model's own world frame; attached at the entity's pose they are composed with it: position
    ``p + R(q) k_p``, orientation ``q * k_q`` (``position``: ``p``, m, in the world; ``orientation``: ``q``,
    ``w x y z``). Hinges and slides are relative to their bodies and stay; a key without ``qpos`` takes the
    attached model's ``qpos0``, already at the pose. ``alone``: the model compiled alone (its ``qpos`` layout).
    """
    p, q = np.asarray(position, dtype=float), np.asarray(orientation, dtype=float)
    flat = np.zeros(9)
    mujoco.mju_quat2Mat(flat, q)
    rotation = flat.reshape(3, 3)
    free = int(mujoco.mjtJoint.mjJNT_FREE)
    starts = [int(alone.jnt_qposadr[j]) for j in range(alone.njnt) if int(alone.jnt_type[j]) == free]

    def placed(at: np.ndarray[Any, np.dtype[np.float64]], turn: np.ndarray[Any, np.dtype[np.float64]]) -> list[float]:
        out = np.zeros(4)
        mujoco.mju_mulQuat(out, q, turn)
        return [*(p + rotation @ at), *out]

    for key in child.keys:
        qpos = np.array(key.qpos, dtype=float)
        if qpos.size >= alone.nq:
            for a in starts:
                qpos[a : a + 7] = placed(qpos[a : a + 3], qpos[a + 3 : a + 7])
            key.qpos = qpos.tolist()
        mpos, mquat = np.array(key.mpos, dtype=float), np.array(key.mquat, dtype=float)
        if mpos.size and mpos.size == 3 * (mquat.size // 4):
            for m in range(mpos.size // 3):
                pose = placed(mpos[3 * m : 3 * m + 3], mquat[4 * m : 4 * m + 4])
                mpos[3 * m : 3 * m + 3], mquat[4 * m : 4 * m + 4] = pose[:3], pose[3:]
            key.mpos, key.mquat = mpos.tolist(), mquat.tolist()


def _scale_total_mass(child: mujoco.MjSpec, compile_alone: Any) -> None:
    """Apply ``<compiler settotalmass>`` by scaling the model's masses and densities.

    MuJoCo's own advice: the attribute is deprecated and makes every compile print a warning. The masses come
    out as MuJoCo's rule makes them (tests/test_mjcf_robot.py compares).
    """
    total = float(child.compiler.settotalmass)
    if total <= 0:
        return
    child.compiler.settotalmass = -1.0
    model = compile_alone()
    scale = total / float(model.body_mass.sum())
    for body in child.bodies:
        if body.explicitinertial:
            body.mass *= scale
            body.inertia = [v * scale for v in body.inertia]
            body.fullinertia = [v * scale for v in body.fullinertia]
    for geom in child.geoms:
        if math.isfinite(geom.mass):
            geom.mass *= scale
        geom.density *= scale


def _massless_world_geoms(child: mujoco.MjSpec) -> None:
    """Give the model's world geoms (a floor, a table it stands on) no mass, as MuJoCo gives the world body none.

    Attached under the entity's body they would otherwise count as its mass (a 4 x 4 x 0.1 m slab: 1.6 t on a
    body the model says is the world; every export's static body carried it). A free entity keeps them as
    they are: its body must have a mass to move.
    """
    for geom in child.worldbody.geoms:
        geom.mass = 0.0


def _keep_flags(child: mujoco.MjSpec) -> None:
    """Keep what the model's contact and gravity switches meant, for its own bodies, in the world's options.

    ``<flag contact="disable"/>``: its geoms collide with nothing (``contype = conaffinity = 0``, its contact
    pairs dropped). ``<flag gravity="disable"/>`` or ``gravity="0 0 0"``: its bodies carry their own weight
    (``gravcomp = 1``, MuJoCo's gravity compensation). Other switches are the world's.
    """
    flags = int(child.option.disableflags)
    if flags & int(mujoco.mjtDisableBit.mjDSBL_CONTACT):
        for geom in child.geoms:
            geom.contype = geom.conaffinity = 0
        for pair in list(child.pairs):
            child.delete(pair)
    if flags & int(mujoco.mjtDisableBit.mjDSBL_GRAVITY) or not np.any(child.option.gravity):
        for body in child.bodies:
            if body.name != "world":
                body.gravcomp = 1.0


def _take_settings(child: mujoco.MjSpec, world: mujoco.MjSpec) -> None:
    """The world's options, sizes, statistics and visual settings into the model.

    MuJoCo's attach keeps the parent's anyway, and prints a warning of every difference on the console.
    """
    pairs = [(child.option, world.option), (child.stat, world.stat)]
    pairs += [
        (getattr(child.visual, g), getattr(world.visual, g))
        for g in ("global_", "headlight", "map", "quality", "rgba", "scale")
    ]
    for mine, theirs in pairs:
        for name in dir(theirs):
            if not name.startswith("_") and not callable(getattr(theirs, name)):
                setattr(mine, name, getattr(theirs, name))
    for name in _SIZES:
        setattr(child, name, getattr(world, name))


def _world_only(body: Any) -> bool:
    """Whether a top-level body must stay a child of the world: a free joint, or a mocap body."""
    return bool(body.mocap) or any(int(j.type) == int(mujoco.mjtJoint.mjJNT_FREE) for j in body.joints)


#: Joint settings that are not values (identity, place in the tree, the frame set through ``set_frame``).
_NOT_COPIED = {"id", "parent", "frame", "signature", "compiler", "classname", "set_frame"}


def _joint_fields(joint: Any) -> dict[str, Any]:
    """Every setting of a spec joint, to add it again (MuJoCo's spec has no way to move a joint in its body)."""
    return {
        name: getattr(joint, name)
        for name in dir(joint)
        if not name.startswith("_") and name not in _NOT_COPIED and not callable(getattr(joint, name))
    }
