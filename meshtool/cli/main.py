"""The ``meshtool`` command line: a thin click layer over the library.

Each command turns its options into the library's frozen options dataclass, calls the library, and maps
the outcome to output and an exit code:

* 0: written (warnings allowed);
* 1: the input could not be converted, or the output would replace an input or a file meshtool did not
  write (one ``error:`` line on stderr, nothing written; ``--force`` replaces files of other kinds, never
  an input);
* 2: usage error (click);
* 3: meshtool itself failed (a bug: please report it; set ``MESHTOOL_DEBUG=1`` for the traceback).

Start-up: this module imports click and nothing else heavy. The commands live in
:mod:`meshtool.cli.mesh_commands`, :mod:`meshtool.cli.model_commands`, :mod:`meshtool.cli.pack` and
:mod:`meshtool.cli.validate` (what they share: :mod:`meshtool.cli.command_support`) and are imported when one of
them runs, so
``meshtool --version`` and ``meshtool --help`` never import numpy, trimesh or Pillow.
"""

from __future__ import annotations

import importlib
import os
from typing import Any

import click

from meshtool import __version__
from meshtool.cli.common import VocabularyGroup

# Before anything imports numpy: OpenBLAS's worker threads spin while they wait, which cost a small
# asset's obj2bin --mjcf 0.75 s CPU instead of 0.42 s (issue 28); the arrays here are too small to gain
# from them. A user's own OPENBLAS_NUM_THREADS is kept.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")


#: Command name -> (``module:attribute``, the first paragraph of its help, shown by ``meshtool --help``).
#: tests/test_startup.py checks that each summary is the command's own.
COMMANDS: dict[str, tuple[str, str]] = {
    "export": ("meshtool.cli.pack:export", "Export an .mbin as GLB, MuJoCo's legacy MSH and/or USD."),
    "hulls": (
        "meshtool.cli.mesh_commands:hulls",
        "Compute the collision hulls of SRC (a mesh file) and report their quality; writes nothing.",
    ),
    "info": (
        "meshtool.cli.pack:info",
        "Describe an .mbin file: counts, sections, sizes, checksums and metadata.",
    ),
    "mjcf": (
        "meshtool.cli.model_commands:mjcf",
        "Write a MuJoCo model for SRC: an .mbin, a mesh file (packed first, as obj2bin does) or a folder of .mbin.",
    ),
    "normalize": (
        "meshtool.cli.mesh_commands:normalize",
        "Normalise SRC (OBJ, STL, PLY, glTF/GLB or COLLADA) into OUTPUT/NAME/: metres, Z-up, PNG textures.",
    ),
    "unpack": ("meshtool.cli.pack:unpack", "Turn an .mbin back into OBJ/MTL/PNG in OUTPUT/NAME/."),
    "urdf": (
        "meshtool.cli.model_commands:urdf",
        "Import ROBOT (a URDF): every mesh normalised, packed and hulled; an MJCF of the robot.",
    ),
    "validate": (
        "meshtool.cli.validate:validate_command",
        "Check OBJ sources and .mbin packs under PATHS against the rules of docs/validate-rules.md.",
    ),
}


def _import(target: str) -> Any:
    module, _, attribute = target.partition(":")
    return getattr(importlib.import_module(module), attribute)


class LazyGroup(VocabularyGroup):
    """A click group whose subcommands are imported when one is run (or its own help is asked for).

    The group's ``--help`` lists the commands from :data:`COMMANDS` without importing them.
    """

    def list_commands(self, ctx: click.Context) -> list[str]:
        """Every command name, loaded or not, sorted."""
        return sorted({*super().list_commands(ctx), *COMMANDS})

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        """The command, imported on first use."""
        if cmd_name not in self.commands and cmd_name in COMMANDS:
            command = _import(COMMANDS[cmd_name][0])
            if not isinstance(command, click.Command):  # pragma: no cover - a broken table is a bug
                raise TypeError(f"{COMMANDS[cmd_name][0]} is not a click command")
            self.add_command(command, cmd_name)
        return super().get_command(ctx, cmd_name)

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        """The group's command list from :data:`COMMANDS`, importing none of them."""
        names = self.list_commands(ctx)
        if not names:
            return
        limit = formatter.width - 6 - max(len(n) for n in names)
        rows = []
        for name in names:
            loaded = self.commands.get(name)
            summary = COMMANDS[name][1] if loaded is None else None
            command = loaded or click.Command(name, help=summary)
            if not command.hidden:
                rows.append((name, command.get_short_help_str(limit)))
        if rows:
            with formatter.section("Commands"):
                formatter.write_dl(rows)


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="meshtool")
def main() -> None:
    """Make mesh assets (OBJ/MTL, STL, PLY, glTF/GLB, COLLADA) simulation-ready."""


def __getattr__(name: str) -> Any:
    """``obj2bin`` (its own console script) and the commands, imported on first use."""
    if name == "obj2bin":
        return _import("meshtool.cli.mesh_commands:obj2bin")
    if name in COMMANDS:
        return _import(COMMANDS[name][0])
    raise AttributeError(f"module 'meshtool.cli.main' has no attribute {name!r}")


if __name__ == "__main__":  # pragma: no cover
    main()
