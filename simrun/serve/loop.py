"""The served world's simulation loop: one thread owns the world; everything else talks to it through queues.

The loop thread loads the scene itself (a camera's GL context belongs to the thread that made it), binds
the services (:func:`simrun.run.session.prepare`) and then steps. Between chunks of steps it runs the calls that
HTTP handlers queued (:meth:`SimLoop.call`: a service command, a query, pause, step, reset), so a request
never races the physics and the physics never waits for a request. Modes:

* real time (default): simulated time follows the wall clock times the real-time factor (``rate``), in
  chunks of at most :data:`CHUNK_SECONDS` simulated seconds; between chunks the thread sleeps on its call
  queue, so a command is applied as soon as it arrives (at the next step boundary);
* lockstep: the world advances only through :meth:`SimLoop.step_request` (``POST /api/step``);
* paused: no stepping; calls still run.

After each chunk the loop publishes to every subscriber (:class:`Broadcast`): body poses every
``1 / pose_rate`` simulated seconds (and after every requested step) and each sensor's new readings as
they come, at the sensor's own rate. Every subscriber has a bounded queue; when it is full the oldest
message is dropped, so a slow or vanished client never slows the simulation.

A service command applied to the world is kept with the simulated time it was applied at; with a
recording (:mod:`simrun.serve.recording`) those commands go into the ``.simlog``, and ``simrun resim``
replays them at the same step, bit for bit.
"""

from __future__ import annotations

import asyncio
import collections
import concurrent.futures
import contextlib
import contextvars
import json
import math
import queue
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from simrun.errors import SimrunError
from simrun.run.commands import Command
from simrun.serve.catalogue import RequestError, build_catalogue, plain
from simrun.serve.images import ImageEncoder, image_of
from simrun.serve.request_budget import REQUESTS_PER_SECOND
from simrun.world.world import World

#: Longest stretch of simulated time stepped between two looks at the call queue, seconds.
CHUNK_SECONDS = 0.01
#: Wall seconds a chunk may take when the world runs faster than real time, and the longest chunk then,
#: simulated seconds.
WALL_CHUNK, MAX_CHUNK_SECONDS = 0.005, 0.5
#: Most calls waiting for the loop; beyond, requests are answered 503.
MAX_PENDING_CALLS = 256
#: Messages a subscriber may have waiting; beyond, its oldest are dropped.
SUBSCRIBER_QUEUE = 64
#: Longest wait for the loop to answer a call, wall seconds.
CALL_TIMEOUT = 30.0
#: Most steps one ``POST /api/step`` may ask for.
MAX_STEPS = 100_000
#: Physics steps a step request runs between two looks at the shutdown flag and its deadline.
STEP_CHUNK = 50
#: Wall seconds after its arrival at which a step request stops stepping and answers with the state it
#: reached (``"cancelled": "deadline"``), well before the server's :data:`CALL_TIMEOUT`: a client never
#: gets a 503 for steps that go on.
STEP_DEADLINE = CALL_TIMEOUT - 5.0
#: Shortest wall time between two published pose messages, seconds (a world run faster than real time
#: publishes at most this often).
MIN_POSE_INTERVAL = 1.0 / 120
#: Shortest wall time between two published readings of one sensor, seconds: a sensor streams at its own
#: rate in simulated time, up to 60 messages per wall second (a world run 1000 times faster than real time
#: would otherwise send a 10 Hz laser 10 000 times a second to every client).
MIN_SENSOR_INTERVAL = 1.0 / 60
_SHUTTING_DOWN = RequestError(503, "", "the server is shutting down; the call did not run")
#: The refusal of a step request while the world runs in real time (409).
REALTIME_STEP = "the world runs in real time; pause it (or serve --lockstep) to step"
#: Real-time factors accepted.
MIN_RATE, MAX_RATE = 0.01, 1000.0


@dataclass
class ServeOptions:
    """How to serve a scene.

    Attributes:
        scene: The scene file.
        lockstep: Advance only on step requests.
        rate: Real-time factor (simulated seconds per wall second) in real-time mode.
        pose_rate: Body poses published per simulated second.
        record: ``.simlog`` to write (from the start until shutdown or ``recording stop``).
        record_sensors: Sensors whose readings the recording keeps.
        record_mcap: Also write the recording as MCAP (this path) when it is finished.
        seed: Sensor noise seed.
        paused: Start paused.
        request_rate: Requests one client address may send per wall second in real time (a burst of twice as
            many; changing requests half as many, a burst of ``request_rate``): :mod:`simrun.serve.request_budget`.
    """

    scene: Path
    lockstep: bool = False
    rate: float = 1.0
    pose_rate: float = 30.0
    record: Path | None = None
    record_sensors: tuple[str, ...] = ()
    record_mcap: Path | None = None
    seed: int | None = None
    paused: bool = False
    extra: dict[str, Any] = field(default_factory=dict)
    request_rate: float = REQUESTS_PER_SECOND


class Subscriber:
    """One stream client's bounded mailbox (filled by the loop thread, drained by its asyncio task).

    Args:
        loop: The asyncio loop of the client's task (woken through ``call_soon_threadsafe``).
        sensors: Sensor names whose readings it wants (``None``: all but images).
        poses: Whether it wants body poses.
        images: Camera sensors whose frames it wants (base64 in the message).
        image_format: ``"jpeg"`` (quality 80) or ``"png"``.
    """

    def __init__(
        self,
        loop: asyncio.AbstractEventLoop,
        sensors: set[str] | None,
        poses: bool,
        images: set[str],
        image_format: str = "jpeg",
    ) -> None:
        self.loop, self.sensors, self.poses, self.images = loop, sensors, poses, images
        self.image_format = image_format
        self.messages: collections.deque[str] = collections.deque(maxlen=SUBSCRIBER_QUEUE)
        self.ready = asyncio.Event()
        self.dropped = 0

    def push(self, message: str) -> None:
        """Queue a message (from any thread); the oldest goes when the queue is full."""
        if len(self.messages) == self.messages.maxlen:
            self.dropped += 1
        self.messages.append(message)
        if self.ready.is_set():  # already woken; it clears the flag before it drains, so nothing is missed
            return
        with contextlib.suppress(RuntimeError):  # its loop is closed: the client is gone
            self.loop.call_soon_threadsafe(self.ready.set)


class Broadcast:
    """The set of subscribers (thread-safe)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._subscribers: list[Subscriber] = []

    def add(self, subscriber: Subscriber) -> None:
        """Start sending to ``subscriber``."""
        with self._lock:
            self._subscribers.append(subscriber)

    def remove(self, subscriber: Subscriber) -> None:
        """Stop sending to ``subscriber``."""
        with self._lock:
            if subscriber in self._subscribers:
                self._subscribers.remove(subscriber)

    def describe(self) -> dict[str, int]:
        """``{"open", "queued", "dropped"}``: streams now, messages waiting, messages dropped so far."""
        subscribers = self.current()
        return {
            "open": len(subscribers),
            "queued": sum(len(s.messages) for s in subscribers),
            "dropped": sum(s.dropped for s in subscribers),
        }

    def current(self) -> list[Subscriber]:
        """The subscribers now."""
        with self._lock:
            return list(self._subscribers)


class SimLoop:
    """The simulation thread of ``simrun serve`` (see the module).

    Args:
        options: What to serve.
        recording_factory: Called in the loop thread as ``factory(world, loop)`` after the services are
            bound, to start the recording (:class:`simrun.serve.recording.LiveRecording`); ``None``: none.

    Attributes:
        catalogue: Entities, services and sensors (:func:`simrun.serve.catalogue.build_catalogue`).
        broadcast: The stream subscribers.
        applied: The service commands applied so far, with their simulated times.
    """

    def __init__(self, options: ServeOptions, recording_factory: Callable[[World, SimLoop], Any] | None = None) -> None:
        self.options = options
        self.rate = options.rate
        self.paused = options.paused
        self.broadcast = Broadcast()
        self.applied: list[Command] = []
        self.catalogue: dict[str, Any] = {}
        self.recording: Any = None
        #: Every edit applied to the world this session (``simrun serve --edit``), in order: (simulated time s,
        #: the edit's ``EditRecord.to_json``, the state size before it, after it). A recording started later
        #: writes them first, so ``simrun resim`` rebuilds the edited world from the scene before its checkpoint.
        self.edit_history: list[tuple[float, str, int, int]] = []
        #: The Foxglove WebSocket server (:class:`simrun.serve.foxglove_live.FoxgloveLive`), when one is asked for.
        self.foxglove: Any = None
        self.steps = 0
        self._factory = recording_factory
        self._calls: queue.Queue[_Call] = queue.Queue(MAX_PENDING_CALLS)
        self._deferred: collections.deque[_Call] = collections.deque()  # changes that arrived during a step
        #: The compiled model the loop thread last saw (a new object after an edit recompiles the world): the
        #: version of what ``/api/scene.glb`` shows.
        self.model: Any = None
        self._images = ImageEncoder()
        self._stop = threading.Event()
        self._started: concurrent.futures.Future[None] = concurrent.futures.Future()
        context = contextvars.copy_context()  # the caller's output policy (--force) holds in the thread too
        self._thread = threading.Thread(target=context.run, args=(self._main,), name="simrun-serve-loop", daemon=True)
        self._world: World | None = None
        self._pace = (0.0, 0.0)  # (wall, sim) at the last change of rate, pause or reset
        self._rtf_window: collections.deque[tuple[float, float]] = collections.deque(maxlen=4096)
        self._last_samples: dict[str, int] = {}
        self._next_pose = 0.0
        self._last_pose_wall = -math.inf
        self._last_sent: dict[str, float] = {}  # wall time each sensor's reading last went out
        self._state: dict[str, Any] = {}
        self.error: str | None = None

    # -- life cycle ----------------------------------------------------------------------------------------

    def start(self, timeout: float = 120.0) -> None:
        """Start the thread and wait until the world is loaded and bound.

        Raises:
            SimrunError: The scene (or a binding, or the recording) was refused.
        """
        self._thread.start()
        self._started.result(timeout)

    def interrupt(self) -> None:
        """Ask the loop to stop (from a signal handler: it only sets a flag).

        The loop thread finishes the physics step it is in (a step request stops at its next chunk of
        :data:`STEP_CHUNK` steps and answers with the state reached), then finishes the recording and ends.
        """
        self._stop.set()

    def stop(self, timeout: float | None = None) -> None:
        """Stop stepping, finish the recording, and wait for the thread (``None``: however long that takes).

        MuJoCo is never torn down under a running step: the process must not exit before the thread.
        """
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout)

    @property
    def running(self) -> bool:
        """Whether the loop thread is alive."""
        return self._thread.is_alive()

    def _main(self) -> None:
        from simrun.run.session import prepare
        from simrun.scene.scene_file import load_scene

        try:
            world = load_scene(self.options.scene)
            prepare(world, seed=self.options.seed)
            self.catalogue = build_catalogue(world)
            self._world = world
            if self._factory is not None:
                self.recording = self._factory(world, self)
            self._publish(world, poses=True)
        except Exception as exc:  # a refused scene (SimrunError), or a bug the command reports as one (exit 3)
            self._started.set_exception(exc)
            return
        self._started.set_result(None)
        try:
            self._run(world)
        except SimrunError as exc:
            self.error = str(exc)
        except Exception as exc:  # a crash of the simulation thread: the recording is still finished below
            self.error = f"the simulation thread failed ({type(exc).__name__}: {exc})"
        finally:
            self._drain(world, final=True)
            self._images.close()
            if self.recording is not None:
                try:
                    self.recording.finish()
                except SimrunError as exc:
                    self.error = str(exc)

    def _run(self, world: World) -> None:
        dt = world.model.opt.timestep
        periods = [s.period for s in world.sensors.values() if s.period > 0]
        base = min([CHUNK_SECONDS, *periods])
        self._pace = (time.perf_counter(), world.time)
        while not self._stop.is_set():
            if self._deferred or not self._calls.empty():
                self._drain(world)
            if self.paused or self.options.lockstep:
                self._wait(0.05)
                continue
            wall0, sim0 = self._pace
            delay = wall0 + (world.time - sim0) / self.rate - time.perf_counter()
            if delay > 0:  # ahead of the wall clock: sleep, waking for calls
                self._wait(min(delay, 0.05))
                continue
            if delay < -0.25:  # far behind (a slow scene): carry on from now rather than catch up in a burst
                self._pace = (time.perf_counter(), world.time)
            # faster than real time, chunks grow to WALL_CHUNK of wall time each (a call still waits at most that)
            chunk = max(1, round(max(base, min(self.rate * WALL_CHUNK, MAX_CHUNK_SECONDS)) / dt))
            world.step(chunk)
            self.steps += chunk
            self._publish(world)

    def _wait(self, seconds: float) -> None:
        """Sleep up to ``seconds``, waking at once for a queued call (which runs then)."""
        if self._deferred:
            assert self._world is not None
            self._drain(self._world)
            return
        try:
            item = self._calls.get(timeout=seconds)
        except queue.Empty:
            return
        assert self._world is not None
        self._run_call(self._world, item)

    def _drain(self, world: World, final: bool = False) -> None:
        while True:
            if self._deferred:
                item = self._deferred.popleft()
            else:
                try:
                    item = self._calls.get_nowait()
                except queue.Empty:
                    return
            if final:
                if item.future.set_running_or_notify_cancel():
                    item.future.set_exception(
                        RequestError(503, "", "the server is shutting down; the call did not run")
                    )
            else:
                self._run_call(world, item)

    def _serve_reads(self, world: World) -> None:
        """During a step request: run the queued reads now, keep the changes for after the step (in order)."""
        while True:
            try:
                item = self._calls.get_nowait()
            except queue.Empty:
                return
            if item.read:
                self._run_call(world, item)
            else:
                self._deferred.append(item)

    def _run_call(self, world: World, item: _Call) -> None:
        future = item.future
        if not future.set_running_or_notify_cancel():
            return
        try:
            future.set_result(item.fn(world))
        except Exception as exc:  # handed to the request that asked (a RequestError, or a bug)
            future.set_exception(exc)
        if not item.read:
            self._note_model(world)

    def _note_model(self, world: World) -> None:
        """Keep :attr:`model` current after a change (an edit may have rebuilt the world)."""
        with contextlib.suppress(SimrunError):  # the next step reports it
            self.model = world.model

    # -- calls (from any thread) ---------------------------------------------------------------------------

    def call(self, fn: Callable[[World], Any], read: bool = False) -> concurrent.futures.Future[Any]:
        """Run ``fn(world)`` in the loop thread between steps; its result (or error) in the future.

        Args:
            fn: The call.
            read: ``fn`` only reads the world (a state, a sensor, a snapshot): it also runs between the chunks
                of a running step request, so reads are answered at once during a long step. Other calls wait
                for the step to end (in the order they came).

        Raises:
            RequestError: 503 when the loop has stopped or too many calls wait.
        """
        if not self._thread.is_alive() or self._stop.is_set():
            raise RequestError(503, "", "the simulation is not running" + (f" ({self.error})" if self.error else ""))
        future: concurrent.futures.Future[Any] = concurrent.futures.Future()
        try:
            self._calls.put_nowait(_Call(fn, future, read))
        except queue.Full:
            raise RequestError(503, "", f"{MAX_PENDING_CALLS} calls are waiting; try again") from None
        return future

    def apply(self, command: Command) -> Callable[[World], Any]:
        """The call that applies a validated service command now and records it (for :meth:`call`)."""

        def run(world: World) -> Any:
            timed = replace(command, t=float(world.data.time))
            try:
                timed.apply(world)
            except SimrunError as exc:
                raise RequestError(422, "args", str(exc)) from None
            self.applied.append(timed)
            if self.recording is not None:
                self.recording.command(timed)
            return {"time": timed.t, "applied": True}

        return run

    def step_request(self, steps: int, deadline: float = STEP_DEADLINE) -> Callable[[World], Any]:
        """The call that advances ``steps`` physics steps (lockstep or paused).

        The steps run in chunks of :data:`STEP_CHUNK`; between chunks the call stops when the server shuts
        down (SIGINT/SIGTERM) or ``deadline`` wall seconds after the request arrived. Its answer is the
        state reached, with ``"stepped"`` (steps done), ``"requested"`` and ``"cancelled"`` (``None``, or
        ``"shutdown"``/``"deadline"`` when it stopped early): the world is exactly at that state.
        """
        arrived = time.monotonic()

        def run(world: World) -> Any:
            if not (self.options.lockstep or self.paused):
                raise RequestError(409, "steps", REALTIME_STEP)
            done, cancelled = 0, None
            while done < steps:
                if self._stop.is_set():
                    cancelled = "shutdown"
                    break
                if time.monotonic() - arrived >= deadline:
                    cancelled = "deadline"
                    break
                n = min(STEP_CHUNK, steps - done)
                world.step(n)
                done += n
                self.steps += n
                self._serve_reads(world)
            self._publish(world, poses=True)
            return {**self.state(world), "stepped": done, "requested": steps, "cancelled": cancelled}

        return run

    def set_paused(self, on: bool) -> Callable[[World], Any]:
        """The call that pauses or resumes."""

        def run(world: World) -> Any:
            self.paused = on
            self._pace = (time.perf_counter(), world.time)
            self._rtf_window.clear()
            self._publish(world, poses=True)
            return self.state(world)

        return run

    def set_rate(self, rate: float) -> Callable[[World], Any]:
        """The call that changes the real-time factor."""

        def run(world: World) -> Any:
            self.rate = rate
            self._pace = (time.perf_counter(), world.time)
            self._rtf_window.clear()
            return self.state(world)

        return run

    def reset(self) -> Callable[[World], Any]:
        """The call that resets the world to time 0 (refused while recording)."""

        def run(world: World) -> Any:
            if self.recording is not None and self.recording.active:
                raise RequestError(409, "", "the world is being recorded; stop the recording before a reset")
            world.reset()
            self.applied.clear()
            self._last_samples.clear()
            self._next_pose = 0.0
            self._pace = (time.perf_counter(), world.time)
            self._rtf_window.clear()
            self._publish(world, poses=True)
            return self.state(world)

        return run

    # -- state and publishing (loop thread) ----------------------------------------------------------------

    def state(self, world: World) -> dict[str, Any]:
        """Time, mode, rate, measured real-time factor, steps, recording and every body's pose."""
        data = world.data
        return {
            "time": float(data.time),
            "mode": "lockstep" if self.options.lockstep else "realtime",
            "paused": self.paused,
            "rate": self.rate,
            "measured_rate": self.measured_rate(),
            "steps": self.steps,
            "recording": self.recording.describe() if self.recording is not None else None,
            "streams": self.broadcast.describe(),
            "poses": self._poses(world),
        }

    def measured_rate(self) -> float | None:
        """Simulated seconds per wall second over the last second or so of stepping (``None``: not enough)."""
        window = list(self._rtf_window)
        if len(window) < 2 or window[-1][0] - window[0][0] <= 0:
            return None
        return (window[-1][1] - window[0][1]) / (window[-1][0] - window[0][0])

    def latest(self) -> dict[str, Any]:
        """The last published state (read without a thread hop)."""
        return self._state

    def _poses(self, world: World) -> dict[str, list[float]]:
        data = world.data
        names = self.catalogue["bodies"]
        xpos, xquat = data.xpos, data.xquat
        return {names[b]: [*map(float, xpos[b]), *map(float, xquat[b])] for b in range(1, len(names))}

    def _publish(self, world: World, poses: bool = False) -> None:
        self.model = world.model
        now = time.perf_counter()
        sim = float(world.data.time)
        self._rtf_window.append((now, sim))
        while len(self._rtf_window) > 2 and now - self._rtf_window[0][0] > 1.0:
            self._rtf_window.popleft()
        subscribers = self.broadcast.current()
        dt = world.model.opt.timestep
        due = sim + 0.5 * dt >= self._next_pose and now - self._last_pose_wall >= MIN_POSE_INTERVAL
        if poses or due:
            period = 1.0 / self.options.pose_rate
            while self._next_pose <= sim + 0.5 * dt:  # a fixed grid in simulated time (chunks do not drift it)
                self._next_pose += period
            self._last_pose_wall = now
            self._state = self.state(world)
            if self.foxglove is not None:
                self.foxglove.poses(sim, self._state["poses"])
            if subscribers:
                message = json.dumps({"type": "poses", "time": sim, "poses": self._state["poses"]})
                for sub in subscribers:
                    if sub.poses:
                        sub.push(message)
        for name, sensor in world.sensors.items():
            samples = int(sensor.samples)
            if samples == self._last_samples.get(name, 0) or sensor.reading is None:
                continue
            self._last_samples[name] = samples
            if (not subscribers and self.foxglove is None) or now - self._last_sent.get(name, -math.inf) < (
                MIN_SENSOR_INTERVAL
            ):
                continue
            self._last_sent[name] = now
            if self.foxglove is not None:
                self.foxglove.sensor(name, float(getattr(sensor.reading, "time", sim)), sensor.reading)
            if not subscribers:
                continue
            image = image_of(sensor.reading)
            if image is not None:  # encoded and sent by the encoder thread: here only a copy of the pixels
                wanting = [sub for sub in subscribers if name in sub.images]
                if wanting:
                    self._images.put(name, sim, np.array(image), wanting)
                continue
            text: str | None = None
            for sub in subscribers:
                if sub.sensors is not None and name not in sub.sensors:
                    continue
                if text is None:
                    text = json.dumps({"type": "sensor", "name": name, "time": sim, "reading": plain(sensor.reading)})
                sub.push(text)


@dataclass(frozen=True)
class _Call:
    """A queued call: the function, the future its answer goes to, whether it only reads the world."""

    fn: Callable[[World], Any]
    future: concurrent.futures.Future[Any]
    read: bool = False


def is_finite_number(value: Any) -> bool:
    """A JSON number (not a boolean) that is finite."""
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
