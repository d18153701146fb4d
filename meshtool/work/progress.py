r"""Progress of long work (stages of a conversion, parts of a decomposition, a simulation), for a display.

The library never prints: it calls :func:`report`, which does nothing unless a caller (the CLI) installed a
sink with :func:`reporting`. What a report is about (the file being converted) is set once around the work
with :func:`subject`, and every report inside names it (``head.obj: collision hulls``).

:class:`Display` is the command line's sink: one line on a terminal's stderr with a spinner, the file, the
stage, ``done/total`` and the time the stage has taken, redrawn in place (``\r\x1b[K``) ten times a second
by a ticker thread, so the line moves while CoACD or MuJoCo work and no report comes. It draws nothing when
the stream is not a terminal (a pipe, a log, ``--json``) or with ``-q``; output written through
:meth:`Display.write_above` clears the line first, so text never runs into it.
"""

from __future__ import annotations

import contextlib
import contextvars
import shutil
import threading
import time
from collections.abc import Callable, Iterator
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
        if self._ticker is None:
            self._ticker = threading.Thread(target=self._tick, name="meshtool-progress", daemon=True)
            self._ticker.start()

    def line(self) -> str:
        """The progress line as drawn now (without the clearing sequence), cut to the terminal's width."""
        spinner = FRAMES[self._frame % len(FRAMES)]
        text = f"{spinner} {self._label}{self._count}  {elapsed_text(self.clock() - self._since)}"
        width = shutil.get_terminal_size((80, 24)).columns
        return text if len(text) < width else text[: max(width - 2, 1)] + "~"  # a wrapped line cannot be cleared

    def _draw(self) -> None:
        self.stream.write(CLEAR + self.line())
        self.stream.flush()
        self._shown = True

    def _tick(self) -> None:
        while not self._stop.wait(TICK_S):
            with self._lock:
                if self._label:
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
            self._label = ""
            self.clear()


def _is_terminal(stream: TextIO) -> bool:
    try:
        return stream.isatty()
    except (AttributeError, ValueError):
        return False
