r"""Progress of long work (stages of a conversion, parts of a decomposition, a simulation, a batch), for a display.

The library never prints: it calls :func:`report`, which does nothing unless a caller (the CLI) installed a
sink with :func:`reporting`. What a report is about (the file being converted) is set once around the work
with :func:`subject`, and every report inside names it (``head.obj: collision hulls``).

:class:`Display` is the command line's sink: one line on a terminal's stderr with a spinner, the file, the
stage, ``done/total`` and the time the stage has taken, redrawn in place (``\r\x1b[K``) ten times a second
by a ticker thread, so the line moves while CoACD or MuJoCo work and no report comes. It draws nothing when
the stream is not a terminal (a pipe, a log, ``--json``) or with ``-q``; output written through
:meth:`Display.write_above` clears the line first, so text never runs into it.

A batch of many items (``obj2bin DIR``, ``meshtool validate``, ``simrun test``) reports through a
:class:`Meter`: each finished item gives a :class:`Tick` (done, total, items per second, time left, the
last item's name) to the caller's callback, and :meth:`Tick.line` is the one progress line the three
commands show, ``[ 37/120] 31%  2.4 items/s  eta 0:35  last: NAME``. On a terminal the CLI hands it to
:meth:`Display.batch` (the spinner in front; a stage reported by the work itself follows after `` -- ``).
"""

from __future__ import annotations

import contextlib
import contextvars
import shutil
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import TextIO

#: ``sink(stage, done, total)``; ``total`` 0 when the stage has no count.
Sink = Callable[[str, int, int], None]
_SINK: contextvars.ContextVar[Sink | None] = contextvars.ContextVar("meshtool_progress", default=None)
_SUBJECT: contextvars.ContextVar[str | None] = contextvars.ContextVar("meshtool_progress_subject", default=None)
#: Spinner frames (ASCII: every terminal and font shows them).
FRAMES = "|/-\\"
#: Seconds between two redraws of the ticker.
TICK_S = 0.1
#: Clears the terminal line: carriage return, then erase to the end of the line.
CLEAR = "\r\x1b[K"


def report(stage: str, done: int = 0, total: int = 0) -> None:
    """Tell the installed sink (if any) that ``stage`` is under way, ``done`` of ``total`` items."""
    sink = _SINK.get()
    if sink is not None:
        about = _SUBJECT.get()
        sink(f"{about}: {stage}" if about else stage, done, total)


@contextlib.contextmanager
def reporting(sink: Sink | None) -> Iterator[None]:
    """Send :func:`report` calls in this context to ``sink``."""
    token = _SINK.set(sink)
    try:
        yield
    finally:
        _SINK.reset(token)


@contextlib.contextmanager
def subject(name: str) -> Iterator[None]:
    """Name ``name`` (a file) in every :func:`report` inside this context.

    A subject already set outside is kept: it knows more (``[3/10] head.obj`` in a folder conversion).
    """
    token = _SUBJECT.set(_SUBJECT.get() or name)
    try:
        yield
    finally:
        _SUBJECT.reset(token)


def elapsed_text(seconds: float) -> str:
    """``7 s``, ``1:05``, ``1:02:03``: a duration as a progress line shows it."""
    whole = int(seconds)
    if whole < 60:
        return f"{whole} s"
    minutes, secs = divmod(whole, 60)
    if minutes < 60:
        return f"{minutes}:{secs:02d}"
    hours, minutes = divmod(minutes, 60)
    return f"{hours}:{minutes:02d}:{secs:02d}"


def clock_text(seconds: float) -> str:
    """``0:35``, ``12:05``, ``1:02:03``: a time left as a batch line shows it (whole seconds, rounded up)."""
    whole = max(0, int(-(-seconds // 1)))
    minutes, secs = divmod(whole, 60)
    if minutes < 60:
        return f"{minutes}:{secs:02d}"
    hours, minutes = divmod(minutes, 60)
    return f"{hours}:{minutes:02d}:{secs:02d}"


@dataclass(frozen=True, slots=True)
class Tick:
    """Where a batch stands after one more item finished.

    Attributes:
        done: Items finished (from a cache included), 1 to ``total``.
        total: Items in the batch.
        last: The name of the item that just finished (as the command names it: a file, a run).
        elapsed_s: Seconds since the batch started (its :class:`Meter` was made).
        rate: Items per second over the items this batch computed (not those answered from a cache), or
            ``None`` before the first.
        eta_s: Seconds left at that rate (``0`` when done), or ``None`` without a rate.
    """

    done: int
    total: int
    last: str
    elapsed_s: float
    rate: float | None
    eta_s: float | None

    def line(self) -> str:
        """``[ 37/120] 31%  2.4 items/s  eta 0:35  last: NAME``: the batch line of every batch command."""
        width = len(str(self.total))
        percent = 100 * self.done // self.total if self.total else 100
        rate = "- items/s" if self.rate is None else f"{self.rate:.1f} items/s"
        eta = "-" if self.eta_s is None else clock_text(self.eta_s)
        return f"[{self.done:>{width}}/{self.total}] {percent}%  {rate}  eta {eta}  last: {self.last}"


#: ``sink(tick)``: what a batch calls after each finished item.
TickSink = Callable[[Tick], None]


class Meter:
    """Counts a batch's finished items and tells ``sink`` a :class:`Tick` after each.

    Args:
        total: Items in the batch.
        sink: The callback (``None``: count only).
        clock: Monotonic seconds (for tests).
    """

    def __init__(self, total: int, sink: TickSink | None = None, clock: Callable[[], float] = time.monotonic) -> None:
        self.total = total
        self.sink = sink
        self.clock = clock
        self.started = clock()
        self.done = 0
        self.computed = 0

    def advance(self, last: str, *, computed: bool = True) -> Tick:
        """One more item finished (``computed``: by this batch, not answered from a cache); its tick."""
        self.done += 1
        self.computed += computed
        elapsed = self.clock() - self.started
        rate = self.computed / elapsed if self.computed and elapsed > 0 else None
        left = self.total - self.done
        eta = 0.0 if left <= 0 else (left / rate if rate else None)
        tick = Tick(self.done, self.total, last, elapsed, rate, eta)
        if self.sink is not None:
            self.sink(tick)
        return tick


class Display:
    """A progress line on a terminal: ``| head.obj: collision hulls 2/5  12 s``, redrawn in place.

    Use it as a :data:`Sink` (``display(stage, done, total)``). The first call starts a ticker thread that
    redraws the line every :data:`TICK_S` seconds (spinner and elapsed time move while the work runs in C
    code or a child process); :meth:`close` stops it and clears the line. Every write to the stream goes
    through one lock, so the ticker never draws into the middle of other output.

    Args:
        stream: The terminal (stderr).
        enabled: Draw at all; ``None``: only when ``stream`` is a terminal.
        clock: Monotonic seconds (for tests).
    """

    def __init__(
        self, stream: TextIO, enabled: bool | None = None, clock: Callable[[], float] = time.monotonic
    ) -> None:
        self.stream = stream
        self.enabled = _is_terminal(stream) if enabled is None else enabled
        self.clock = clock
        self._lock = threading.RLock()
        self._label = ""
        self._count = ""
        self._batch = ""
        self._since = 0.0
        self._frame = 0
        self._shown = False
        self._stop = threading.Event()
        self._ticker: threading.Thread | None = None

    def __call__(self, stage: str, done: int = 0, total: int = 0) -> None:
        """Show ``stage`` (and ``done/total`` when ``total``); the elapsed time restarts with a new stage."""
        if not self.enabled:
            return
        count = f" {done}/{total}" if total else ""
        with self._lock:
            if stage == self._label and count == self._count and self._shown:
                return  # nothing new: the ticker keeps the line moving
            if stage != self._label:
                self._label, self._since = stage, self.clock()
            self._count = count
            self._draw()
        self._start_ticker()

    def batch(self, text: str | None) -> None:
        """Lead the line with ``text`` (a batch's :meth:`Tick.line`; ``None``: none); drawn on the next tick.

        The first one is drawn at once. A stage reported meanwhile follows it after `` -- ``.
        """
        if not self.enabled:
            return
        with self._lock:
            first = not self._batch and not self._shown
            self._batch = text or ""
            if first and self._batch:
                self._draw()
        self._start_ticker()

    def _start_ticker(self) -> None:
        with self._lock:
            if self._ticker is None:
                self._ticker = threading.Thread(target=self._tick, name="meshtool-progress", daemon=True)
                self._ticker.start()

    def line(self) -> str:
        """The progress line as drawn now (without the clearing sequence), cut to the terminal's width."""
        spinner = FRAMES[self._frame % len(FRAMES)]
        stage = f"{self._label}{self._count}  {elapsed_text(self.clock() - self._since)}" if self._label else ""
        shown = f"{self._batch} -- {stage}" if self._batch and stage else self._batch or stage
        text = f"{spinner} {shown}"
        width = shutil.get_terminal_size((80, 24)).columns
        return text if len(text) < width else text[: max(width - 2, 1)] + "~"  # a wrapped line cannot be cleared

    def _draw(self) -> None:
        self.stream.write(CLEAR + self.line())
        self.stream.flush()
        self._shown = True

    def _tick(self) -> None:
        while not self._stop.wait(TICK_S):
            with self._lock:
                if self._label or self._batch:
                    self._frame += 1
                    self._draw()

    def clear(self) -> None:
        """Clear the line (the ticker draws it again on its next tick while the work goes on)."""
        with self._lock:
            if self._shown:
                self.stream.write(CLEAR)
                self.stream.flush()
                self._shown = False

    def write_above(self, target: TextIO, text: str) -> int:
        """Write ``text`` to ``target`` (stdout or stderr of the same terminal) with the line cleared first."""
        with self._lock:
            self.clear()
            written = target.write(text)
            target.flush()
            return written

    def close(self) -> None:
        """Stop the ticker and clear the line."""
        self._stop.set()
        if self._ticker is not None:
            self._ticker.join()
            self._ticker = None
        with self._lock:
            self._label = self._batch = ""
            self.clear()


def _is_terminal(stream: TextIO) -> bool:
    try:
        return stream.isatty()
    except (AttributeError, ValueError):
        return False
