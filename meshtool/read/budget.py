"""How much geometry one mesh file may expand to, counted before the work is done.

A few hundred bytes of glTF (accessors with huge counts and no buffer, one buffer view reused by thousands of
primitives) or of COLLADA (``<instance_node>`` fan-out, a "billion laughs" without a DTD) can describe
billions of triangles. Readers add what a primitive, an instance or a node *will* produce to an
:class:`ExpansionBudget` before allocating anything for it, so such a file is refused in time proportional
to its size, with one error line naming the file and what overflowed.

The limits default to :data:`MAX_TRIANGLES` and :data:`MAX_VERTICES`; the environment variables
``MESHTOOL_MAX_TRIANGLES`` and ``MESHTOOL_MAX_VERTICES`` raise or lower them for a genuine large file
(``docs/limits.md``). A COLLADA visual scene may also place at most :data:`MAX_INSTANCES` node and
primitive instances (``MESHTOOL_MAX_INSTANCES``), however few triangles they carry. :func:`limit_from_env`
reads such a variable.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

from meshtool.errors import FormatError

#: Triangles one mesh file may expand to, over all its primitives, instances and nodes (2^24).
MAX_TRIANGLES = 1 << 24
#: Vertices one mesh file may expand to (three per triangle of an unindexed mesh).
MAX_VERTICES = 3 << 24
TRIANGLES_ENV = "MESHTOOL_MAX_TRIANGLES"
VERTICES_ENV = "MESHTOOL_MAX_VERTICES"
#: Nodes placed plus primitives placed that one visual scene may expand to (instances, not triangles).
MAX_INSTANCES = 100_000
INSTANCES_ENV = "MESHTOOL_MAX_INSTANCES"


def limit_from_env(name: str, default: int) -> int:
    """The positive integer in environment variable ``name``, else ``default``.

    Raises:
        FormatError: The variable is set but not a positive integer.
    """
    text = os.environ.get(name, "").strip()
    if not text:
        return default
    if not text.isascii() or not text.isdigit() or int(text) <= 0:
        raise FormatError(
            f"environment variable {name}={text!r} is not a positive whole number", hint=f"unset {name} or fix it"
        )
    return int(text)


@dataclass(slots=True)
class ExpansionBudget:
    """Triangles and vertices still allowed for one file.

    Attributes:
        path: The file, for messages.
        max_triangles: Triangles allowed in all.
        max_vertices: Vertices allowed in all.
        triangles: Triangles charged so far.
        vertices: Vertices charged so far.
    """

    path: str
    max_triangles: int
    max_vertices: int
    triangles: int = 0
    vertices: int = 0

    @classmethod
    def for_file(cls, path: str) -> ExpansionBudget:
        """A fresh budget with the configured limits (environment variables, else the defaults).

        Raises:
            FormatError: A limit variable is set to something other than a positive integer.
        """
        return cls(path, limit_from_env(TRIANGLES_ENV, MAX_TRIANGLES), limit_from_env(VERTICES_ENV, MAX_VERTICES))

    def charge(self, triangles: int, vertices: int, what: str, *, offset: int | None = None) -> None:
        """Count ``triangles`` and ``vertices`` that ``what`` is about to produce, before producing them.

        Args:
            triangles: Triangles it adds (``count * instances``, computed with Python integers).
            vertices: Vertices it adds.
            what: Where they come from, for the message (``mesh 3 primitive 0``, ``node 'arm' instance 12``).
            offset: Byte offset of the element in the file, when known.

        Raises:
            FormatError: The running total passes a limit (code ``expansion-limit``).
        """
        self.triangles += max(int(triangles), 0)
        self.vertices += max(int(vertices), 0)
        if self.triangles > self.max_triangles:
            self._refuse("triangles", self.triangles, self.max_triangles, TRIANGLES_ENV, what, offset)
        if self.vertices > self.max_vertices:
            self._refuse("vertices", self.vertices, self.max_vertices, VERTICES_ENV, what, offset)

    def _refuse(self, kind: str, total: int, limit: int, env: str, what: str, offset: int | None) -> None:
        raise FormatError(
            f"expands to more than {limit:,} {kind} (at least {total:,} with {what}); not read",
            path=self.path,
            offset=offset,
            hint=f"check the file; for a genuine mesh this large set {env}",
            code="expansion-limit",
        )


__all__ = [
    "INSTANCES_ENV",
    "MAX_INSTANCES",
    "MAX_TRIANGLES",
    "MAX_VERTICES",
    "TRIANGLES_ENV",
    "VERTICES_ENV",
    "ExpansionBudget",
    "limit_from_env",
]
