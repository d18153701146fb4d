"""Bounded parse of COLLADA XML, and the element helpers the COLLADA modules share.

- :func:`parse_xml`: lxml with no DTD, no entities and no network, at most :data:`MAX_ELEMENTS` elements
  and 2,048 levels of nesting (libxml2's own limit).
"""

from __future__ import annotations

import copy
import importlib
from collections.abc import Iterator
from typing import Any

from meshtool.errors import FormatError

etree: Any = importlib.import_module("lxml.etree")  # installed with pycollada and yourdfpy; no type stubs
#: XML elements one COLLADA file may have (about 0.5 GB of parsed tree).
MAX_ELEMENTS = 1_000_000
_CHUNK = 1 << 16
DAMAGED = "the COLLADA file is damaged; export it again"


def parse_xml(data: bytes, path: str) -> Any:
    """Parse ``data`` with no DTD, entities or network, at most :data:`MAX_ELEMENTS` elements.

    Returns:
        The root element (``COLLADA``).

    Raises:
        FormatError: Not well-formed XML, a DOCTYPE, too many or too deeply nested elements, not COLLADA.
    """
    parser = etree.XMLPullParser(
        events=("start",),
        huge_tree=True,  # float arrays over 10 MB of text are genuine; depth stays capped at 2,048
        resolve_entities=False,
        no_network=True,
        load_dtd=False,
        remove_comments=True,
        remove_pis=True,
    )
    count = 0
    try:
        for start in range(0, len(data), _CHUNK):
            parser.feed(data[start : start + _CHUNK])
            for _, element in parser.read_events():
                count += 1
                if count > MAX_ELEMENTS:
                    raise FormatError(
                        f"COLLADA with more than {MAX_ELEMENTS:,} XML elements is not read",
                        path=path,
                        line=element.sourceline,
                        hint="check the file; split a genuine model this large",
                        code="expansion-limit",
                    )
        root = parser.close()
    except etree.XMLSyntaxError as exc:
        text = str(exc).splitlines()[0][:120] if str(exc) else type(exc).__name__
        if "Excessive depth" in text:
            text = "elements nested more than 2,048 deep"
        raise FormatError(
            f"COLLADA cannot be read: {text}", path=path, line=exc.lineno, hint="the file is damaged"
        ) from None
    docinfo = root.getroottree().docinfo
    if docinfo.doctype or docinfo.internalDTD is not None:
        raise FormatError(
            "COLLADA with a DOCTYPE or ENTITY declaration is not read (entities could read or expand files "
            "outside the asset)",
            path=path,
            hint="remove the declaration; COLLADA files need none",
        )
    if not isinstance(root.tag, str) or etree.QName(root).localname != "COLLADA":
        raise FormatError("not a COLLADA document: the root element is not <COLLADA>", path=path, line=root.sourceline)
    return root


def subset(root: Any, names: tuple[str, ...]) -> bytes:
    """The document with only the top-level elements named ``names`` (what pycollada is given to read)."""
    kept = etree.Element(root.tag, attrib=dict(root.attrib), nsmap=root.nsmap)
    for element in root:
        if local(element) in names:
            kept.append(copy.deepcopy(element))
    return bytes(etree.tostring(kept))


def local(element: Any) -> str:
    """The element's tag without its namespace (``""`` for comments and the like)."""
    tag = element.tag
    if not isinstance(tag, str):
        return ""
    return tag.rpartition("}")[2]


def children(element: Any, name: str) -> Iterator[Any]:
    """Child elements of ``element`` named ``name`` (any namespace), in document order."""
    return (c for c in element if local(c) == name)


def child(element: Any, name: str) -> Any:
    """The first child element named ``name``, or ``None``."""
    return next(children(element, name), None)


def fail(message: str, path: str, element: Any, hint: str = DAMAGED) -> FormatError:
    """The error ``message`` about ``element``, at its line (raised by the caller)."""
    return FormatError(message, path=path, line=element.sourceline, hint=hint)


def describe(element: Any) -> str:
    """``<float_array id='x'>`` or ``<triangles>``: the element as a message names it."""
    ident = str(element.get("id") or element.get("sid") or "")[:60]
    return f"<{local(element)} id='{ident}'>" if ident else f"<{local(element)}>"


__all__ = ["DAMAGED", "MAX_ELEMENTS", "child", "children", "describe", "fail", "local", "parse_xml", "subset"]
