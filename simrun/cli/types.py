"""Parameter types the ``simrun`` commands share (click types that refuse NaN, durations, frame rates, outputs).

Also the render modes and image size (``--render-mode``, ``--size WxH``) of play, replay and snapshot.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import click


class Number(click.ParamType):  # type: ignore[type-arg]
    """A finite float in [low, high] (click's FloatRange lets NaN through)."""

    name = "number"

    def __init__(self, low: float, high: float, low_open: bool = False) -> None:
        self.low, self.high, self.low_open = low, high, low_open

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> float:
        """``value`` as a float, or click's usage error naming the option and the range."""
        try:
            number = float(value)
        except (TypeError, ValueError):
            self.fail(f"{value!r} is not a number", param, ctx)
        below = number <= self.low if self.low_open else number < self.low
        if not math.isfinite(number) or below or number > self.high:
            bracket = "(" if self.low_open else "["
            self.fail(f"{value!r} is not in {bracket}{self.low:g}, {self.high:g}]", param, ctx)
        return number


#: Longest simulated run from the command line (one day), seconds.
MAX_SECONDS = 86400.0
SECONDS = Number(0.0, MAX_SECONDS)
FPS = Number(0.0, 1000.0, low_open=True)
#: An output file (not a folder).
OUT = click.Path(path_type=Path, dir_okay=False)


#: Render modes (simrun.run.render.MODES, which imports MuJoCo; tests/test_perf_startup.py checks they agree).
MODES = ("visual", "wireframe", "physics", "combined", "none")
#: The default image size (simrun.run.session.DEFAULT_SIZE, checked equal by tests/test_perf_startup.py).
DEFAULT_SIZE = (640, 480)
#: The one default image size of play, replay and snapshot (docs/cli.md).
DEFAULT_SIZE_TEXT = f"{DEFAULT_SIZE[0]}x{DEFAULT_SIZE[1]}"


def _size(text: str) -> tuple[int, int]:
    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise click.BadParameter(f"expected WxH, got {text!r}") from None
    if not (16 <= width <= 4096 and 16 <= height <= 4096):
        raise click.BadParameter("width and height must be 16..4096")
    return width, height
