"""A bound on how deeply the TOML and JSON documents users hand in may nest.

Python's parsers (``tomllib``, ``json``) recurse once per level: a 1 KB file ``x = [[[[...]]]]`` of a few
hundred levels exhausts the interpreter's stack and raises ``RecursionError``, which no caller expects.
:func:`bounded` runs a parse, turns that into a :class:`NestingError`, and refuses documents that parsed
but nest deeper than :data:`MAX_NESTING` levels, so the answer does not depend on how deep the caller's
stack happened to be. Every configuration, scene, commands file, recording header and glTF JSON that
meshtool and simrun read goes through it (docs/limits.md).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

#: Most levels of arrays and tables (objects) inside each other in a document read from a file.
MAX_NESTING = 64

T = TypeVar("T")


class DocumentLimitError(ValueError):
    """A document is past one of the bounds of this module; the message says which, in one line."""


class NumberTooLongError(DocumentLimitError):
    """A number in the document has more digits than Python converts (``sys.get_int_max_str_digits``, 4300)."""

    def __init__(self, detail: str) -> None:
        super().__init__(f"a number in it is too long ({detail}); write it with fewer digits")


class NestingError(DocumentLimitError):
    """A document nests arrays and tables deeper than the limit; the message says so in one line."""

    def __init__(self, limit: int = MAX_NESTING) -> None:
        self.limit = limit
        super().__init__(
            f"nested more than {limit} levels deep (arrays or tables inside each other); "
            "flatten the structure (the nesting limit is in docs/limits.md)"
        )


def bounded(parse: Callable[[], T], limit: int = MAX_NESTING) -> T:
    """Run ``parse`` (a ``tomllib.loads`` or ``json.loads`` call) with the nesting bounded.

    Args:
        parse: Parses the document and returns it.
        limit: Most levels of nesting accepted.

    Returns:
        What ``parse`` returned.

    Raises:
        NestingError: The document nests deeper than ``limit`` (also when the parser ran out of stack).
        NumberTooLongError: An integer has more digits than Python converts (a 5,000-digit TOML or JSON
            integer makes the parser raise a plain ``ValueError``, not its syntax error).
        Exception: Whatever ``parse`` raises for other reasons (its own syntax errors).
    """
    try:
        value = parse()
    except RecursionError:
        raise NestingError(limit) from None
    except ValueError as exc:
        if type(exc) is ValueError and "integer string conversion" in str(exc):  # int()'s digit limit
            raise NumberTooLongError(str(exc).split(";")[0].lower()) from None
        raise
    if nesting_depth(value, limit) > limit:
        raise NestingError(limit)
    return value


def nesting_depth(value: Any, stop: int | None = None) -> int:
    """Levels of lists and dicts inside each other in ``value`` (``0`` for a scalar), without recursion.

    Args:
        value: A parsed document.
        stop: Stop counting once the depth exceeds this (the result is then ``stop + 1``).
    """
    best = 0
    stack: list[tuple[Any, int]] = [(value, 1)]
    while stack:
        item, depth = stack.pop()
        if isinstance(item, dict):
            children: Any = item.values()
        elif isinstance(item, list):
            children = item
        else:
            continue
        best = max(best, depth)
        if stop is not None and best > stop:
            return stop + 1
        stack.extend((c, depth + 1) for c in children if isinstance(c, dict | list))
    return best
