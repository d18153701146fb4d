"""Progress of long work on one file (stages of a conversion, parts of a decomposition), for a display.

The library never prints: it calls :func:`report`, which does nothing unless a caller (the CLI) installed a
sink with :func:`reporting`. The CLI's sink draws on stderr, and only when stderr is a terminal
(:class:`meshtool.cli_common.Progress`).
"""

from __future__ import annotations

import contextlib
import contextvars
from collections.abc import Callable, Iterator

#: ``sink(stage, done, total)``; ``total`` 0 when the stage has no count.
Sink = Callable[[str, int, int], None]
_SINK: contextvars.ContextVar[Sink | None] = contextvars.ContextVar("meshtool_progress", default=None)


def report(stage: str, done: int = 0, total: int = 0) -> None:
    """Tell the installed sink (if any) that ``stage`` is under way, ``done`` of ``total`` items."""
    sink = _SINK.get()
    if sink is not None:
        sink(stage, done, total)


@contextlib.contextmanager
def reporting(sink: Sink | None) -> Iterator[None]:
    """Send :func:`report` calls in this context to ``sink``."""
    token = _SINK.set(sink)
    try:
        yield
    finally:
        _SINK.reset(token)
