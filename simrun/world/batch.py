"""Building a world of many entities without MuJoCo's walk of the whole tree at every addition (issue 41).

MuJoCo's spec recomputes its lists of tree elements (every body, geom, joint, site, camera, light and frame)
and its signature at every addition (``mjs_addBody``, ``mjs_addGeom``...: ``ResetTreeLists``,
``MakeTreeLists``), so the k-th addition costs O(k) and a spec of N entities O(N^2) (about 60 us per body
added to a spec of 10,000; MuJoCo's own MJCF parser adds its elements the same way). :class:`TreeBuilder`
builds the entities that touch nothing but their own body (and the shared asset library) into small
child specs of :data:`BATCH` entities, where an addition walks at most that many, and attaches them to the
world's spec (``MjSpec.attach`` to a frame, which moves the elements: no copy), their elements unnamed
while they are attached (an attachment checks every name of the spec attached to) and named again after.

The model compiled from such a spec is the one the entities built one by one give, byte for byte: an
attached body lies in an identity frame, which MuJoCo composes with its pose exactly, except for the sign
of a zero (``-0.0`` becomes ``0.0``), so an entity whose pose holds a negative zero is built directly. The
spec handed on is the world's spec copied once (``MjSpec.copy``), which forgets the attachments: the
copy compiles and writes its XML without MuJoCo's warning about attaching with an empty prefix (names
are kept as the entities gave them; simrun's full names are unique already).
"""

from __future__ import annotations

import math
import threading
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any

import mujoco

if TYPE_CHECKING:
    from simrun.world.entity import Entity
    from simrun.world.pose import Pose

#: Entities per child spec; a world of more entities than this is built in batches.
BATCH = 128
#: Most batches merged into one child spec before it is attached to the world's spec.
MERGE = 8
#: The warning MuJoCo gives (through ``mju_warning``) at every attachment with an empty prefix.
EMPTY_PREFIX = "Attaching a spec with an empty prefix"

_batchable: dict[type, bool] = {}


def batchable(cls: type[Entity]) -> bool:
    """Whether entities of ``cls`` may be built in a child spec.

    ``BATCHABLE`` set by the class that defines the ``build`` it runs: a subclass overriding ``build`` is
    built directly unless it says so too.
    """
    known = _batchable.get(cls)
    if known is None:
        owner = next(c for c in cls.__mro__ if "build" in vars(c))
        known = _batchable[cls] = bool(vars(owner).get("BATCHABLE", False)) and bool(cls.HAS_BODY)
    return known


def _negative_zero(values: tuple[float, ...]) -> bool:
    return -1.0 in [math.copysign(1.0, v) for v in values if v == 0.0]


class TreeBuilder:
    """Where each entity's body goes while a spec is built, batching what can be batched.

    Args:
        spec: The world's spec (assets, options and every entity that is not batched go straight into it).
        batched: Build batchable entities in child specs (a world of more than :data:`BATCH` entities);
            ``False``: every entity straight into ``spec``, as one by one.
    """

    def __init__(self, spec: mujoco.MjSpec, batched: bool) -> None:
        self.spec, self.batched = spec, batched
        self._child: mujoco.MjSpec | None = None
        self._members: set[str] = set()  # full names of the bodies in the child spec being filled
        self._stack: list[tuple[mujoco.MjSpec, int]] = []  # filled child specs, with their batch counts
        self._names: list[tuple[Any, str]] = []  # the elements of filled child specs and their names
        self._attached = False
        self._bodies = 0  # bodies of batchable entities (one each: their builds add none)
        self._others = False  # an entity that may add bodies of its own was built

    def parent(self, full: str, entity: Entity, pose: Pose | None, bodies: dict[str, Any]) -> Any:
        """The body to add ``entity``'s body (at ``pose``) to, or ``None`` for a body-less entity.

        ``bodies`` maps the full names of the bodies built so far to their MjSpec bodies; every body stays
        valid when its child spec is attached (MuJoCo moves the elements).
        """
        parent = entity.parent
        fits = batchable(type(entity))
        if fits:
            self._bodies += 1
        else:
            self._others = True
        if self.batched and fits and pose is not None:
            if parent is not None:  # with its parent: in the child spec being filled, or in the spec
                if parent in self._members:
                    self._members.add(full)
                return bodies[parent]  # (a child adds nothing to the order of top-level bodies)
            if not _negative_zero(pose.position + pose.orientation):
                if self._child is None or len(self._members) >= BATCH:
                    self._seal()
                    self._child = _child_of(self.spec)
                self._members.add(full)
                return self._child.worldbody
        self.flush()  # everything before it attached first: the world's bodies stay in entity order
        if not entity.HAS_BODY:
            return None
        return bodies[parent] if parent else self.spec.worldbody

    def _seal(self) -> None:
        """Put the child spec being filled on the stack of filled ones, merging equal ones (see :meth:`flush`)."""
        child, self._child = self._child, None
        self._members = set()
        if child is None:
            return
        names = self._names
        for elements in (child.bodies[1:], child.geoms, child.joints, child.sites, child.cameras, child.lights):
            for element in elements:
                name = element.name
                if name:
                    names.append((element, name))
                    element.name = ""
        stack, size = self._stack, 1
        with _quiet_attach():
            while stack and stack[-1][1] == size and size < MERGE:  # a binary counter, up to MERGE batches
                into, _ = stack.pop()
                into.attach(child, frame=into.worldbody.add_frame(), prefix="")
                child, size = into, 2 * size
        stack.append((child, size))

    def flush(self) -> None:
        """Attach every filled child spec to the world's spec, in entity order, and name their elements again.

        MuJoCo's attachment checks the name of every named element of the spec attached to (about 1.3 us
        each) and moves the elements of the attached spec in a time that grows with the square of their
        number: the elements of a filled child spec are unnamed while it is attached (their names are set
        again here, once every spec is in place), and child specs are merged pairwise up to :data:`MERGE`
        batches before they are attached.
        """
        self._seal()
        if not self._stack:
            return
        stack, self._stack = self._stack, []
        with _quiet_attach():
            for child, _ in stack:
                self.spec.attach(child, frame=self.spec.worldbody.add_frame(), prefix="")
        for element, name in self._names:
            element.name = name
        self._names = []
        self._attached = True

    def finish(self) -> tuple[mujoco.MjSpec, int]:
        """The built spec and its number of bodies, the world body included.

        The spec is the world's, or its copy when child specs were attached to it. The bodies are counted
        where every entity was batchable (one body each); else ``len(spec.bodies)``, which makes a Python
        object per body (25 us each in a spec of 10,000).
        """
        self.flush()
        spec = self.spec.copy() if self._attached else self.spec
        return spec, len(spec.bodies) if self._others else 1 + self._bodies


def _child_of(spec: mujoco.MjSpec) -> mujoco.MjSpec:
    """An empty spec whose compiler settings are the world's (its elements keep them once attached)."""
    child = mujoco.MjSpec()
    child.compiler.degree = spec.compiler.degree
    return child


_lock = threading.Lock()
_depth = 0
_previous: Callable[[str], None] | None = None


def _forward(message: str) -> None:
    if message.startswith(EMPTY_PREFIX):
        return
    if _previous is not None:
        _previous(message)
    else:
        warnings.warn(f"MuJoCo: {message.strip()}", RuntimeWarning, stacklevel=2)


@contextmanager
def _quiet_attach() -> Iterator[None]:
    """Within the block, MuJoCo's warning about an empty prefix is dropped.

    MuJoCo would print it and write it to ``MUJOCO_LOG.TXT``. Any other warning goes on to the handler that
    was installed. One handler for all threads building at once.
    """
    global _depth, _previous
    with _lock:
        if _depth == 0:
            _previous = mujoco.get_mju_user_warning()
            mujoco.set_mju_user_warning(_forward)
        _depth += 1
    try:
        yield
    finally:
        with _lock:
            _depth -= 1
            if _depth == 0:
                mujoco.set_mju_user_warning(_previous)
                _previous = None
