"""Source rules (S...), and the normaliser's findings translated into rule findings.

The validator reads an OBJ exactly as ``meshtool normalize`` does (:func:`meshtool.repair.normalise.prepare`, in
memory) and turns what the normaliser noticed into rule findings: a missing texture is a repair for the
normaliser but a defect of the source for the validator.

Findings are judged by what the OBJ's consumer reads: when every description file that uses it is an MJCF
(MuJoCo reads an OBJ's geometry only, never its MTL or the textures the MTL names), a missing MTL (S002) or
texture (S003) loses nothing the consumer loads and is a warning that says so; with no consumer (the OBJ is
the asset) or a consumer that reads materials (URDF and SDFormat: RViz, Gazebo and simrun's ``UrdfRobot``
read the MTL), it stays an error.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Sequence
from typing import Any

from meshtool.files.safeopen import printable
from meshtool.findings import Finding, Severity
from meshtool.frame.consumers import ConsumerRef
from meshtool.validate.rules import hit

#: Normaliser finding code -> rule ID (codes not listed are repairs that need no attention).
FROM_NORMALISER: dict[str, str] = {
    "mtl-missing": "S002",
    "mtl-not-a-file": "S002",
    "texture-missing": "S003",
    "texture-not-a-file": "S003",
    "texture-unreadable": "S003",
    "texture-trailing-data": "S005",
    "material-undefined": "S004",
    "texture-converted": "S005",
    "reference-outside-root": "S008",
    "consumer-frames-differ": "S014",
    "consumer-index-limit": "S015",
    "encoding-latin1": "S010",
    "unknown-statement": "S011",
    "usemtl-empty": "S011",
    "mtllib-empty": "S011",
    "vertex-extra-values": "S011",
    "vertex-colors-partial": "S011",
    "vertex-colors-invalid": "S011",
    "face-too-small": "S011",
    "vt-missing": "S011",
    "vn-missing": "S011",
    "vt-index-out-of-range": "S011",
    "vn-index-out-of-range": "S011",
    "texcoords-partial": "S011",
    "mtl-statement-invalid": "S011",
    "mtl-statement-outside-material": "S011",
    "material-duplicate": "S011",
    "mtl-reference-empty": "S011",
    "texture-reference-empty": "S011",
    "non-finite-vertices": "G001",
    "no-faces": "G002",
    "degenerate-faces": "G003",
    "part-padded": "G012",
    "scale-suspicious": "U001",
    "stl-normals-disagree": "S012",
    "stl-trailing-data": "S011",
    "stl-endsolid-missing": "S011",
    "colors-invalid": "S011",
    "texture-coordinates-invalid": "S011",
    "normals-invalid": "S011",
}

_ABSOLUTE = re.compile(r"^([A-Za-z]:[\\/]|[\\/]|[A-Za-z][A-Za-z0-9+.-]*://)")
_SAFE_NAME = re.compile(r"^[A-Za-z0-9_.\-/]+$")
_RAW_BYTE = re.compile(r"\\x([89a-f][0-9a-f])")  # a byte that is not UTF-8, as printable() shows it
_REPAIRED = ("backslash", "case-insensitive", "basename", "search-path")


#: Rules about the MTL and its textures: judged by whether the OBJ's consumers read them.
MATERIAL_RULES = ("S002", "S003")


def from_normaliser(findings: Iterable[Finding], consumers: Sequence[ConsumerRef] = ()) -> list[Finding]:
    """Rule findings for the normaliser's findings (missing files reached by an escape are reported once).

    Args:
        findings: The normaliser's findings.
        consumers: The description files that use the OBJ (:func:`meshtool.frame.consumers.find_consumers`): when
            there are some and none reads materials, S002/S003 are warnings naming the nearest one.
    """
    found = list(findings)
    escaped = {(f.path, f.line) for f in found if f.code == "reference-outside-root"}
    unread = bool(consumers) and not any(c.reads_materials for c in consumers)
    out = []
    for f in found:
        rule = FROM_NORMALISER.get(f.code)
        if rule is None:
            continue
        if f.code in ("mtl-missing", "texture-missing") and (f.path, f.line) in escaped:
            continue  # the escape (S008) is the cause; "not found" would repeat it
        if unread and rule in MATERIAL_RULES:
            first = consumers[0]
            more = f" and {len(consumers) - 1} more" if len(consumers) > 1 else ""
            said = (
                f"{f.message}; not read by its consumer {first.file}{more} "
                f"({first.format.upper()}: MuJoCo reads no MTL or texture of an OBJ)"
            )
            out.append(hit(rule, said, f.path, f.line, Severity.WARNING))
            continue
        out.append(hit(rule, f.message, f.path, f.line))
    return out


def reference_findings(resolutions: Iterable[dict[str, Any]]) -> list[Finding]:
    """S006 (absolute) and S007 (needed repair) for the references recorded in ``asset.json`` form."""
    out = []
    for r in resolutions:
        origin, _, line_text = str(r["from"]).rpartition(":")
        line = int(line_text) if line_text.isdigit() else None
        ref = str(r["ref"]).strip()
        if _ABSOLUTE.match(ref):
            out.append(hit("S006", f"{r['kind']} reference '{ref}' is absolute", origin, line))
        elif r["found"] is not None and r["rule"] in _REPAIRED:
            out.append(
                hit(
                    "S007",
                    f"{r['kind']} reference '{ref}' only resolves as '{r['found']}' (rule: {r['rule']})",
                    origin,
                    line,
                )
            )
    return out


def name_findings(names: Iterable[str]) -> list[Finding]:
    r"""S009 for every file name (relative paths, ``/``-separated) with unsafe characters.

    A name's bytes that are not UTF-8 (surrogate escapes, or ``\xNN`` as :func:`printable` spells them)
    are named as bytes.
    """
    out = []
    for name in sorted({printable(n) for n in names}):
        if name.startswith("<") or _SAFE_NAME.match(name):
            continue
        raw = sorted(set(_RAW_BYTE.findall(name)))
        bad = sorted({c for c in _RAW_BYTE.sub("", name) if not _SAFE_NAME.match(c)})
        shown = " ".join([*(f"byte 0x{b} (not UTF-8)" for b in raw), *("space" if c == " " else repr(c) for c in bad)])
        out.append(hit("S009", f"file name '{name}' has unsafe characters: {shown}", name))
    return out


def encoding_findings(name: str, data: bytes) -> list[Finding]:
    """S010 for a byte-order mark or UTF-16 text (Latin-1 comes from the parser's finding)."""
    if data.startswith((b"\xff\xfe", b"\xfe\xff")):
        return [hit("S010", "the file is UTF-16 text; most tools read OBJ/MTL as UTF-8 or ASCII", name)]
    if data.startswith(b"\xef\xbb\xbf"):
        return [hit("S010", "the file starts with a UTF-8 byte-order mark, which some OBJ readers choke on", name)]
    return []
