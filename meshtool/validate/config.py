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
"""

from __future__ import annotations

import fnmatch
import re
import tomllib
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

from meshtool.errors import MeshtoolError
from meshtool.findings import Finding, Severity
from meshtool.nesting import DocumentLimitError, bounded
from meshtool.resolve import is_file, read_cache
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
    """

    severity: tuple[tuple[str, str], ...] = ()
    ignore: tuple[str, ...] = ()
    per_path_ignores: tuple[tuple[str, tuple[str, ...]], ...] = ()
    limits: Limits = field(default_factory=Limits)
    source_roots: tuple[Path, ...] = ()
    root: Path = Path(".")
    file: str | None = None
    timeout: float = DEFAULT_TIMEOUT

    def fingerprint(self) -> dict[str, Any]:
        """What changes the raw findings (the cache key part); severities and ignores apply afterwards."""
        return {"limits": self.limits.as_dict(), "source_roots": [str(p) for p in self.source_roots]}

    def apply(self, findings: list[Finding], asset_path: Path) -> list[Finding]:
        """Severity overrides and ignores applied to one asset's findings."""
        severity = dict(self.severity)
        try:
            rel = asset_path.resolve().relative_to(self.root.resolve()).as_posix()
        except ValueError:
            rel = asset_path.as_posix()
        ignored = set(self.ignore)
        for pattern, rules in self.per_path_ignores:
            if _glob_match(pattern, rel):
                ignored.update(rules)
        out = []
        for f in findings:
            if ("*" in ignored and f.code != "X001") or f.code in ignored:
                continue
            level = severity.get(f.code)
            if level == "off":
                continue
            out.append(replace(f, severity=Severity(level)) if level else f)
        return out


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
    return parse_config(table, str(path), where, path.parent)


def parse_config(table: dict[str, Any], file: str, where: str, root: Path) -> ValidateConfig:
    """Build a :class:`ValidateConfig` from the validate table of a TOML document."""

    def fail(message: str, hint: str | None = None) -> ConfigError:
        return ConfigError(f"{where}: {message}", path=file, hint=hint)

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

    known = {"severity", "ignore", "per-path-ignores", "limits", "source-roots", "timeout"}
    for key in table:
        if key not in known:
            raise fail(f"unknown key {key!r}", f"use one of {', '.join(sorted(known))}")
    severity = []
    for key, level in dict(table.get("severity", {})).items():
        rid = rule_id(key)
        if rid is None:
            raise fail(f"severity: unknown rule {key!r}", "see docs/validate-rules.md")
        if level not in ("error", "warning", "info", "off"):
            raise fail(f"severity of {key}: {level!r}", "use error, warning, info or off")
        severity.append((rid, str(level)))
    per_path = []
    for pattern, rules in dict(table.get("per-path-ignores", {})).items():
        per_path.append((str(pattern), rules_of(rules, f"per-path-ignores {pattern!r}", True)))
    limits_table = dict(table.get("limits", {}))
    values: dict[str, Any] = {}
    defaults = Limits()
    for key, value in limits_table.items():
        name = key.replace("-", "_")
        if not hasattr(defaults, name):
            names = ", ".join(f.name.replace("_", "-") for f in fields(Limits))
            raise fail(f"limits: unknown limit {key!r}", f"use one of {names}")
        kind = type(getattr(defaults, name))
        if isinstance(value, bool) or not isinstance(value, int | float) or value <= 0:
            raise fail(f"limits.{key} must be a positive number, got {value!r}")
        values[name] = kind(value)
    timeout = table.get("timeout", DEFAULT_TIMEOUT)
    if isinstance(timeout, bool) or not isinstance(timeout, int | float) or not 0 <= timeout < float("inf"):
        raise fail(f"timeout must be a number of seconds (0: no limit), got {timeout!r}")
    roots = table.get("source-roots", [])
    if not isinstance(roots, list) or not all(isinstance(r, str) for r in roots):
        raise fail("source-roots must be a list of folders")
    return ValidateConfig(
        severity=tuple(sorted(severity)),
        ignore=rules_of(table.get("ignore", []), "ignore", False),
        per_path_ignores=tuple(per_path),
        limits=Limits(**values),
        source_roots=tuple(root / r for r in roots),
        root=root,
        file=file,
        timeout=float(timeout),
    )


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
