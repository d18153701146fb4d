"""MTL reader and writer: material libraries of Wavefront OBJ files.

Colours (``Ka Kd Ks Ke Tf``), scalars (``Ns Ni d Tr illum`` and the PBR extension ``Pr Pm Ps Pc Pcr
aniso anisor``) are parsed as floats; every texture statement (``map_*``, ``bump``, ``norm``, ``disp``,
``decal``, ``refl``) is split into its options and a file name. File names may contain spaces, may be
quoted, and options may even follow the name (``bumpmap2.jpg -bm 1.5``). Bad statements become findings;
the reader only fails on data that is not text. A trailing ``# comment`` after a statement is dropped
(:mod:`meshtool.read.obj.comments`).

Transparency: the MTL specification says ``d`` is opacity and ``Tr`` its complement (``Tr 0`` is opaque),
but MeshLab (and every tool built on its VCG library, which writes ``# Converted by Meshlab Group``) writes
``Tr 1`` for an opaque material. When the MTL's header names such an exporter, ``Tr`` is read as opacity;
otherwise as ``1 - d``. ``d`` always wins over ``Tr``. :func:`opaque_if_invisible` turns a material that
would be fully invisible although faces use it into an opaque one.

Texture roles (:func:`texture_colorspace`): colour maps (``map_Kd map_Ka map_Ks map_Ke decal``) are sRGB
encoded; data maps (normal, bump, displacement, alpha, roughness, metallic, exponent) are linear.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

from meshtool.errors import MtlParseError
from meshtool.findings import Finding, info, warning
from meshtool.read.obj.comments import strip_name_comment, strip_numeric_comment
from meshtool.read.textio import decode_text

COLOR_KEYS = ("Ka", "Kd", "Ks", "Ke", "Tf")
_COLOR_ALIASES = {"Kt": "Tf"}
SCALAR_KEYS = ("Ns", "Ni", "d", "Pr", "Pm", "Ps", "Pc", "Pcr", "aniso", "anisor")
MAP_KEYS = (
    "map_Ka",
    "map_Kd",
    "map_Ks",
    "map_Ke",
    "map_Ns",
    "map_d",
    "map_Pr",
    "map_Pm",
    "map_Ps",
    "map_Bump",
    "bump",
    "norm",
    "disp",
    "decal",
    "refl",
)
_MAP_ALIASES = {
    "map_bump": "bump",
    "map_Bump": "bump",
    "bump": "bump",
    "map_kd": "map_Kd",
    "map_tr": "map_d",
    "map_Disp": "disp",
    "map_disp": "disp",
    "map_Norm": "norm",
    "map_norm": "norm",
    "map_Kn": "norm",
}
#: Maps whose pixels are colours (sRGB encoded); every other map holds data (linear).
COLOR_MAPS = frozenset({"map_Ka", "map_Kd", "map_Ks", "map_Ke", "decal"})
#: Maps that perturb the surface normal (kept in the output; MuJoCo does not use them).
SURFACE_MAPS = frozenset({"bump", "norm", "disp"})
#: Header comment words of exporters that write ``Tr`` as opacity (``Tr 1`` = opaque), lower case.
TR_AS_OPACITY_EXPORTERS = {"meshlab": "MeshLab", "vcglib": "VCGlib"}
#: Opacity below which a material cannot be seen at all (one step of 8-bit alpha).
INVISIBLE_BELOW = 1.0 / 255.0
# option -> (least, most) number of arguments
MAP_OPTIONS: dict[str, tuple[int, int]] = {
    "-blendu": (1, 1),
    "-blendv": (1, 1),
    "-boost": (1, 1),
    "-bm": (1, 1),
    "-cc": (1, 1),
    "-colorspace": (1, 1),
    "-clamp": (1, 1),
    "-imfchan": (1, 1),
    "-mm": (2, 2),
    "-o": (1, 3),
    "-s": (1, 3),
    "-t": (1, 3),
    "-texres": (1, 1),
    "-type": (1, 1),
}
_TOKEN = re.compile(r"\S+")
_UNKNOWN = "unknown"
_NUMERIC_OPTIONS = {"-boost", "-bm", "-mm", "-o", "-s", "-t", "-texres"}


@dataclass(slots=True)
class TextureMap:
    """One texture statement.

    Attributes:
        file: The file name as written, options and quotes removed (may contain spaces or backslashes).
        options: Options in file order, e.g. ``{"-s": ("2", "2", "1"), "-clamp": ("on",)}``; numeric option
            arguments are normalised float text (``"2.0"``).
        line: 1-based line of the statement.
    """

    file: str
    options: dict[str, tuple[str, ...]]
    line: int


@dataclass(slots=True)
class Material:
    """One ``newmtl`` block.

    Attributes:
        name: Material name as written.
        line: Line of its ``newmtl``.
        colors: Colour statements, each (r, g, b) floats.
        scalars: Scalar statements as floats (``Tr`` is stored as ``d = 1 - Tr`` when ``d`` is absent).
        illum: Illumination model, or ``None``.
        maps: Texture statements by canonical key (``bump`` for ``map_Bump``/``map_bump``).
    """

    name: str
    line: int
    colors: dict[str, tuple[float, float, float]] = field(default_factory=dict)
    scalars: dict[str, float] = field(default_factory=dict)
    illum: int | None = None
    maps: dict[str, TextureMap] = field(default_factory=dict)


@dataclass(slots=True)
class MtlData:
    """A parsed MTL file.

    Attributes:
        path: Name used in findings.
        materials: Materials in file order (a repeated name keeps its first definition).
        findings: Statements that were malformed or ignored.
        header_comments: Comment lines before the first statement (without the ``#``).
        tr_exporter: The exporter named in the header that writes ``Tr`` as opacity, or ``None``.
    """

    path: str
    materials: list[Material]
    findings: list[Finding]
    header_comments: list[str] = field(default_factory=list)
    tr_exporter: str | None = None


def texture_colorspace(key: str) -> str:
    """``sRGB`` for a colour map key (``map_Kd``...), ``linear`` for a data map (normal, bump, alpha...)."""
    return "sRGB" if key in COLOR_MAPS else "linear"


def tr_exporter(header_comments: list[str]) -> str | None:
    """The exporter that writes ``Tr`` as opacity, when a header comment names one."""
    text = " ".join(header_comments).lower()
    return next((name for word, name in TR_AS_OPACITY_EXPORTERS.items() if word in text), None)


def opaque_if_invisible(material: Material, path: str | None = None) -> Finding | None:
    """Make a material that faces use, and that would be fully invisible (``d`` < 1/255), opaque.

    Args:
        material: A material that faces use; changed in place.
        path: File for the finding.

    Returns:
        A ``material-invisible`` warning when the opacity was changed, else ``None``.
    """
    d = material.scalars.get("d")
    if d is None or d >= INVISIBLE_BELOW:
        return None
    material.scalars["d"] = 1.0
    return warning(
        "material-invisible",
        f"material {material.name!r} has opacity d={d:g} (fully invisible) but faces use it: made opaque "
        "(d 1); pass --strict to refuse such files",
        path,
    )


def parse_mtl(data: bytes | str, path: str = "<mtl>") -> MtlData:
    """Parse an MTL file.

    Args:
        data: File contents (bytes in any supported encoding, or text).
        path: Name used in findings.

    Returns:
        The materials and findings.

    Raises:
        MtlParseError: When the data is binary, not text.
    """
    raw = data.encode("utf-8") if isinstance(data, str) else data
    decoded = decode_text(raw, path, MtlParseError)
    findings = list(decoded.findings)
    materials: list[Material] = []
    seen: set[str] = set()
    current: Material | None = None
    unknown: dict[str, int] = {}
    header: list[str] = []
    in_header = True
    for line_no, line in enumerate(decoded.text.split("\n"), start=1):
        words = line.split(None, 1)
        if not words or words[0].startswith("#"):
            if words and in_header:
                header.append(line.strip().lstrip("#").strip())
            continue
        in_header = False
        keyword, rest = words[0], (words[1].strip() if len(words) > 1 else "")
        if keyword == "newmtl":
            name = strip_name_comment(rest).strip('"') or "default"
            current = Material(name, line_no)
            if name in seen:
                findings.append(
                    warning("material-duplicate", f"material {name!r} defined again; first kept", path, line_no)
                )
                continue
            seen.add(name)
            materials.append(current)
            continue
        if current is None:
            findings.append(
                warning(
                    "mtl-statement-outside-material",
                    f"'{keyword[:20]}' before any 'newmtl' ignored",
                    path,
                    line_no,
                )
            )
            continue
        problem = _statement(current, keyword, rest, line_no)
        if problem is _UNKNOWN:
            unknown.setdefault(keyword[:20], line_no)
        elif problem:
            findings.append(warning("mtl-statement-invalid", problem, path, line_no))
    for keyword, line_no in unknown.items():
        findings.append(info("mtl-statement-unsupported", f"unsupported statement '{keyword}' ignored", path, line_no))
    exporter = tr_exporter(header)
    for material in materials:
        if "d" not in material.scalars and "Tr" in material.scalars:
            tr = material.scalars["Tr"]
            if exporter is not None:
                material.scalars["d"] = tr
                how = f"read as opacity (d {_num(tr)}) as {exporter} writes it"
            else:
                material.scalars["d"] = 1.0 - tr
                how = f"read as transparency (d {_num(1.0 - tr)}) as the MTL specification says"
            findings.append(
                info("mtl-tr-converted", f"material {material.name!r}: 'Tr {_num(tr)}' {how}", path, material.line)
            )
        material.scalars.pop("Tr", None)
    return MtlData(path, materials, findings, header, exporter)


def _statement(material: Material, keyword: str, rest: str, line_no: int) -> str | None:
    """Apply one statement to ``material``; return a problem description or ``None``."""
    keyword = _COLOR_ALIASES.get(keyword, keyword)
    key = _MAP_ALIASES.get(keyword, keyword)
    rest = strip_name_comment(rest) if key in MAP_KEYS else strip_numeric_comment(rest)
    if keyword in COLOR_KEYS:
        values = _floats(rest)
        if values is None or not 1 <= len(values) <= 3:
            return f"'{keyword}' needs 1 to 3 finite numbers (spectral/xyz forms are not supported): {rest[:40]!r}"
        r = values[0]
        material.colors[keyword] = (
            r,
            values[1] if len(values) > 1 else r,
            values[2] if len(values) > 2 else r,
        )
        return None
    if keyword in (*SCALAR_KEYS, "Tr"):
        values = _floats(rest)
        if values is None or len(values) != 1:
            return f"'{keyword}' needs one finite number: {rest[:40]!r}"
        material.scalars[keyword] = values[0]
        return None
    if keyword == "illum":
        values = _floats(rest)
        if values is None or len(values) != 1 or values[0] != int(values[0]):
            return f"'illum' needs an integer: {rest[:40]!r}"
        material.illum = int(values[0])
        return None
    if key in MAP_KEYS:
        parsed = parse_map_statement(rest)
        if parsed is None:
            return f"'{keyword}' has no file name"
        file, options = parsed
        material.maps[key] = TextureMap(file, options, line_no)
        return None
    return _UNKNOWN


def _floats(text: str) -> list[float] | None:
    """The numbers of ``text``; ``None`` unless all are finite, within +-1e6 and plain ASCII without ``_``."""
    words = text.split()
    if any("_" in w or not w.isascii() for w in words):  # float() reads "1_0" as 10
        return None
    try:
        values = [float(w) for w in words]
    except ValueError:
        return None
    return values if all(abs(v) <= 1e6 for v in values) else None  # False for NaN and infinities


def parse_map_statement(rest: str) -> tuple[str, dict[str, tuple[str, ...]]] | None:
    """Split a texture statement's argument into (file name, options).

    Args:
        rest: Everything after the keyword, e.g. ``-s 1 1 1 -clamp on my texture.png -bm 0.5``.

    Returns:
        The file name (spaces kept, quotes removed) and the options in order, or ``None`` when there is no
        file name.
    """
    tokens = [(m.group(0), m.start(), m.end()) for m in _TOKEN.finditer(rest)]
    options: dict[str, tuple[str, ...]] = {}
    i = _take_options(tokens, 0, options)
    if i >= len(tokens):
        return None
    start = tokens[i][1]
    if rest[start] == '"':
        close = rest.find('"', start + 1)
        if close > start:
            name = rest[start + 1 : close]
            j = next((k for k, t in enumerate(tokens) if t[1] > close), len(tokens))
            _take_options(tokens, j, options)
            return (name, options) if name else None
    # the name runs until a known option that is followed by valid arguments
    j = i + 1
    while j < len(tokens):
        trailing: dict[str, tuple[str, ...]] = {}
        if tokens[j][0] in MAP_OPTIONS and _take_options(tokens, j, trailing) == len(tokens):
            options.update(trailing)
            break
        j += 1
    name = rest[start : tokens[j - 1][2]]
    return name, options


def _take_options(tokens: list[tuple[str, int, int]], i: int, options: dict[str, tuple[str, ...]]) -> int:
    """Consume options starting at token ``i``; return the index of the first token that is not one."""
    while i < len(tokens) and tokens[i][0] in MAP_OPTIONS:
        option = tokens[i][0]
        least, most = MAP_OPTIONS[option]
        args: list[str] = []
        k = i + 1
        while k < len(tokens) and len(args) < most:
            word = tokens[k][0]
            if option in _NUMERIC_OPTIONS:
                number = _floats(word)
                if number is None or len(number) != 1:
                    break
                args.append(repr(number[0]))
            else:
                if word in MAP_OPTIONS:
                    break
                args.append(word)
            k += 1
        if len(args) < least:
            return i
        options[option] = tuple(args)
        i = k
    return i


def format_mtl(materials: list[Material], header: str) -> str:
    """Write materials as MTL text in a canonical statement order.

    Args:
        materials: Materials to write; texture files must already be the output file names.
        header: Comment text for the first line.

    Returns:
        The MTL text, LF line endings, numbers in shortest round-trip form.
    """
    out = [f"# {header}"]
    for m in materials:
        out.append("")
        out.append(f"newmtl {m.name}")
        for key in COLOR_KEYS:
            if key in m.colors:
                out.append(f"{key} {' '.join(_num(v) for v in m.colors[key])}")
        for key in SCALAR_KEYS:
            if key in m.scalars:
                out.append(f"{key} {_num(m.scalars[key])}")
        if m.illum is not None:
            out.append(f"illum {m.illum}")
        for key in MAP_KEYS:
            if key in m.maps:
                t = m.maps[key]
                opts = "".join(f"{k} {' '.join(v)} " for k, v in t.options.items())
                out.append(f"{key} {opts}{t.file}")
    return "\n".join(out) + "\n"


def _num(value: float) -> str:
    text = repr(float(value))
    return text[:-2] if text.endswith(".0") else text
