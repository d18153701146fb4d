"""Trailing comments on OBJ and MTL statements: ``Kd 1.000 1.000 1.000  # white``.

Neither format defines comments after a statement, yet exporters and hand edits write them. Two rules keep
data intact:

* numeric statements (colours, scalars, ``illum``, ``s``): a ``#`` that starts a word ends the statement
  (a number never starts with ``#``; ``1.#IND`` does not start with it);
* names and file names (``newmtl``, ``usemtl``, ``o``, ``g``, ``mtllib``, ``map_*``): only a ``#`` after
  whitespace and followed by whitespace or the end of the line ends the statement, so ``Material #25``
  and ``tex #2.png`` keep their ``#``.
"""

from __future__ import annotations

import re

_NUMERIC_COMMENT = re.compile(r"(?:^|\s)#")
_NAME_COMMENT = re.compile(r"(?:^|\s)#(?:\s|$)")


def strip_numeric_comment(text: str) -> str:
    """``text`` up to a trailing comment of a numeric statement, right-stripped.

    Args:
        text: The arguments of a statement (everything after its keyword).

    Returns:
        The arguments without the comment.
    """
    match = _NUMERIC_COMMENT.search(text)
    return (text[: match.start()] if match else text).rstrip()


def strip_name_comment(text: str) -> str:
    """``text`` up to a trailing ``# comment`` of a name statement, right-stripped.

    Args:
        text: The arguments of a statement (everything after its keyword).

    Returns:
        The arguments without the comment; ``#`` inside a name (``Material #25``) is kept.
    """
    match = _NAME_COMMENT.search(text)
    return (text[: match.start()] if match else text).rstrip()


def strip_statement_comment(line: str) -> str:
    """A whole OBJ statement line without its trailing comment (the keyword decides the rule).

    Args:
        line: One line, keyword first.

    Returns:
        The line without the trailing comment; a line that is only a comment becomes empty.
    """
    stripped = line.lstrip()
    if stripped.startswith("#"):
        return ""
    keyword, _, rest = stripped.partition(" ")
    if "\t" in keyword:
        keyword, _, tail = keyword.partition("\t")
        rest = f"{tail} {rest}" if rest else tail
    if keyword in _NAME_KEYWORDS:
        return f"{keyword} {strip_name_comment(rest)}".rstrip()
    return f"{keyword} {strip_numeric_comment(rest)}".rstrip()


_NAME_KEYWORDS = frozenset({"o", "g", "usemtl", "mtllib", "newmtl"})
