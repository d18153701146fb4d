"""The World: one MjSpec built from named entities, compiled lazily, stepped and reset.

Entities are kept in insertion order; the spec is rebuilt from them whenever they change, so removing an
entity is exact and the same entities always give the same model. A rebuilt world starts again at time 0 from
the initial poses; controllers keep their settings, and their clocks restart so each ticks at the first step.
Names: a top-level entity ``box`` owns the body ``box`` and elements ``box/...``; a child ``wheel`` of
``robot`` is ``robot/wheel``.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from simrun.entities.environment import Camera
from simrun.errors import CompileError, EntityError, Origin, SimrunError
from simrun.world import model_cache
from simrun.world import options as model_options
from simrun.world.assets import AssetLibrary
from simrun.world.batch import BATCH, TreeBuilder
from simrun.world.entity import BuildContext, Entity
from simrun.world.registry import Controller, arguments, python_fail, scene_type, service_arguments

INTEGRATORS = {
    "euler": mujoco.mjtIntegrator.mjINT_EULER,
    "rk4": mujoco.mjtIntegrator.mjINT_RK4,
    "implicit": mujoco.mjtIntegrator.mjINT_IMPLICIT,
    "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
}
_NAME = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.-]*$")
#: Shortest and longest physics timestep accepted, seconds.
MIN_TIMESTEP, MAX_TIMESTEP = 1e-5, 0.1
#: Most bodies a world may have (entities with a body, robot links included); bounds the work of one scene.
MAX_BODIES = 10_000


_mj_step = mujoco.mj_step  # bound once: World.step's single-step path is timed against raw mj_step


#: The world's defaults of the options :class:`WorldOptions` holds.
DEFAULT_TIMESTEP, DEFAULT_GRAVITY, DEFAULT_INTEGRATOR = 0.002, (0.0, 0.0, -9.81), "implicitfast"


class _NotGiven(float):
    """The default of :attr:`WorldOptions.timestep`: a float (the field keeps its type) that means "not given"."""


#: Told apart by identity, so a NaN passed on purpose is refused, not taken for "not given".
_NOT_GIVEN = _NotGiven("nan")


@dataclass(frozen=True, slots=True)
class WorldOptions:
    """Physics options.

    A ``timestep`` or ``integrator`` given here (or in a scene's ``[world]``) is *explicit*: it governs over
    a robot's own ``<option>``; one left out is simrun's default (2 ms, ``implicitfast``) unless a robot's
    model sets it (:mod:`simrun.world.options`).

    Attributes:
        timestep: Seconds per step.
        gravity: m/s^2.
        integrator: ``euler``, ``rk4``, ``implicit`` or ``implicitfast``.
        explicit: The names among ``timestep`` and ``integrator`` that were given (set from the arguments).
    """

    timestep: float = _NOT_GIVEN  # _NOT_GIVEN, "": not given (the defaults above)
    gravity: tuple[float, float, float] = DEFAULT_GRAVITY
    integrator: str = ""
    explicit: frozenset[str] = field(default=frozenset(), init=False)

    def __post_init__(self) -> None:
        given = frozenset(
            n
            for n, unset in (("timestep", self.timestep is _NOT_GIVEN), ("integrator", not self.integrator))
            if not unset
        )
        object.__setattr__(self, "explicit", given)
        if "timestep" not in given:
            object.__setattr__(self, "timestep", DEFAULT_TIMESTEP)
        if "integrator" not in given:
            object.__setattr__(self, "integrator", DEFAULT_INTEGRATOR)
        if not MIN_TIMESTEP <= self.timestep <= MAX_TIMESTEP:  # NaN given on purpose fails here too
            raise EntityError(f"timestep must be in [{MIN_TIMESTEP:g}, {MAX_TIMESTEP:g}] seconds, got {self.timestep}")
        if self.integrator not in INTEGRATORS:
            raise EntityError(f"integrator must be one of {', '.join(INTEGRATORS)}")
        if len(self.gravity) != 3 or not all(math.isfinite(g) for g in self.gravity):
            raise EntityError("gravity needs 3 finite numbers")


#: MuJoCo's arena when the model does not size it (``<size memory>`` automatic: 14 MiB for simrun's worlds).
ARENA_DEFAULT = 14 * 1024 * 1024


def arena_bytes(nbody: int) -> int | None:
    """The arena (``<size memory>``, bytes) a world of ``nbody`` bodies (the world body included) needs.

    MuJoCo's collision broadphase takes one int per pair of bodies from the arena (``mj_collision``: about
    ``2 nbody^2`` bytes; 18 MB for 3,001 bodies, which the automatic 14 MiB arena refuses with
    ``mj_stackAlloc: out of memory``), and the same again for its sorting. ``None`` (MuJoCo's automatic size)
    while that fits in half the automatic arena; else the automatic arena plus ``4 nbody^2``.
    """
    pairs = 4 * nbody * nbody
    return None if pairs <= ARENA_DEFAULT // 2 else ARENA_DEFAULT + pairs


class World:
    """A simulation world of named entities.

    Args:
        options: Physics options.
        base_dir: Folder that relative asset and texture paths are resolved against.
    """

    def __init__(self, options: WorldOptions | None = None, base_dir: Path | str = ".") -> None:
        self.options = options or WorldOptions()
        self.base_dir = Path(base_dir)
        self._entities: dict[str, Entity] = {}
        self._spec: mujoco.MjSpec | None = None
        self._model: mujoco.MjModel | None = None
        self._data: mujoco.MjData | None = None
        self._assets = AssetLibrary(mujoco.MjSpec())
        self._hooked: list[Entity] = []
        self._sched_list: list[Controller] = []  # single-step fast path (step/reschedule)
        self._sched_time = math.nan
        self._sched_half = self._sched_dt = 0.0
        self._sched_until = -math.inf
        #: MuJoCo's automatic resets of an unstable simulation so far, and the time of the last (see :meth:`step`).
        self.mujoco_resets, self.last_reset = 0, math.nan
        #: Compiled-model cache (simrun/world/model_cache.py; ``SIMRUN_MODEL_CACHE``); ``None`` compiles every time.
        self.model_cache: model_cache.ModelCache | None = model_cache.default()
        self.services: list[dict[str, Any]] = []
        #: Runtime controllers (services, sensors: :class:`~simrun.world.registry.Controller`): ``tick(model, data)``
        #: every ``period`` s from ``next_time``, in creation order (checkpoints depend on it).
        self.controllers: list[Controller] = []
        self._bound: dict[tuple[str, str], Any] = {}
        #: Sensors created from ``[[sensors]]`` specs (or :meth:`add_sensor`), by name.
        self.sensors: dict[str, Any] = {}
        self.sensor_specs: list[dict[str, Any]] = []
        #: Asset names (used by ``MeshEntity.asset``) to ``.mbin`` paths relative to ``base_dir``.
        self.assets: dict[str, str] = {}
        #: Where each entity (by full name), service (``services:TYPE:ENTITY``) and sensor (``sensors:NAME``)
        #: came from (file, line, ``entities[3]``, name: ``scene.toml:12: entities[3] 'box'``; set by
        #: ``load_scene``), for later errors, which carry them as fields;
        #: ``NAME#PARAM`` keys hold the line of one parameter (a build error starting with ``mass`` points there).
        self.origins: dict[str, Origin] = {}

    # -- entities ------------------------------------------------------------------------------------------

    def insert(self, entity: Entity) -> Entity:
        """Add an entity (and later its children, which name it as ``parent``).

        Raises:
            EntityError: Bad or duplicate name, unknown parent, or a kinematic child.
        """
        if not _NAME.match(entity.name):
            raise EntityError(f"entity name {entity.name!r} must match [A-Za-z0-9_.-]+ (no '/')")
        full = self.full_name(entity)
        if full in self._entities:
            raise EntityError(f"an entity named {full!r} already exists; names must be unique")
        if entity.parent is not None and entity.parent not in self._entities:
            raise EntityError(f"{full!r}: parent {entity.parent!r} does not exist; insert the parent first")
        if entity.parent is not None and not self._entities[entity.parent].HAS_BODY:
            raise EntityError(
                f"{full!r}: parent {entity.parent!r} is a {self._entities[entity.parent].TYPE}, not a body"
            )
        if entity.kinematic and entity.parent is not None:
            raise EntityError(
                f"{full!r} is kinematic but has a parent: a kinematic (mocap) body is moved by set_pose and is "
                "fixed to the world, so as a child it would pin its parent in place (the trap of a kinematic arm "
                "base holding a robot to the floor). Make it a top-level entity, or drive the child with joints "
                "and actuators instead"
            )
        if entity.kinematic and entity.free:
            raise EntityError(f"{full!r}: an entity is either kinematic or free, not both")
        if entity.free and entity.parent is not None:
            raise EntityError(f"{full!r}: only top-level entities can have a free joint")
        self._entities[full] = entity
        self._invalidate()
        return entity

    def remove(self, name: str) -> None:
        """Remove an entity and its descendants.

        Raises:
            EntityError: No entity has that name.
        """
        if name not in self._entities:
            raise EntityError(f"no entity named {name!r}")
        doomed = [n for n in self._entities if n == name or n.startswith(name + "/")]
        for n in doomed:
            del self._entities[n]
        self._invalidate()

    def set_entities(self, entities: dict[str, Entity]) -> None:
        """Replace the whole entity table (full name to entity, in this order); the model is built again.

        A hook for :mod:`simrun.world.edit`, which checks the table and compiles it itself before it keeps it.
        """
        self._entities = dict(entities)
        self._invalidate()

    def adopt(self, spec: mujoco.MjSpec | None, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Take a model compiled from the current entities, and its state, without restarting anything.

        A hook for :mod:`simrun.world.edit` (an edit of the running world): unlike :meth:`compile`, every
        controller keeps its clock and state; the caller has set ``data`` (time, positions...). ``spec``
        ``None``: built again when asked for.
        """
        main = [full for full, e in self._entities.items() if isinstance(e, Camera) and e.main]
        if main:
            model.vis.global_.cameraid = model.camera(main[0]).id
        self._spec, self._model, self._data = spec, model, data
        self.reschedule()
        self._hooked = [e for e in self._entities.values() if type(e).before_step is not Entity.before_step]

    def full_name(self, entity: Entity) -> str:
        """``parent/name`` for children, ``name`` for top-level entities."""
        return f"{entity.parent}/{entity.name}" if entity.parent else entity.name

    def entity(self, name: str) -> Entity:
        """The entity with this full name."""
        try:
            return self._entities[name]
        except KeyError:
            raise EntityError(f"no entity named {name!r}") from None

    def __iter__(self) -> Iterator[tuple[str, Entity]]:
        return iter(self._entities.items())

    def __len__(self) -> int:
        return len(self._entities)

    # -- building and simulation ---------------------------------------------------------------------------

    def _invalidate(self) -> None:
        self._spec = self._model = self._data = None
        self.reschedule()

    def build_spec(self, batched: bool | None = None) -> mujoco.MjSpec:
        """A fresh spec with every entity built into it (assets added once, from memory).

        Args:
            batched: Build the entities that allow it in child specs of :data:`~simrun.world.batch.BATCH`
                entities, each attached once (:mod:`simrun.world.batch`: the same model, in time linear in
                the entities); ``None``: when the world has more than ``BATCH`` entities.
        """
        spec = mujoco.MjSpec()
        spec.modelname = "world"
        spec.compiler.degree = False  # angles in radians (joint ranges), as everywhere in simrun
        spec.option.timestep = self.options.timestep
        spec.option.gravity = list(self.options.gravity)
        spec.option.integrator = INTEGRATORS[self.options.integrator]
        model_options.apply(spec.option, self.option_choice()[0])
        spec.visual.headlight.ambient = [0.3, 0.3, 0.3]
        assets = AssetLibrary(spec, files=self._assets.files, images=self._assets.images, sources=self._assets.sources)
        bodies: dict[str, Any] = {}
        tree = TreeBuilder(spec, len(self._entities) > BATCH if batched is None else batched)
        for full, entity in self._entities.items():
            try:
                self._build_entity(tree, full, entity, assets, bodies)
            except (EntityError, ValueError) as exc:
                raise self._located(full, entity, exc) from None
        spec, nbody = tree.finish()
        if nbody - 1 > MAX_BODIES:
            raise EntityError(f"the world has {nbody - 1} bodies, over the limit of {MAX_BODIES}")
        spec.assets = dict(assets.vfs)
        arena = arena_bytes(nbody)
        if arena is not None:
            spec.memory = arena
        main = [full for full, e in self._entities.items() if isinstance(e, Camera) and e.main]
        if len(main) > 1:
            raise EntityError(f"more than one main camera: {', '.join(main)}")
        return spec

    def _build_entity(
        self, tree: TreeBuilder, full: str, entity: Entity, assets: AssetLibrary, bodies: dict[str, Any]
    ) -> None:
        ctx = BuildContext(tree.spec, full, assets, self.base_dir, self.assets)
        if not entity.HAS_BODY:
            tree.parent(full, entity, None, bodies)  # what was batched before it is attached first
            entity.build(None, ctx)
            return
        pose = entity.body_pose()
        parent = tree.parent(full, entity, pose, bodies)
        body = parent.add_body()
        body.name, body.pos, body.quat = full, pose.position, pose.orientation
        if entity.kinematic:
            body.mocap = True
        if entity.free:
            body.add_freejoint(name=f"{full}/free")
        entity.build(body, ctx)
        bodies[full] = body

    def _located(self, full: str, entity: Entity, exc: Exception) -> EntityError:
        """An entity's build error, prefixed with where the entity came from (its scene file and line).

        The parameter is the error's ``key`` field where it has one; else the first word of a message that
        starts with it (``mass must be ...``), as entities' parameter checks word them.
        """
        message = exc.message if isinstance(exc, SimrunError) and exc.message else str(exc)
        for prefix in (f"{entity.TYPE} {entity.name!r}: ", f"{entity.TYPE} {full!r}: "):
            message = message.removeprefix(prefix)
        key = exc.key if isinstance(exc, SimrunError) else None
        if key:
            message = f"{key}: {message}"
        field = key or message.split(" ", 1)[0].split("[", 1)[0].rstrip(":")
        origin = self.origins.get(f"{full}#{field}") or self.origins.get(full)
        hint = exc.hint if isinstance(exc, SimrunError) else None
        if origin is None:  # an entity added from Python
            return EntityError(f"{entity.TYPE} {full!r}: {message}", entity=full, hint=hint)
        return origin.error(message, hint)

    def compile(self) -> tuple[mujoco.MjModel, mujoco.MjData]:
        """Build and compile (done lazily by :attr:`model` and :attr:`data`).

        Raises:
            CompileError: MuJoCo refused the model (its message included).
        """
        cache = self.model_cache
        model = cache.load(self) if cache is not None else None
        spec = None  # on a cache hit the spec is built when asked for (World.spec)
        if model is None:
            spec = self.build_spec()
            try:
                model = spec.compile()
            except ValueError as exc:
                raise CompileError(f"MuJoCo cannot compile the world: {exc}") from None
            if cache is not None:
                cache.store(self, model, model_cache.read_files(self._assets))
        main = [full for full, e in self._entities.items() if isinstance(e, Camera) and e.main]
        if main:
            model.vis.global_.cameraid = model.camera(main[0]).id  # the main view renders from this camera
        self._spec, self._model, self._data = spec, model, mujoco.MjData(model)
        for controller in self.controllers:
            controller.next_time = 0.0  # a new model starts at time 0: every clock restarts (after a rebuild too)
        self.reschedule()
        self._hooked = [e for e in self._entities.values() if type(e).before_step is not Entity.before_step]
        mujoco.mj_forward(model, self._data)
        return model, self._data

    @property
    def time(self) -> float:
        """Simulation time, seconds (0 before the first compile)."""
        return float(self._data.time) if self._data is not None else 0.0

    @property
    def spec(self) -> mujoco.MjSpec:
        """The compiled spec."""
        if self._spec is None:
            if self._model is None:
                self.compile()
            if self._spec is None:  # the model came from the compiled-model cache: build the spec now
                spec = self.build_spec()
                spec.compile()
                self._spec = spec
        return self._spec

    @property
    def model(self) -> mujoco.MjModel:
        """The compiled model."""
        if self._model is None:
            self.compile()
        assert self._model is not None
        return self._model

    @property
    def data(self) -> mujoco.MjData:
        """The simulation state."""
        if self._data is None:
            self.compile()
        assert self._data is not None
        return self._data

    def step(self, n: int = 1) -> None:
        """Advance ``n`` physics steps.

        Entity ``before_step`` hooks run before every step. Controllers (services, sensors) run when due on
        the simulation clock (``tick`` every ``period`` seconds; controls hold between ticks); between
        ticks the steps run inside MuJoCo (``mj_step`` with ``nstep``), so a controller at 100 Hz costs one
        Python call per 10 ms of simulated time, not one per step. A single step between ticks is one
        ``mj_step`` call: the world remembers when the next controller is due (see :meth:`reschedule`).
        """
        data = self._data
        if n == 1 and data is not None:
            now = data.time
            if (
                now == self._sched_time  # time moved only by this world's own steps since the schedule
                and now + self._sched_half < self._sched_until  # the scan's own test: no controller is due
                and self.controllers == self._sched_list  # same controllers, same order (identity compares)
            ):
                _mj_step(self._model, data)
                self._sched_time = now + self._sched_dt  # MuJoCo's own `time += timestep`
                if data.time < now:  # MuJoCo reset the data (an unstable simulation): the clock goes on
                    self._clock_after_reset(now, 1)
                return
        model = self._model
        if model is None or data is None:
            model, data = self.model, self.data
        dt = model.opt.timestep
        controllers, hooked, mj_step = self.controllers, self._hooked, mujoco.mj_step
        remaining, half = n, 0.5 * dt
        upcoming, scanned = math.inf, self._sched_list
        while remaining > 0:
            now = data.time + half  # ticks do not advance time
            upcoming, scanned = math.inf, list(controllers)
            for controller in controllers:
                due = controller.next_time
                if now >= due:
                    controller.tick(model, data)
                    period = controller.period or dt
                    while due <= now:
                        due += period
                    controller.next_time = due
                if due < upcoming:
                    upcoming = due
            if hooked:
                for entity in hooked:
                    entity.before_step(model, data)
                count = 1
            elif remaining == 1:
                count = 1
            elif upcoming < math.inf:
                count = min(remaining, max(1, round((upcoming - data.time) / dt)))
            else:
                count = remaining
            before = data.time
            mj_step(model, data, count)
            if data.time < before + (count - 0.5) * dt:  # MuJoCo reset the data: the clock goes on
                self._clock_after_reset(before, count)
            remaining -= count
        if hooked or n < 1:
            self.reschedule()
        else:  # single steps skip the scan while data.time + dt / 2 < upcoming and the scanned list is unchanged
            self._sched_list, self._sched_time, self._sched_until = scanned, data.time, upcoming
            self._sched_half, self._sched_dt = half, dt

    def _clock_after_reset(self, before: float, steps: int) -> None:
        """MuJoCo reset the data during the last ``steps`` steps from ``before`` s (BADQACC, BADQPOS, BADQVEL).

        The state is the model's initial one, but the clock goes on: ``data.time`` is set to what ``steps``
        steps of ``time += timestep`` from ``before`` give (bit for bit what single steps give), so
        controllers, commands and recordings never see time run backwards. Counted in ``mujoco_resets``,
        the time the (last) reset step began in ``last_reset``.
        """
        data, model = self._data, self._model
        assert data is not None and model is not None
        dt = model.opt.timestep
        since = min(steps, max(1, round(data.time / dt)))  # steps since the (last) reset, its own included
        clock = before
        for _ in range(steps - since):
            clock += dt
        self.last_reset = clock
        for _ in range(since):
            clock += dt
        data.time = clock
        self.mujoco_resets += 1
        self._sched_time = clock

    def reschedule(self) -> None:
        """Forget the remembered next-due time, so the next :meth:`step` scans every controller.

        Call it after changing a controller's ``next_time`` (``restore`` from a snapshot) without moving the
        simulation time; adding or removing controllers and any change of ``data.time`` other than this
        world's steps (``reset``, ``mj_setState``) are noticed without it.
        """
        self._sched_list = []
        self._sched_time = math.nan
        self._sched_until = -math.inf

    def run(self, seconds: float) -> None:
        """Step until ``seconds`` of simulated time have passed."""
        self.step(round(seconds / float(self.model.opt.timestep)))

    def service(self, kind: str, entity: str) -> Any:
        """The service of type ``kind`` bound to ``entity`` (``[[services]]`` of a scene), created on first use.

        Raises:
            EntityError: No such binding, or an unknown service type.
        """
        binding = next((s for s in self.services if s.get("type") == kind and s.get("entity") == entity), None)
        if binding is None:
            raise EntityError(f"no {kind} is bound to {entity!r}; add it under [[services]] or create it in code")
        key = (kind, entity)
        if key not in self._bound:
            cls = scene_type("services", kind).load()
            self._bound[key] = cls(self, entity, **service_arguments(binding))
        return self._bound[key]

    def add_sensor(self, spec: dict[str, Any]) -> Any:
        """Create a sensor from a spec ``{type, name, entity, ...parameters}`` (a ``[[sensors]]`` table).

        Raises:
            EntityError: Unknown type, missing or duplicate name, unknown entity or parameter.
        """
        kind, name = spec.get("type"), spec.get("name")
        registered = scene_type("sensors", kind)
        if not isinstance(name, str) or name in self.sensors:
            raise EntityError(f"a sensor needs a unique 'name', got {name!r}")
        target = spec.get(registered.binds)
        if not isinstance(target, str):
            raise EntityError(f"sensor {name!r} needs a {registered.binds!r} string")
        params = arguments("sensors", registered.name, spec, python_fail(f"sensor {name!r}"))  # as a scene's
        try:
            sensor = registered.load()(self, target, **params)
        except TypeError as exc:
            raise EntityError(f"sensor {name!r}: {exc}") from None
        self.sensors[name] = sensor
        self.sensor_specs.append(dict(spec))
        return sensor

    def check_bindings(self) -> None:
        """Create every bound service and take one trial reading of every sensor, then restore the sensors.

        ``simrun check`` and ``simrun play`` call it so that a service bound to the wrong kind of entity or a
        sensor that cannot read its entity (a missing geom or joint) fails before the run, with the scene
        file and line of the binding. The trial readings leave no trace: each sensor's snapshot (clock,
        sample count, noise generator) is restored afterwards.

        Raises:
            EntityError: A binding that does not fit, prefixed with where it came from.
        """
        model, data = self.model, self.data
        for binding in self.services:
            kind, entity = binding["type"], binding["entity"]
            try:
                self.service(kind, entity)
            except EntityError as exc:
                origin = self.origins.get(f"services:{kind}:{entity}")
                if origin is None:
                    raise EntityError(f"service {kind} of {entity!r}: {exc}", entity=entity) from None
                raise origin.error(str(exc)) from None
        for name, sensor in self.sensors.items():
            state, reading = sensor.snapshot(), sensor.reading
            try:
                sensor.sample(model, data)
            except (EntityError, KeyError, IndexError, ValueError) as exc:
                origin = self.origins.get(f"sensors:{name}")
                reason = exc.args[0] if isinstance(exc, KeyError) and exc.args else exc
                if origin is None:
                    raise EntityError(
                        f"sensor {name!r}: cannot read {sensor.entity!r}: {reason}", entity=name
                    ) from None
                raise origin.error(f"cannot read {sensor.entity!r}: {reason}") from None
            finally:
                sensor.restore(state)
                sensor.reading = reading

    def run_until(self, done: Any, timeout: float) -> bool:
        """Step until ``done()`` is true or ``timeout`` simulated seconds pass; returns ``done()``."""
        end = self.data.time + timeout
        while not done() and self.data.time < end:
            self.step()
        return bool(done())

    def reset(self, keyframe: str | None = None) -> None:
        """Back to the initial state (time 0, initial poses), or to a keyframe; controllers are reset too.

        Args:
            keyframe: Full name of a keyframe (an MJCF model's ``home`` of the entity ``arm`` is ``arm/home``);
                ``None``: the initial state. An entity's keyframe places its model at the entity's pose (see
                :mod:`simrun.robots.mjcf_robot`); every other entity is at its initial state in it.

        Raises:
            EntityError: No keyframe of that name (the message lists them).
        """
        model = self.model
        if keyframe is None:
            mujoco.mj_resetData(model, self.data)
        else:
            names = [model.key(k).name for k in range(model.nkey)]
            if keyframe not in names:
                raise EntityError(
                    f"no keyframe named {keyframe!r}; keyframes: {', '.join(names) or 'none'}", key="keyframe"
                )
            mujoco.mj_resetDataKeyframe(model, self.data, names.index(keyframe))
        mujoco.mj_forward(self.model, self.data)
        for controller in self.controllers:
            controller.reset(self.model, self.data)
            controller.next_time = 0.0
        self.reschedule()

    def files_read(self) -> list[Path]:
        """Every file the builds of this world read, by real path; empty before the first build.

        ``.mbin`` assets, images and what imports read (URDF robots: the URDF, its meshes, MTL and textures).
        """
        return sorted({*self._assets.files, *self._assets.images, *self._assets.sources})

    def option_choice(self) -> tuple[dict[str, Any], list[str]]:
        """The MuJoCo options the robots' own ``<option>`` give this world, and the overrides as warnings.

        The rule is :mod:`simrun.world.options`'s: explicit world options govern, then the first robot
        (entity order) that sets an option. Robots are the entities with ``own_options(base_dir)``
        (:class:`~simrun.robots.mjcf_robot.MjcfRobot`); each model is read again (not compiled).
        """
        robots = []
        for full, entity in self._entities.items():
            own = getattr(entity, "own_options", None)
            if own is not None:
                try:
                    robots.append((full, own(self.base_dir)))
                except (EntityError, ValueError):
                    continue  # the build names the problem, with its file and line
        current = {"timestep": self.options.timestep, "integrator": int(INTEGRATORS[self.options.integrator])}
        return model_options.choose(current, self.options.explicit, robots)

    def scene_warnings(self) -> list[str]:
        """Warnings about the world at its initial state, as ``simrun check`` prints them (simrun.world.checks)."""
        from simrun.world.checks import scene_warnings

        return scene_warnings(self)

    def warnings(self) -> dict[str, int]:
        """MuJoCo warnings raised so far, by name (read from the counters ``data.warning.number``, one array)."""
        counts = self.data.warning.number
        if not counts.any():
            return {}
        return {mujoco.mjtWarning(k).name: int(n) for k, n in enumerate(counts.tolist()) if n}

    # -- named access --------------------------------------------------------------------------------------

    def body(self, name: str) -> Any:
        """MjData view of an entity's body (``xpos``, ``xquat``, ``cvel``...)."""
        try:
            return self.data.body(name)
        except KeyError:
            raise EntityError(f"no body named {name!r}") from None

    def geom(self, name: str) -> Any:
        """MjData view of a geom, e.g. ``box/geom``."""
        try:
            return self.data.geom(name)
        except KeyError:
            raise EntityError(f"no geom named {name!r}") from None

    def joint(self, name: str) -> Any:
        """MjData view of a joint, e.g. ``box/free``."""
        try:
            return self.data.joint(name)
        except KeyError:
            raise EntityError(f"no joint named {name!r}") from None

    def set_pose(self, name: str, position: Any, orientation: Any = (1.0, 0.0, 0.0, 0.0)) -> None:
        """Move a kinematic entity (its mocap body) to a world pose.

        Raises:
            EntityError: The entity is not kinematic.
        """
        if not self.entity(name).kinematic:
            raise EntityError(f"{name!r} is not kinematic; only kinematic entities are moved by set_pose")
        mocap = int(self.model.body(name).mocapid[0])
        self.data.mocap_pos[mocap] = np.asarray(position, dtype=float)
        self.data.mocap_quat[mocap] = np.asarray(orientation, dtype=float)
