"""Start-up: `import meshtool`, `meshtool --version` and `--help` import no heavy module (no timings here)."""

from __future__ import annotations

import json
import subprocess
import sys

import click
import pytest

HEAVY = ("trimesh", "mujoco", "pxr", "scipy", "coacd", "dask", "numpy", "PIL", "manifold3d", "simrun")


def _imported(code: str) -> set[str]:
    probe = f"{code}\nimport json, sys\nprint(json.dumps(sorted(sys.modules)))"
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True).stdout
    return {name.split(".")[0] for name in json.loads(out.strip().splitlines()[-1])}


RUN = (
    "import sys; sys.argv = ['meshtool', '{}']\nfrom meshtool.cli.main import main\n"
    "try: main()\nexcept SystemExit: pass"
)


@pytest.mark.parametrize(
    "code",
    [
        "import meshtool",
        "import meshtool.cli.main",
        "from meshtool import __version__",
        RUN.format("--version"),
        RUN.format("--help"),
    ],
)
def test_light_start_imports_nothing_heavy(code: str) -> None:
    assert not _imported(code) & set(HEAVY)


def test_library_paths_that_need_no_trimesh() -> None:
    """Loading an .mbin and the normalise/pack path never import trimesh, scipy, mujoco or pxr."""
    loaded = _imported(
        "import meshtool\nfrom meshtool.packfile import load, pack\n"
        "import meshtool.repair.normalise, meshtool.pipeline\n"
        "import meshtool.cli.mesh_commands, meshtool.cli.model_commands"
    )
    assert not loaded & {"trimesh", "scipy", "mujoco", "pxr", "coacd", "dask", "simrun"}


def test_lazy_names_resolve() -> None:
    import meshtool
    from meshtool.packfile import load
    from meshtool.repair.normalise import normalise as function

    assert meshtool.load is load and meshtool.normalise is function  # the function, not the submodule
    assert set(meshtool.__all__) <= set(dir(meshtool))
    with pytest.raises(AttributeError):
        meshtool.nothing  # noqa: B018


def test_help_summaries_are_the_commands_own() -> None:
    """`meshtool --help` lists the commands from a table; each summary must match the command's docstring."""
    from meshtool.cli import main as cli

    ctx = click.Context(cli.main)
    for name, (target, summary) in cli.COMMANDS.items():
        command = cli._import(target)
        assert command.name == name
        assert command.get_short_help_str(500) == click.Command(name, help=summary).get_short_help_str(500)
    listed = set(cli.main.list_commands(ctx))
    assert listed == set(cli.COMMANDS)
    assert cli.obj2bin.name == "obj2bin"
