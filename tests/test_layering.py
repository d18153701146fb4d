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
    entry_points = ("cli.py", "cli_commands.py", "cli_common.py", "cli_validate.py", "coacd_worker.py")  # CLI, CoACD
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


def _simrun_imports(path: Path) -> set[str]:
    """simrun modules a module imports when it runs (function bodies too; ``if TYPE_CHECKING:`` blocks not)."""
    tree = ast.parse(path.read_text())
    skipped = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            skipped.update(id(n) for child in node.body for n in ast.walk(child))
    found = set()
    for node in ast.walk(tree):
        if id(node) in skipped:
            continue
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names if a.name.startswith("simrun."))
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0 and node.module.startswith("simrun"):
            if node.module == "simrun":
                found.update(f"simrun.{a.name}" for a in node.names)
            else:
                found.add(node.module)
    return found


def test_simrun_has_no_import_cycle():
    """No cycle among simrun's modules, counting imports inside functions and the registry's lazy targets."""
    from simrun.registry import REGISTRY

    modules = {f"simrun.{p.stem}": p for p in (ROOT / "simrun").glob("*.py") if p.stem != "__init__"}
    graph = {name: {m for m in _simrun_imports(path) if m in modules and m != name} for name, path in modules.items()}
    graph["simrun.registry"] |= {t.target.split(":")[0] for t in REGISTRY.values()}
    assert {"simrun.sensors", "simrun.arm", "simrun.cameras", "simrun.drive_service"} <= graph["simrun.registry"]
    state: dict[str, int] = {}  # 1 on the stack, 2 done

    def visit(name: str, stack: list[str]) -> None:
        state[name] = 1
        for target in sorted(graph[name]):
            if state.get(target) == 1:
                cycle = [*stack[stack.index(target) :], target]
                raise AssertionError("import cycle: " + " -> ".join(cycle))
            if target not in state:
                visit(target, [*stack, target])
        state[name] = 2

    for name in sorted(graph):
        if name not in state:
            visit(name, [name])


def test_each_simrun_module_imports_alone():
    """Each module imports first in a fresh interpreter (an order-dependent cycle would fail here)."""
    import subprocess
    import sys

    names = sorted(f"simrun.{p.stem}" for p in (ROOT / "simrun").glob("*.py") if p.stem != "__init__")
    script = (
        "import importlib, sys\n"
        "bad = []\n"
        f"for name in {names!r}:\n"
        "    for loaded in [m for m in sys.modules if m == 'simrun' or m.startswith('simrun.')]:\n"
        "        del sys.modules[loaded]\n"
        "    try:\n"
        "        importlib.import_module(name)\n"
        "    except Exception as exc:\n"
        "        bad.append(f'{name}: {type(exc).__name__}: {exc}')\n"
        "print('\\n'.join(bad))\n"
    )
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300, check=False)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == ""
