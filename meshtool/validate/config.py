"""Configuration of ``meshtool validate``: severity overrides, ignores and limits.

Read from ``[tool.meshtool.validate]`` in a ``pyproject.toml`` or ``[validate]`` in a ``meshtool.toml``::

    [tool.meshtool.validate]
    severity = { G007 = "error", hull-fit = "off" }   # by ID or name; off drops the rule
    ignore = ["S009"]                                  # rules never reported
    source-roots = ["assets/src"]                      # where .mbin sources live (for K003)
    timeout = 300                                      # seconds per asset (X002 past it); 0: no limit

    [tool.meshtool.validate.per-path-ignores]          # globs relative to the config file's folder
    "props/balls/**" = ["P002"]
    "legacy/**" = ["*"]

    [tool.meshtool.validate.limits]
    max-vertices = 200000

    [[tool.meshtool.validate.paths]]                   # settings for the assets a glob matches, in file order
    glob = "props/cm/**"                               # relative to the config file's folder
    units = "cm"                                       # the sources' unit (mm, cm, m, in, ft, auto)
    up = "z"                                           # their up axis (y, z, auto)
    severity = { U001 = "error" }                      # as above; a severity turns on a rule ignored above
    ignore = ["P002"]                                  # rules not reported there ("*": all but X001)
    limits = { max-vertices = 500000 }                 # limits there
"""

from __future__ import annotations

import fnmatch
import re
import tomllib
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

from meshtool.errors import MeshtoolError
from meshtool.files.nesting import DocumentLimitError, bounded
from meshtool.files.resolve import is_file, read_cache
from meshtool.findings import Finding, Severity
from meshtool.frame.units import UNIT_FACTORS
from meshtool.validate.rules import rule_id

#: Seconds one asset's check may take before it is stopped with an X002 finding (``timeout``, ``--timeout``).
DEFAULT_TIMEOUT = 300.0


class ConfigError(MeshtoolError, ValueError):
    """The validation configuration is invalid (a usage error: exit code 2)."""

    exit_code = 2


@dataclass(frozen=True, slots=True)
class Limits:
    """Numbers the rules compare against (TOML keys are the field names with ``-`` for ``_``).

    Attributes:
        max_vertices: G011: most welded vertices per asset.
        min_volume_m3: G010: smallest volume of a closed mesh, m^3.
        min_volume_fraction: G010: smallest volume / bounding-box volume of a closed mesh.
        max_hulls: C001: most collision hulls per asset (the ``mujoco`` preset's 32).
        max_hull_vertices: C002: most vertices per hull.
        max_hull_volume_ratio: C003: largest hull volume / mesh volume (closed meshes).
        max_hull_gap: C003: largest distance of the surface outside the hulls, as a fraction of the
            bounding-box diagonal.
        density: P004: kg/m^3 used for the mass (the hulls' volume times this).
        min_mass: P004: kg.
        max_mass: P004: kg.
        max_inertia_ratio: P005: largest / smallest principal moment of inertia.
        settle_time: P002: seconds of simulated time the body has to come to rest after the drop.
    """

    max_vertices: int = 200_000
    min_volume_m3: float = 1e-9
    min_volume_fraction: float = 1e-4
    max_hulls: int = 32
    max_hull_vertices: int = 64
    max_hull_volume_ratio: float = 2.0
    max_hull_gap: float = 0.05
    density: float = 1000.0
    min_mass: float = 0.001
    max_mass: float = 1000.0
    max_inertia_ratio: float = 1e5
    settle_time: float = 3.0

    def as_dict(self) -> dict[str, float]:
        """The limits as plain numbers (what the physics plugin receives)."""
        return {f.name: float(getattr(self, f.name)) for f in fields(self)}


#: Keys of a ``[[validate.paths]]`` entry.
PATH_KEYS = ("glob", "units", "up", "severity", "ignore", "limits")
#: Up axes a ``[[validate.paths]]`` entry may give (:class:`meshtool.repair.normalise.NormaliseOptions`).
UP_AXES = ("y", "z", "auto")


@dataclass(frozen=True, slots=True)
class PathSettings:
    """One ``[[validate.paths]]`` entry: settings for the assets its glob matches.

    Attributes:
        glob: Asset paths it applies to, relative to the configuration file's folder (``**`` spans folders).
        units: The sources' unit (``mm``, ``cm``, ``m``, ``in``, ``ft``, ``auto``), or ``None`` to leave it.
        up: The sources' up axis (``y``, ``z``, ``auto``), or ``None`` to leave it.
        severity: Rule ID -> severity name or ``off`` there (a severity turns on a rule ignored before).
        ignore: Rule IDs (or ``*``: all but X001) not reported there.
        limits: (limit field name, value) pairs that replace the limits there.
    """

    glob: str
    units: str | None = None
    up: str | None = None
    severity: tuple[tuple[str, str], ...] = ()
    ignore: tuple[str, ...] = ()
    limits: tuple[tuple[str, float], ...] = ()


@dataclass(frozen=True, slots=True)
class AssetSettings:
    """What the configuration gives one asset before its check: unit, up axis, limits.

    Attributes:
        units: The source's unit for the reader, or ``None`` (decided as ``normalize`` decides it).
        up: The source's up axis, or ``None``.
        limits: The limits its rules compare against.
    """

    units: str | None
    up: str | None
    limits: Limits


@dataclass(frozen=True, slots=True)
class ValidateConfig:
    """Parsed configuration.

    Attributes:
        severity: Rule ID -> severity name (``error``, ``warning``, ``info``) or ``off``.
        ignore: Rule IDs never reported.
        per_path_ignores: (glob, rule IDs or ``*``) pairs; globs match asset paths relative to ``root``.
        limits: See :class:`Limits`.
        source_roots: Extra folders where ``.mbin`` sources are looked for (K003).
        root: Folder the globs and source roots are relative to (the config file's folder).
        file: The configuration file, or ``None`` for the defaults.
        timeout: Seconds one asset's check may take (X002 past it); 0 for no limit.
        paths: ``[[validate.paths]]`` entries in file order (a later match wins where two set one thing).
    """

    severity: tuple[tuple[str, str], ...] = ()
    ignore: tuple[str, ...] = ()
    per_path_ignores: tuple[tuple[str, tuple[str, ...]], ...] = ()
    limits: Limits = field(default_factory=Limits)
    source_roots: tuple[Path, ...] = ()
    root: Path = Path(".")
    file: str | None = None
    timeout: float = DEFAULT_TIMEOUT
    paths: tuple[PathSettings, ...] = ()

    def fingerprint(self) -> dict[str, Any]:
        """What changes the raw findings (the cache key part); severities and ignores apply afterwards."""
        return {"limits": self.limits.as_dict(), "source_roots": [str(p) for p in self.source_roots]}

    def settings_for(self, asset_path: Path) -> AssetSettings:
        """The unit, up axis and limits of one asset: the defaults, then each matching ``paths`` entry."""
        units = up = None
        limits = self.limits
        for entry in self._matching(asset_path):
            units = entry.units or units
            up = entry.up or up
            overrides: dict[str, Any] = dict(entry.limits)
            limits = replace(limits, **overrides)
        return AssetSettings(units, up, limits)

    def apply(self, findings: list[Finding], asset_path: Path) -> list[Finding]:
        """Severity overrides and ignores applied to one asset's findings.

        The top-level ``ignore`` and ``per-path-ignores`` win over the top-level ``severity``; then each
        matching ``paths`` entry in order sets severities (turning an ignored rule on) and ignores rules.
        ``*`` hides every rule but X001, whatever comes after it.
        """
        levels = dict(self.severity)
        ignored = set(self.ignore)
        rel = self._relative(asset_path)
        for pattern, rules in self.per_path_ignores:
            if _glob_match(pattern, rel):
                ignored.update(rules)
        levels.update((rule, "off") for rule in ignored)
        for entry in self._matching(asset_path):
            levels.update(entry.severity)
            levels.update((rule, "off") for rule in entry.ignore)
        out = []
        for f in findings:
            if ("*" in levels and f.code != "X001") or levels.get(f.code) == "off":
                continue
            level = levels.get(f.code)
            out.append(replace(f, severity=Severity(level)) if level else f)
        return out

    def _relative(self, asset_path: Path) -> str:
        """``asset_path`` relative to :attr:`root` (``/``-separated), as the globs see it."""
        try:
            return asset_path.resolve().relative_to(self.root.resolve()).as_posix()
        except ValueError:
            return asset_path.as_posix()

    def _matching(self, asset_path: Path) -> list[PathSettings]:
        rel = self._relative(asset_path) if self.paths else ""
        return [entry for entry in self.paths if _glob_match(entry.glob, rel)]


def find_config(start: Path) -> Path | None:
    """The configuration file that applies in ``start`` (searching upwards).

    In each folder from ``start`` up: its ``meshtool.toml``, else its ``pyproject.toml`` if that has a
    ``[tool.meshtool.validate]`` table.
    """
    for folder in (start.resolve(), *start.resolve().parents):
        if is_file(folder / "meshtool.toml"):
            return folder / "meshtool.toml"
        pyproject = folder / "pyproject.toml"
        if is_file(pyproject) and re.search(rb"^\[tool\.meshtool\.validate", read_cache(pyproject) or b"", re.M):
            return pyproject
    return None


def load_config(path: Path | None) -> ValidateConfig:
    """Parse a configuration file (``None``: the defaults).

    Raises:
        ConfigError: The file is missing, not TOML, or has an unknown key, rule, severity or limit.
    """
    if path is None:
        return ValidateConfig()
    data = read_cache(path)
    if data is None:
        raise ConfigError("configuration file not found", path=str(path), hint="check --config")
    try:
        document = bounded(lambda: tomllib.loads(data.decode("utf-8")))
    except DocumentLimitError as exc:
        raise ConfigError(str(exc), path=str(path)) from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ConfigError(f"not valid TOML: {exc}", path=str(path)) from None
    if path.name == "pyproject.toml":
        table, where = document.get("tool", {}).get("meshtool", {}).get("validate", {}), "[tool.meshtool.validate]"
    else:
        table, where = document.get("validate", {}), "[validate]"
    return parse_config(table, str(path), where, path.parent, data.decode("utf-8"))


def parse_config(table: dict[str, Any], file: str, where: str, root: Path, source: str | None = None) -> ValidateConfig:
    """Build a :class:`ValidateConfig` from the validate table of a TOML document.

    Args:
        table: The validate table.
        file: The configuration file, as errors name it.
        where: The table's header (``[validate]``, ``[tool.meshtool.validate]``), as errors name it.
        root: The folder globs and source roots are relative to.
        source: The document's text: an unknown key's error names its line (``None``: no lines).

    Raises:
        ConfigError: An unknown key, rule, severity, limit, unit or up axis, or a value of the wrong type.
    """
    lines = _KeyLines(source, where)

    def fail(message: str, hint: str | None = None, line: int | None = None) -> ConfigError:
        return ConfigError(f"{where}: {message}", path=file, hint=hint, line=line)

    def rules_of(values: Any, key: str, star: bool) -> tuple[str, ...]:
        if not isinstance(values, list) or not all(isinstance(v, str) for v in values):
            raise fail(f"{key} must be a list of rule IDs or names")
        out = []
        for v in values:
            if star and v == "*":
                out.append("*")
                continue
            rid = rule_id(v)
            if rid is None:
                raise fail(f"{key}: unknown rule {v!r}", "see docs/validate-rules.md")
            out.append(rid)
        return tuple(out)

    def severities(value: Any, key: str) -> tuple[tuple[str, str], ...]:
        if not isinstance(value, dict):
            raise fail(f"{key} must be a table of rule = severity")
        out = []
        for name, level in value.items():
            rid = rule_id(name)
            if rid is None:
                raise fail(f"{key}: unknown rule {name!r}", "see docs/validate-rules.md")
            if level not in ("error", "warning", "info", "off"):
                raise fail(f"{key} of {name}: {level!r}", "use error, warning, info or off")
            out.append((rid, str(level)))
        return tuple(sorted(out))

    def limits_of(value: Any, key: str, after: int | None) -> dict[str, Any]:
        if not isinstance(value, dict):
            raise fail(f"{key} must be a table of limit = number")
        values: dict[str, Any] = {}
        defaults = Limits()
        for name, number in value.items():
            field_name = name.replace("-", "_")
            if not hasattr(defaults, field_name):
                names = ", ".join(f.name.replace("_", "-") for f in fields(Limits))
                raise fail(f"{key}: unknown limit {name!r}", f"use one of {names}", lines.find(name, after))
            kind = type(getattr(defaults, field_name))
            if isinstance(number, bool) or not isinstance(number, int | float) or number <= 0:
                raise fail(f"{key}.{name} must be a positive number, got {number!r}")
            values[field_name] = kind(number)
        return values

    known = {"severity", "ignore", "per-path-ignores", "limits", "source-roots", "timeout", "paths"}
    for key in table:
        if key not in known:
            raise fail(f"unknown key {key!r}", f"use one of {', '.join(sorted(known))}", lines.find(key))
    severity = severities(dict(table.get("severity", {})), "severity")
    per_path = []
    for pattern, rules in dict(table.get("per-path-ignores", {})).items():
        per_path.append((str(pattern), rules_of(rules, f"per-path-ignores {pattern!r}", True)))
    values = limits_of(dict(table.get("limits", {})), "limits", None)
    entries = table.get("paths", [])
    if not isinstance(entries, list) or not all(isinstance(e, dict) for e in entries):
        raise fail("paths must be an array of tables ([[...paths]] entries)", line=lines.find("paths"))
    paths = []
    for number, entry in enumerate(entries, 1):
        label = f"paths entry {number}"
        start = lines.entry(number)
        for key in entry:
            if key not in PATH_KEYS:
                known_keys = ", ".join(sorted(PATH_KEYS))
                raise fail(f"{label}: unknown key {key!r}", f"use one of {known_keys}", lines.find(key, start))
        glob = entry.get("glob")
        if not isinstance(glob, str) or not glob.strip():
            raise fail(f'{label}: glob must be a path pattern such as "props/cm/**"', line=start)
        units, up = entry.get("units"), entry.get("up")
        if units is not None and (not isinstance(units, str) or (units not in UNIT_FACTORS and units != "auto")):
            choices = ", ".join((*UNIT_FACTORS, "auto"))
            raise fail(f"{label}: unknown units {units!r}", f"use one of {choices}", lines.find("units", start))
        if up is not None and up not in UP_AXES:
            raise fail(f"{label}: unknown up axis {up!r}", f"use one of {', '.join(UP_AXES)}", lines.find("up", start))
        paths.append(
            PathSettings(
                glob=glob,
                units=units,
                up=up,
                severity=severities(entry.get("severity", {}), f"{label}: severity"),
                ignore=rules_of(entry.get("ignore", []), f"{label}: ignore", True),
                limits=tuple(sorted(limits_of(entry.get("limits", {}), f"{label}: limits", start).items())),
            )
        )
    timeout = table.get("timeout", DEFAULT_TIMEOUT)
    if isinstance(timeout, bool) or not isinstance(timeout, int | float) or not 0 <= timeout < float("inf"):
        raise fail(f"timeout must be a number of seconds (0: no limit), got {timeout!r}")
    roots = table.get("source-roots", [])
    if not isinstance(roots, list) or not all(isinstance(r, str) for r in roots):
        raise fail("source-roots must be a list of folders")
    return ValidateConfig(
        severity=severity,
        ignore=rules_of(table.get("ignore", []), "ignore", False),
        per_path_ignores=tuple(per_path),
        limits=Limits(**values),
        source_roots=tuple(root / r for r in roots),
        root=root,
        file=file,
        timeout=float(timeout),
        paths=tuple(paths),
    )


class _KeyLines:
    """Where keys are in a configuration's text, so that an error can name the line (TOML parsers give none).

    Args:
        source: The document's text, or ``None`` (every lookup answers ``None``).
        where: The validate table's header: ``[validate]`` or ``[tool.meshtool.validate]``.
    """

    def __init__(self, source: str | None, where: str) -> None:
        self.lines = source.splitlines() if source is not None else []
        name = re.escape(where.strip("[]"))
        self.table = re.compile(rf"^\s*\[\s*{name}\s*\]")
        self.entries = re.compile(rf"^\s*\[\[\s*{name}\.paths\s*\]\]")

    def entry(self, number: int) -> int | None:
        """The line of the ``number``-th (1-based) ``[[...paths]]`` header, ``None`` when there is none."""
        found = [k for k, line in enumerate(self.lines, 1) if self.entries.match(line)]
        return found[number - 1] if number <= len(found) else None

    def find(self, key: str, after: int | None = None) -> int | None:
        """The first line setting ``key`` (``key =``, ``"key" =``), from line ``after`` or the table's header."""
        if after is None:
            after = next((k for k, line in enumerate(self.lines, 1) if self.table.match(line)), 1)
        pattern = re.compile(rf"""(^|[\s{{,.])(["']?){re.escape(key)}\2\s*=""")
        order: list[int] = [*range(after, len(self.lines) + 1), *range(1, after)]
        for number in order:
            line = self.lines[number - 1]
            if not line.lstrip().startswith("#") and pattern.search(line):
                return number
        return None


def _glob_match(pattern: str, path: str) -> bool:
    """Whether a ``/``-separated relative path matches a glob where ``**`` spans folders."""
    regex = ""
    k = 0
    while k < len(pattern):
        if pattern.startswith("**/", k):
            regex, k = regex + "(?:.*/)?", k + 3
        elif pattern.startswith("**", k):
            regex, k = regex + ".*", k + 2
        elif pattern[k] == "*":
            regex, k = regex + "[^/]*", k + 1
        elif pattern[k] == "?":
            regex, k = regex + "[^/]", k + 1
        else:
            regex, k = regex + re.escape(pattern[k]), k + 1
    return re.fullmatch(regex, path) is not None or fnmatch.fnmatchcase(path, pattern.rstrip("/") + "/*")
