"""What every meshtool command does when meshtool itself fails: one line, exit 3, traceback on request."""

from __future__ import annotations

import os
import sys
from typing import NoReturn

import click

EXIT_INTERNAL = 3


def exit_on_bug(exc: Exception) -> NoReturn:
    """Say that meshtool failed (a bug: please report it) and exit 3; re-raise with ``MESHTOOL_DEBUG`` set."""
    if os.environ.get("MESHTOOL_DEBUG"):
        raise exc
    click.echo(f"internal error: {type(exc).__name__}: {exc} (please report; MESHTOOL_DEBUG=1 shows more)", err=True)
    sys.exit(EXIT_INTERNAL)
