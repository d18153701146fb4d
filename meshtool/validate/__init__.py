"""``meshtool validate``: every asset of a folder checked against documented rules, for CI.

Library use::

    from meshtool.validate import ValidateOptions, validate, render
    report = validate([Path("assets")], ValidateOptions(jobs=4))
    text = render(report, "text")  # the CLI writes it; library code never prints

Rules are listed in :mod:`meshtool.validate.rules` and ``docs/validate-rules.md``.
"""

from meshtool.validate.config import ConfigError, Limits, ValidateConfig, find_config, load_config
from meshtool.validate.reports import FORMATS, render
from meshtool.validate.rules import RULES, Rule
from meshtool.validate.runner import ValidateError, ValidateOptions, ValidationReport, discover, validate
from meshtool.validate.task import AssetResult, AssetTask, check_asset

__all__ = [
    "FORMATS",
    "RULES",
    "AssetResult",
    "AssetTask",
    "ConfigError",
    "Limits",
    "Rule",
    "ValidateConfig",
    "ValidateError",
    "ValidateOptions",
    "ValidationReport",
    "check_asset",
    "discover",
    "find_config",
    "load_config",
    "render",
    "validate",
]
