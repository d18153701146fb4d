"""House rules that are cheap to check by machine."""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def imports(path: Path) -> set[str]:
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names.update(a.name.split(".")[0] for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module.split(".")[0])
    return names


@pytest.mark.parametrize("path", sorted((ROOT / "meshtool").rglob("*.py")), ids=lambda p: p.name)
def test_meshtool_never_imports_simrun_or_mujoco(path):
    assert not imports(path) & {"simrun", "mujoco"}


@pytest.mark.parametrize("path", sorted((ROOT / "meshtool").rglob("*.py")), ids=lambda p: p.name)
def test_library_code_does_not_print_or_exit(path):
    entry_points = ("cli.py", "cli_common.py", "cli_validate.py", "coacd_worker.py")  # the CLI, the CoACD child
    if path.name in entry_points:
        return
    tree = ast.parse(path.read_text())
    calls = {node.func.id for node in ast.walk(tree) if isinstance(node, ast.Call) and isinstance(node.func, ast.Name)}
    assert not calls & {"print", "exit", "quit"}
    exits = [
        node
        for node in ast.walk(tree)
        if isinstance(node, ast.Attribute)
        and node.attr in ("exit", "stdout", "stderr")
        and isinstance(node.value, ast.Name)
        and node.value.id == "sys"
    ]
    assert not exits


def test_only_the_resolver_reads_references():
    """File reads in the library happen in resolve.py (inputs) and outdir.py (writes) only."""
    io_attrs = {"read_bytes", "read_text", "write_bytes", "write_text", "iterdir", "glob", "rglob", "listdir"}
    for path in (ROOT / "meshtool").rglob("*.py"):
        if path.name in ("resolve.py", "outdir.py"):
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Call):
                f = node.func
                assert not (isinstance(f, ast.Name) and f.id == "open"), path
                assert not (isinstance(f, ast.Attribute) and f.attr in io_attrs), (path, f.attr)


def test_every_fixture_is_documented():
    readme = (ROOT / "fixtures" / "README.md").read_text()
    for folder in sorted(p for p in (ROOT / "fixtures").iterdir() if p.is_dir()):
        assert f"`{folder.name}/`" in readme, folder.name


def test_every_finding_code_is_documented():
    docs = (ROOT / "docs" / "findings.md").read_text()
    for path in (ROOT / "meshtool").rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if (
                isinstance(node, ast.Call)
                and isinstance(node.func, ast.Name)
                and node.func.id in ("info", "warning")
                and node.args
                and isinstance(node.args[0], ast.Constant)
            ):
                assert f"`{node.args[0].value}`" in docs, (path.name, node.args[0].value)
