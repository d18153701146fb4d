"""The rules of ``meshtool validate``: stable IDs, default severities and fix hints.

Every rule has an ID (a category letter and three digits, never reused), a kebab-case name (accepted in
configuration as well), a default severity, a one-line summary and a hint. ``docs/validate-rules.md``
documents each of them; a test keeps the two in step.

A rule's finding is a :class:`meshtool.findings.Finding` whose ``code`` is the rule ID.
"""

from __future__ import annotations

from dataclasses import dataclass

from meshtool.findings import Finding, Severity

E, W, I = Severity.ERROR, Severity.WARNING, Severity.INFO  # noqa: E741

CATEGORIES = {
    "S": "source",
    "G": "geometry",
    "U": "scale",
    "C": "collision",
    "P": "physics",
    "K": "pack",
    "X": "tool",
}


@dataclass(frozen=True, slots=True)
class Rule:
    """One validation rule.

    Attributes:
        id: Stable identifier, e.g. ``G005``.
        name: Kebab-case name, e.g. ``winding-inconsistent``.
        severity: Default severity.
        summary: What the rule checks, one line.
        hint: How to fix what it finds, one line.
    """

    id: str
    name: str
    severity: Severity
    summary: str
    hint: str

    @property
    def category(self) -> str:
        """``source``, ``geometry``, ``scale``, ``collision``, ``physics``, ``pack`` or ``tool``."""
        return CATEGORIES[self.id[0]]


_TABLE: list[tuple[str, str, Severity, str, str]] = [
    ("S001", "obj-unreadable", E, "the OBJ cannot be read or has no usable geometry", "fix the file at the place named, or export it again"),
    ("S002", "mtl-missing", E, "an MTL library the OBJ names is not found", "add the MTL file next to the OBJ or fix the mtllib line"),
    ("S003", "texture-missing", E, "a texture an MTL names is missing or cannot be decoded", "add the image next to the MTL, or re-save it as PNG"),
    ("S004", "material-undefined", W, "faces use a material no MTL defines", "define the material in the MTL or fix the usemtl name"),
    ("S005", "texture-format", W, "a texture is not an 8-bit PNG (MuJoCo reads PNG and KTX only)", "convert it to PNG (meshtool normalize does)"),
    ("S006", "path-absolute", W, "a reference is an absolute path (C:\\..., /home/..., file://)", "make the reference relative to the file that names it"),
    ("S007", "path-foreign", W, "a reference only resolves after repair (backslashes, wrong case, other folder)", "write the path as it is on disk, with forward slashes"),
    ("S008", "path-outside", E, "a reference points outside the asset folder", "move the file into the asset folder and reference it relatively"),
    ("S009", "name-unsafe", W, "a file name has spaces, non-ASCII or shell-special characters", "rename to letters, digits, _ . - only"),
    ("S010", "encoding", W, "an OBJ or MTL is not plain UTF-8 (Latin-1, UTF-16, byte-order mark)", "re-save the file as UTF-8 without BOM"),
    ("S011", "syntax", W, "malformed or partial statements were dropped", "fix the lines named, or export again"),
    ("S012", "facet-normals", W, "STL facet normals point against their facets' winding (tools disagree on the outside)", "recalculate normals outside in the modeller and export again"),
    ("S013", "buffer-missing", E, "a glTF buffer is missing, outside the asset folder or too short: no geometry", "put the .bin beside the .gltf, or export a single .glb"),
    ("S014", "consumer-frames-differ", W, "description files (URDF, SDF, MJCF) use the mesh in different frames (scales)", "make every consumer use the mesh at one scale, or give each its own copy"),
    ("S015", "consumer-index-limit", W, "the search for the mesh's consumer files stopped at a limit: its frame may be the wrong one", "pass --model-root with a smaller folder, or move the description files nearer the meshes"),
    ("G001", "non-finite", E, "vertices with NaN or infinite coordinates", "fix or delete those vertices"),
    ("G002", "no-faces", W, "the file has vertices but no faces: usable only as a convex collision hull", "export the faces, not only points or lines"),
    ("G003", "degenerate-faces", W, "triangles with a repeated vertex or zero area", "clean the mesh (merge by distance, delete degenerate)"),
    ("G004", "duplicate-faces", W, "the same triangle appears more than once", "delete the duplicate faces"),
    ("G005", "winding-inconsistent", W, "neighbouring faces wind in opposite directions", "recalculate normals outside in the modeller"),
    ("G006", "inside-out", W, "a closed mesh whose faces all point inwards (negative volume)", "flip all normals"),
    ("G007", "open-mesh", W, "the mesh has boundary edges: volume, mass and inertia are approximate", "close the holes, or give the mass explicitly"),
    ("G008", "non-manifold", W, "edges shared by more than two faces", "split or clean the non-manifold edges"),
    ("G009", "coplanar", W, "all vertices lie in one plane: no volume, collision hulls get thickened", "use a solid, or treat it as visual only"),
    ("G010", "tiny-volume", W, "a closed mesh with almost no volume (under 1 mm^3 or a sliver of its box)", "check the scale, or model the part as a solid"),
    ("G011", "vertex-count", W, "more vertices than the budget (limits.max-vertices)", "decimate the mesh, or raise the budget"),
    ("G012", "part-padded", W, "a part with fewer than 4 distinct vertices was padded with a sliver triangle so MuJoCo loads it (its edges show in G005/G007)", "model the part with at least 4 vertices, or join it to another part of its material"),
    ("U001", "scale-implausible", W, "the largest extent in metres is outside 1 mm .. 10 m", "export in metres, or pass --units / --scale when converting"),
    ("C001", "hull-count", W, "more collision hulls than the budget (limits.max-hulls)", "decompose with a smaller --max-hulls"),
    ("C002", "hull-vertices", W, "a collision hull has more vertices than the budget (limits.max-hull-vertices)", "re-pack with --max-hull-vertices"),
    ("C003", "hull-fit", W, "the collision hulls fit the mesh poorly (too much empty volume, or surface left out)", "decompose: obj2bin --hulls decompose"),
    ("C004", "no-hulls", W, "the pack has no collision hulls", "re-pack with obj2bin --hulls convex or decompose"),
    ("P001", "mujoco-compile", E, "MuJoCo refuses to compile the asset as a free body", "fix what MuJoCo's message names"),
    ("P002", "drop-unsettled", W, "dropped onto a plane, the body is not at rest after limits.settle-time", "check the shape and mass; round objects roll (ignore P002 for them)"),
    ("P003", "mujoco-warning", W, "MuJoCo raised warnings while the body dropped and settled", "check the mass, inertia and hulls"),
    ("P004", "mass-implausible", W, "the mass at limits.density is outside limits.min-mass .. max-mass", "check the scale, or give the mass explicitly in the scene"),
    ("P005", "inertia-implausible", W, "principal moments of inertia differ by more than limits.max-inertia-ratio", "check for slivers and the scale"),
    ("K001", "pack-corrupt", E, "an .mbin fails its structure or checksum checks", "convert the source again with obj2bin"),
    ("K002", "pack-version", E, "an .mbin has a format version this meshtool cannot read", "re-pack it, or upgrade meshtool"),
    ("K003", "pack-stale", W, "an .mbin was made from sources that have changed or gone since", "convert again with obj2bin"),
    ("X001", "internal-error", E, "meshtool itself failed checking this asset (a bug: please report it)", "report the message; the asset was not checked"),
    ("X002", "timeout", E, "the check of an asset did not finish within the time limit (timeout, default 300 s)", "find what makes the asset slow (a huge face, thousands of names), or raise timeout / --timeout"),
]  # fmt: skip

#: Every rule by ID, in documentation order.
RULES: dict[str, Rule] = {row[0]: Rule(*row) for row in _TABLE}
#: Rule IDs by name.
BY_NAME: dict[str, str] = {rule.name: rule.id for rule in RULES.values()}


def rule_id(key: str) -> str | None:
    """The rule ID of an ID (any case) or a name; ``None`` when no rule matches."""
    upper = key.strip().upper()
    if upper in RULES:
        return upper
    return BY_NAME.get(key.strip().lower())


def hit(
    rule: str, message: str, path: str | None = None, line: int | None = None, severity: Severity | None = None
) -> Finding:
    """A finding of ``rule`` with its default severity, or ``severity`` where the rule judges by context.

    Args:
        rule: A rule ID from :data:`RULES`.
        message: What was found, one sentence, with the numbers.
        path: The file it is in, relative to the asset's folder (or as the user named it).
        line: 1-based line in ``path``.
        severity: Instead of the default: S002/S003 are warnings when every consumer of the OBJ reads no
            MTL (:func:`meshtool.validate.source.from_normaliser`). Configured overrides still apply after.

    Raises:
        KeyError: ``rule`` is not a rule ID (a programming error).
    """
    return Finding(rule, severity or RULES[rule].severity, message, path, line)
