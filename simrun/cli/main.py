"""The ``simrun`` command line: a thin layer over the library.

The group, ``doctor`` and ``--allow-root`` live here; the commands over a scene in :mod:`simrun.cli.scene_commands`,
over a recorded log in :mod:`simrun.cli.log_commands`, ``simrun test`` in :mod:`simrun.cli.scenetest` and
``simrun serve`` in :mod:`simrun.cli.serve`.
"""

from __future__ import annotations

import functools
import os
import sys
from pathlib import Path
from typing import Any

import click

from meshtool.cli import output as out
from meshtool.cli.common import VocabularyGroup
from meshtool.cli.output import EXIT_INPUT, fail
from simrun import __version__
from simrun.cli.log_commands import replay, resim
from simrun.cli.scene_commands import check, export, play_command, snapshot, view
from simrun.cli.scenetest import test_command
from simrun.cli.serve import serve_command

# Before anything imports numpy: single-threaded OpenBLAS (its idle threads spin; see meshtool/cli/main.py).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
# Start-up (issue 28): this module imports click and simrun's light modules only; numpy, Pillow, MuJoCo and
# the exporters (glb_export -> trimesh) are imported inside the command that uses them, so ``simrun --help``
# and every ``simrun COMMAND --help`` stay close to a bare click program (tests/test_perf_startup.py).

#: Exit codes: the one table of :data:`meshtool.cli.output.EXIT_CODES` (docs/cli.md), mapped by
#: :func:`meshtool.cli.output.fail`; what a command produced is said through :mod:`meshtool.cli.output`.
#: ``SIMRUN_DEBUG=1`` gives the traceback of an internal error (exit 3).


class _Group(VocabularyGroup):
    """The command group: a user error is one ``error:`` line (exit 1), a bug one ``internal error:`` line (3).

    The vocabulary shared with meshtool (``--json``, ``-q``, ``-v``, exit codes: docs/cli.md) comes from
    :class:`meshtool.cli.common.VocabularyGroup`.
    """

    program = "simrun"

    def run_command(self, ctx: click.Context) -> Any:
        """Run the command, mapping simrun's errors to exit codes; then the notes of the model cache."""
        try:
            return self._mapped(ctx)
        finally:  # a damaged or foreign compiled-model cache entry: compiled again, said once
            model_cache = sys.modules.get("simrun.world.model_cache")  # no cache opened when it was never imported
            for note in model_cache.notes() if model_cache is not None else ():
                out.note(note)

    def _mapped(self, ctx: click.Context) -> Any:
        try:
            return super().run_command(ctx)
        except (click.exceptions.ClickException, click.exceptions.Exit, click.exceptions.Abort):
            raise
        except Exception as exc:  # one mapping (meshtool.cli.output.fail): its kind decides 1 or 2; a bug is 3
            fail(exc, "simrun")


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="simrun")
def main() -> None:
    """Run MuJoCo worlds of meshtool assets.

    Exit codes: 0 ok, 1 invalid input or a failed check (one 'error:' line naming the file and line), 2 usage,
    3 simrun failed (a bug; SIMRUN_DEBUG=1 shows the traceback).
    """


main.add_command(serve_command)  # simrun serve (simrun/cli/serve.py)
main.add_command(test_command)  # simrun test: scene tests with [[expect]] (simrun/cli/scenetest.py)


@main.command("doctor")
@click.option("--json", "as_json", is_flag=True, help="Print the report as one JSON object.")
def doctor(as_json: bool) -> None:
    """Check MuJoCo: version, compile and step a model, which GL backend renders and which headless ones start."""
    from simrun.doctor import check_environment

    report = check_environment()
    choice = report.choice
    gl = {"backend": choice.backend, "reason": choice.reason, "problem": choice.problem} if choice else None
    document: dict[str, Any] = {"status": "ok" if report.physics_ok else "error", "mujoco": report.mujoco_version}
    document |= {"physics_ok": report.physics_ok, "physics_error": report.physics_error}
    document |= {"rendering": gl, "backends": {k: v is None for k, v in report.gl.items()}, "problems": report.gl}
    out.report(document)
    for line in report.lines():
        out.say(line)
    if not report.physics_ok:
        raise SystemExit(EXIT_INPUT)


main.add_command(check)
main.add_command(export)
main.add_command(play_command)
main.add_command(replay)
main.add_command(resim)
main.add_command(view)
main.add_command(snapshot)


#: Folders MJCF models may read from besides the scene's and their own (simrun.robots.mjcf_read.ALLOW_ROOTS_ENV;
#: this module imports no MuJoCo, so the name is written here and tests/test_mjcf_hostile.py checks they agree).
ALLOW_ROOTS_ENV = "SIMRUN_ALLOW_ROOTS"


def _allow_root(command: click.Command) -> click.Command:
    """Give a scene command ``--allow-root DIR`` (repeatable): MJCF models may read files inside DIR too.

    The folders go to the reader through ``SIMRUN_ALLOW_ROOTS`` (absolute, ``os.pathsep``-separated) for as long
    as the command runs, so the processes it starts (``simrun test`` runs, Dask workers) allow them as well.
    """
    command.params.append(
        click.Option(
            ["--allow-root", "allow_roots"],
            multiple=True,
            type=click.Path(path_type=Path, file_okay=False, exists=True),
            help="A folder MJCF models may read files from besides the scene's and their own (repeatable; "
            "docs/limits.md).",
        )
    )
    callback = command.callback
    assert callback is not None

    def run(*args: Any, allow_roots: tuple[Path, ...] = (), **kwargs: Any) -> Any:
        before = os.environ.get(ALLOW_ROOTS_ENV)
        if allow_roots:
            known = [p for p in (before or "").split(os.pathsep) if p]
            os.environ[ALLOW_ROOTS_ENV] = os.pathsep.join([*known, *(os.path.abspath(p) for p in allow_roots)])
        try:
            return callback(*args, **kwargs)
        finally:
            if allow_roots and before is None:
                os.environ.pop(ALLOW_ROOTS_ENV, None)
            elif allow_roots and before is not None:
                os.environ[ALLOW_ROOTS_ENV] = before

    command.callback = functools.update_wrapper(run, callback)
    return command


for _command in (check, export, play_command, snapshot, view, test_command, serve_command):
    _allow_root(_command)
