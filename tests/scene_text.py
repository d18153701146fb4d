"""The tests' small Boe-Bot scene as TOML text, written once: ground, a Boe-Bot, a drive service, and what a test adds.

For the seed's full Boe-Bot scene (sky, box, sun, camera) use the fixture ``fixtures/scenes/boebot.toml``
(``serve_helpers.SCENES / "boebot.toml"``); this text is the bare variant that tests build their own worlds on.
"""

from __future__ import annotations

_HEAD = """[world]
timestep = 0.002

[[entities]]
type = "Ground"
name = "ground"

[[entities]]
type = "BoeBot"
name = "boebot"
pose = {{ position = [{x!r}, {y!r}, 0.001] }}
"""
_DRIVE = """
[[services]]
type = "DriveService"
entity = "boebot"
"""


def boebot_scene(
    at: tuple[float, float] = (0.0, 0.0), *, entities: str = "", drive: bool = True, tail: str = ""
) -> str:
    """Scene text: 2 ms timestep, a ground ``ground``, a Boe-Bot ``boebot`` on it at ``at`` (x, y in m, world frame;
    z 1 mm), then ``entities`` (TOML text, each table starting with a blank line), a ``DriveService`` for the
    Boe-Bot when ``drive``, then ``tail`` (TOML text: more entities, services or sensors)."""
    x, y = (float(v) for v in at)
    return _HEAD.format(x=x, y=y) + entities + (_DRIVE if drive else "") + tail
