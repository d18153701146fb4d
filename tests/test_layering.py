"""House rules that are cheap to check by machine."""

import ast
import itertools
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


@pytest.mark.parametrize(
    "path", sorted((ROOT / "meshtool").rglob("*.py")), ids=lambda p: p.relative_to(ROOT).as_posix()
)
def test_meshtool_never_imports_simrun_or_mujoco(path):
    assert not imports(path) & {"simrun", "mujoco"}


@pytest.mark.parametrize(
    "path", sorted((ROOT / "meshtool").rglob("*.py")), ids=lambda p: p.relative_to(ROOT).as_posix()
)
def test_library_code_does_not_print_or_exit(path):
    if path.parent.name == "cli" or path.name == "coacd_worker.py":  # the command lines and CoACD's child process
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


CLI_MODULES = sorted(
    p
    for package in ("meshtool", "simrun")
    for p in (ROOT / package).rglob("*.py")
    if p.name.startswith("cli") or "cli" in p.relative_to(ROOT).parts[1:-1]
)


@pytest.mark.parametrize("path", CLI_MODULES, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_commands_say_what_they_did_through_the_one_reporting_layer(path):
    """No command prints: lines, files written, findings and errors go through meshtool/cli/output.py.

    That is how ``--json`` is made from what the command did (not from captured text), and how ``-q`` and
    the exit codes are the same everywhere.
    """
    if path.relative_to(ROOT).as_posix() in ("meshtool/cli/output.py", "meshtool/cli/common.py"):
        return
    tree = ast.parse(path.read_text())
    printing = [
        f"{path.name}:{node.lineno}: {ast.unparse(node.func)}"
        for node in ast.walk(tree)
        if isinstance(node, ast.Call)
        and (
            (isinstance(node.func, ast.Name) and node.func.id in ("print", "exit"))
            or ast.unparse(node.func) in ("click.echo", "click.secho", "sys.stdout.write", "sys.stderr.write")
        )
    ]
    assert not printing


def test_the_reporting_check_sees_every_cli_module():
    names = {p.relative_to(ROOT).as_posix() for p in CLI_MODULES}
    assert {
        "meshtool/cli/mesh_commands.py",
        "meshtool/cli/model_commands.py",
        "meshtool/cli/command_support.py",
        "simrun/cli/main.py",
        "simrun/cli/scene_commands.py",
        "simrun/cli/log_commands.py",
        "simrun/cli/scenetest.py",
        "meshtool/cli/output.py",
    } <= names


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


PACKAGES = ("meshtool", "simrun")


def package_files(*packages: str) -> list[Path]:
    """Every module of ``packages`` (all subpackages), sorted."""
    return sorted(p for package in packages for p in (ROOT / package).rglob("*.py"))


def module_name(path: Path) -> str:
    """``simrun/scenetest/reports.py`` -> ``simrun.scenetest.reports``; a package's ``__init__.py`` -> the package."""
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {module_name(p): p for p in package_files(*PACKAGES)}


def _rel(path: Path) -> str:
    return path.relative_to(ROOT).as_posix()


def _runtime_nodes(tree: ast.Module) -> list[ast.AST]:
    """Every node of ``tree`` that runs (function bodies too), without ``if TYPE_CHECKING:`` blocks."""
    skipped = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            skipped.update(id(n) for child in node.body for n in ast.walk(child))
    return [node for node in ast.walk(tree) if id(node) not in skipped]


def _from_base(node: ast.ImportFrom, module: str) -> str:
    """The absolute module an ``ImportFrom`` in ``module`` names (relative imports resolved)."""
    if node.level == 0:
        return node.module or ""
    package = module if MODULES[module].name == "__init__.py" else module.rpartition(".")[0]
    parts = package.split(".")
    base = parts[: len(parts) - node.level + 1]
    return ".".join([*base, *([node.module] if node.module else [])])


def _known(name: str) -> str | None:
    """``name`` or its longest prefix that is one of :data:`MODULES` (``None``: outside both packages)."""
    parts = name.split(".")
    for end in range(len(parts), 0, -1):
        if ".".join(parts[:end]) in MODULES:
            return ".".join(parts[:end])
    return None


def import_edges(module: str) -> list[tuple[str, str]]:
    """(imported module, ``file:line: source``) for every import in ``module`` that runs, functions included.

    ``from pkg import mod`` counts as importing ``pkg.mod`` when that is a module, else ``pkg`` itself.
    Only modules of meshtool and simrun are kept.
    """
    path = MODULES[module]
    source = path.read_text()
    lines = source.splitlines()
    edges = []
    for node in _runtime_nodes(ast.parse(source)):
        targets: list[str | None] = []
        if isinstance(node, ast.Import):
            targets = [_known(a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = _from_base(node, module)
            targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in MODULES else _known(base) for a in node.names]
        where = f"{_rel(path)}:{getattr(node, 'lineno', 0)}: {lines[getattr(node, 'lineno', 1) - 1].strip()}"
        edges.extend((t, where) for t in dict.fromkeys(targets) if t is not None and t != module)
    return edges


def entry_point_targets() -> dict[tuple[str, str], str]:
    """(group, name) -> target module of every ``meshtool.*`` entry point pyproject.toml declares."""
    import tomllib

    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    return {
        (group, name): value.split(":")[0]
        for group, points in project.get("entry-points", {}).items()
        if group.startswith("meshtool.")
        for name, value in points.items()
    }


def plugin_loads(module: str) -> list[tuple[str, str, int]]:
    """(group, name, line) of every ``load_plugin(GROUP, "name")`` call in ``module``.

    ``GROUP`` is a string literal or a module-level constant of ``module`` bound to one.
    """
    tree = ast.parse(MODULES[module].read_text())
    constants = {
        node.targets[0].id: node.value.value
        for node in tree.body
        if isinstance(node, ast.Assign)
        and len(node.targets) == 1
        and isinstance(node.targets[0], ast.Name)
        and isinstance(node.value, ast.Constant)
        and isinstance(node.value.value, str)
    }
    loads = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and ast.unparse(node.func).endswith("load_plugin") and len(node.args) == 2:
            group, name = node.args
            value = group.value if isinstance(group, ast.Constant) else constants.get(getattr(group, "id", ""))
            assert isinstance(value, str) and isinstance(name, ast.Constant), ast.unparse(node)
            loads.append((value, name.value, node.lineno))
    return loads


def import_graph(packages: tuple[str, ...] = PACKAGES) -> dict[str, dict[str, str]]:
    """Module -> {imported module: where the first such import is} among the modules of ``packages``.

    The registry's lazy targets (``module:Class``, imported on first use) count as imports of
    ``simrun.world.registry.tables``, where the table is.
    """
    inside = {m for m in MODULES if m.split(".")[0] in packages}
    graph: dict[str, dict[str, str]] = {m: {} for m in inside}
    for module in inside:
        for target, where in import_edges(module):
            if target in inside:
                graph[module].setdefault(target, where)
    targets = entry_point_targets()
    for module in inside:  # an entry point loaded at run time is an import of its target by the loading module
        for group, name, line in plugin_loads(module) if module.startswith("meshtool") else []:
            target = targets.get((group, name))
            if target in inside:
                graph[module].setdefault(target, f"{_rel(MODULES[module])}:{line}: loads entry point {group}:{name}")
    if "simrun.world.registry.tables" in graph:
        from simrun.world.registry.tables import REGISTRY

        for t in REGISTRY.values():
            target = t.target.split(":")[0]
            graph["simrun.world.registry.tables"].setdefault(
                target, f"simrun/world/registry/tables.py: REGISTRY target {t.target}"
            )
    return graph


def import_cycles(graph: dict[str, dict[str, str]]) -> list[list[str]]:
    """One cycle (``[a, b, ..., a]``) through each strongly connected group of modules of ``graph``."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    groups: list[set[str]] = []

    def connect(name: str) -> None:  # Tarjan
        index[name] = low[name] = len(index)
        stack.append(name)
        for target in sorted(graph[name]):
            if target not in index:
                connect(target)
                low[name] = min(low[name], low[target])
            elif target in stack:
                low[name] = min(low[name], index[target])
        if low[name] == index[name]:
            group = set()
            while True:
                member = stack.pop()
                group.add(member)
                if member == name:
                    break
            if len(group) > 1:
                groups.append(group)

    for name in sorted(graph):
        if name not in index:
            connect(name)
    cycles = []
    for group in groups:
        start = min(group)
        # the shortest way back to ``start`` inside the group (breadth first)
        previous: dict[str, str] = {}
        frontier = [start]
        while frontier and start not in previous:
            following = []
            for name in frontier:
                for target in sorted(graph[name]):
                    if target in group and target not in previous:
                        previous[target] = name
                        following.append(target)
            frontier = following
        path = [start]
        while path[-1] != start or len(path) == 1:
            path.append(previous[path[-1]])
        cycles.append(path[::-1])
    return sorted(cycles)


def describe_cycles(graph: dict[str, dict[str, str]], cycles: list[list[str]]) -> str:
    """Each cycle as ``a -> b -> a`` followed by the import line of each step."""
    text = []
    for cycle in cycles:
        text.append("import cycle: " + " -> ".join(cycle))
        text.extend(f"    {graph[a][b]}" for a, b in itertools.pairwise(cycle))
    return "\n".join(text)


def test_simrun_has_no_import_cycle():
    """No cycle among simrun's modules, counting imports inside functions and the registry's lazy targets."""
    graph = import_graph(("simrun",))
    assert {
        "simrun.sensors.laser",
        "simrun.robots.arm",
        "simrun.sensors.range_cone",
        "simrun.services.drive_service",
    } <= set(graph["simrun.world.registry.tables"])
    assert {"simrun.scenetest.reports", "simrun.scenetest.report_html"} <= set(graph)  # subpackages too
    cycles = import_cycles(graph)
    assert not cycles, describe_cycles(graph, cycles)


def test_packages_have_no_import_cycle():
    """No cycle in the import graph of meshtool and simrun together (every module, function-level imports too).

    A function-level import between two modules that would form a cycle (one hidden until the function runs)
    fails here like a top-level one.
    """
    graph = import_graph()
    assert {"meshtool.validate.reports.html", "simrun.scenetest.report_html"} <= set(graph)
    cycles = import_cycles(graph)
    assert not cycles, describe_cycles(graph, cycles)


def test_entry_points_count_as_imports_by_the_module_that_loads_them():
    """meshtool reaches simrun at run time only through entry points, and each load is an edge of the graph.

    Entry points are looked up in ``meshtool/plugins.py`` only and loaded through its ``load_plugin``; every
    entry point pyproject.toml declares is loaded somewhere, and each load is an import of its target, so
    :func:`test_packages_have_no_import_cycle` counts them.
    """
    targets = entry_point_targets()
    assert set(targets.values()) >= {"simrun.export.mjcf_builder", "simrun.asset_check"}
    graph = import_graph()
    loaded = {}
    for module in MODULES:
        if module.startswith("meshtool"):
            for group, name, _ in plugin_loads(module):
                loaded[(group, name)] = module
                assert targets[(group, name)] in graph[module], (module, group, name)
    assert set(loaded) == set(targets), "declared but never loaded, or loaded but not declared"
    lookups = [
        f"{_rel(path)}:{node.lineno}"
        for path in package_files("meshtool")
        for node in ast.walk(ast.parse(path.read_text()))
        if (isinstance(node, ast.Name) and node.id == "entry_points")
        or (isinstance(node, ast.Attribute) and node.attr == "entry_points")
        or (isinstance(node, ast.alias) and node.name == "entry_points")
    ]
    assert lookups and all(where.startswith("meshtool/plugins.py:") for where in lookups), lookups
    loader = loaded[("meshtool.mjcf", "builder")]  # the edge would close a cycle if the plugin imported its loader
    assert import_cycles(
        {**graph, "simrun.export.mjcf_builder": {**graph["simrun.export.mjcf_builder"], loader: "probe"}}
    )


def test_the_cycle_check_sees_function_level_and_relative_imports():
    """The graph resolves ``from . import x``, ``from pkg import mod`` and imports inside functions."""
    edges = {
        "a": {"b": "a.py:1"},
        "b": {"c": "b.py:3"},
        "c": {"a": "c.py:9"},
        "d": {"a": "d.py:1"},
    }
    assert import_cycles(edges) == [["a", "b", "c", "a"]]
    assert "c.py:9" in describe_cycles(edges, import_cycles(edges))
    node = ast.parse("from .report_lines import verdict_line").body[0]
    assert isinstance(node, ast.ImportFrom)
    assert _from_base(node, "simrun.scenetest.reports") == "simrun.scenetest.report_lines"
    node = ast.parse("from .. import errors").body[0]
    assert isinstance(node, ast.ImportFrom)
    assert _from_base(node, "simrun.scenetest") == "simrun"
    reports = dict(import_edges("simrun.scenetest.reports"))
    assert "simrun.scenetest.report_html" in reports
    assert "meshtool.work.reportkit" in reports


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def private_uses(source: str, module: str) -> list[str]:
    """``line: what`` for each ``_private`` name of the other package that ``module`` (text ``source``) uses.

    Caught: ``from pkg.mod import _name``, an import of a ``_private`` module, and ``alias._name`` (or a
    longer chain) on any name an import of the other package bound. ``if TYPE_CHECKING:`` imports count too.
    """
    own = module.split(".")[0]
    tree = ast.parse(source)
    bound: set[str] = set()  # local names bound to the other package's modules or objects
    bad = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.name.split(".")[0] in PACKAGES and a.name.split(".")[0] != own:
                    bad += [f"{node.lineno}: import {a.name}" for part in a.name.split(".") if _private(part)]
                    bound.add(a.asname or a.name.split(".")[0])
        elif isinstance(node, ast.ImportFrom):
            base = _from_base(node, module)
            if base.split(".")[0] in PACKAGES and base.split(".")[0] != own:
                bad += [f"{node.lineno}: from {base}" for part in base.split(".") if _private(part)]
                bad += [f"{node.lineno}: from {base} import {a.name}" for a in node.names if _private(a.name)]
                bound.update(a.asname or a.name for a in node.names)
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and _private(node.attr):
            root = node.value
            while isinstance(root, ast.Attribute):
                root = root.value
            if isinstance(root, ast.Name) and root.id in bound:
                bad.append(f"{node.lineno}: {ast.unparse(node)}")
    return bad


@pytest.mark.parametrize("path", package_files(*PACKAGES), ids=_rel)
def test_no_private_name_crosses_packages(path):
    """Neither package imports (or reaches through an imported module for) a ``_private`` name of the other."""
    bad = private_uses(path.read_text(), module_name(path))
    assert not bad, f"{_rel(path)} uses private names of the other package: {bad}"


def test_the_private_name_check_catches_aliases():
    """``import meshtool.x as y; y._name``, ``from meshtool.x import _name`` and the like are all caught."""
    for source in (
        "import meshtool.validate.reports.machine as m\nm._data('x')\n",
        "import meshtool.validate.reports.machine\nmeshtool.validate.reports.machine._data('x')\n",
        "from meshtool.validate.reports.machine import _data\n",
        "from meshtool.validate.reports import machine\nmachine._prop('x')\n",
        "def f():\n    from meshtool.validate.reports.html import _CSS as css\n",
        "import meshtool._hidden\n",
    ):
        assert private_uses(source, "simrun.probe"), source
    assert private_uses("from simrun.world.world import World\nWorld._x\n", "meshtool.probe")
    assert not private_uses("from meshtool import __version__\nfrom simrun.world.world import _y\n", "simrun.probe")
    assert not private_uses("import simrun.world.world as w\nw._z\n", "simrun.probe")  # own package: fine


@pytest.mark.parametrize("package", PACKAGES)
def test_each_module_imports_alone(package):
    """Each module imports first in a fresh interpreter (an order-dependent cycle would fail here).

    Every module of the package, subpackages included; the package's own modules are unloaded before each.
    """
    import subprocess
    import sys

    names = sorted(m for m in MODULES if m.split(".")[0] == package and m != package)
    script = (
        "import importlib, sys\n"
        "bad = []\n"
        f"for name in {names!r}:\n"
        f"    for loaded in [m for m in sys.modules if m in {PACKAGES!r} or m.split('.')[0] in {PACKAGES!r}]:\n"
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


#: simrun's concept folders (issue 37): each holds one idea; the package's top keeps only what every part shares.
SIMRUN_FOLDERS = {
    "world",
    "entities",
    "robots",
    "services",
    "sensors",
    "scene",
    "run",
    "record",
    "export",
    "scenetest",
    "serve",
    "cli",
}


def test_simrun_top_level_is_its_concept_folders_and_a_few_shared_modules():
    top = sorted(p.name for p in (ROOT / "simrun").glob("*.py"))
    folders = {p.name for p in (ROOT / "simrun").iterdir() if p.is_dir() and (p / "__init__.py").exists()}
    assert len(top) <= 12, top
    assert folders == SIMRUN_FOLDERS


@pytest.mark.parametrize("folder", sorted(SIMRUN_FOLDERS))
def test_every_simrun_folder_says_what_it_holds(folder):
    init = ROOT / "simrun" / folder / "__init__.py"
    assert ast.get_docstring(ast.parse(init.read_text())), init


#: meshtool's stage and infrastructure folders (issue 38): read -> frame -> repair -> hulls -> pack, composed in
#: meshtool/pipeline.py, with the outputs and the folders every stage shares.
MESHTOOL_FOLDERS = {
    "read",
    "frame",
    "repair",
    "hulls",
    "packfile",
    "export",
    "mjcf",
    "urdf",
    "validate",
    "files",
    "work",
    "cli",
}


def test_meshtool_top_level_is_its_stage_folders_and_a_few_shared_modules():
    top = sorted(p.name for p in (ROOT / "meshtool").glob("*.py"))
    folders = {p.name for p in (ROOT / "meshtool").iterdir() if p.is_dir() and (p / "__init__.py").exists()}
    assert len(top) <= 12, top
    assert folders == MESHTOOL_FOLDERS


@pytest.mark.parametrize("folder", sorted(MESHTOOL_FOLDERS))
def test_every_meshtool_folder_says_what_it_holds(folder):
    init = ROOT / "meshtool" / folder / "__init__.py"
    assert ast.get_docstring(ast.parse(init.read_text())), init


#: Each stage's entry (module, function): only meshtool/pipeline.py calls them in sequence (issue 38). The
#: composer's order: read -> frame -> repair -> hulls -> packfile; the entries each stage's own entry reaches
#: (read_mesh, read_triangles, source_frame, decide_frame, build_mesh) are listed too, so nothing outside the
#: stage's folder calls them either. tests/test_pipeline_stages.py counts each once per file.
STAGE_ENTRIES = {
    ("meshtool.read.source_asset", "read_source_asset"): "read",
    ("meshtool.read", "read_mesh"): "read",
    ("meshtool.read.triangles", "read_triangles"): "read",
    ("meshtool.frame.declared", "decide_asset_frame"): "frame",
    ("meshtool.frame.declared", "source_frame"): "frame",
    ("meshtool.frame.decide", "decide_frame"): "frame",
    ("meshtool.repair.convert", "convert_asset"): "repair",
    ("meshtool.repair.mesh", "build_mesh"): "repair",
    ("meshtool.hulls.compute", "compute_hulls"): "hulls",
    ("meshtool.packfile", "pack"): "packfile",
    ("meshtool.packfile.write", "pack"): "packfile",
}
#: Callers of a stage entry besides the composer and the stage's own folder, each with why. ``build_mesh(obj)``
#: without the read stage's triangles (tests, bench/parse.py) triangulates the polygons itself; the composer
#: passes the read stage's (tests/test_pipeline_stages.py: read_triangles entered once per file, in read).
STAGE_ENTRY_EXCEPTIONS: set[tuple[str, str]] = {("meshtool/repair/mesh.py", "read_triangles")}


def stage_entry_uses(source: str, module: str) -> list[tuple[str, str]]:
    """``(name, stage)`` of every stage entry the code of ``module`` imports or reaches as ``mod.entry``.

    Imports under ``if TYPE_CHECKING:`` are left out: they never run.
    """
    found = []
    for node in _runtime_nodes(ast.parse(source)):  # an ``if TYPE_CHECKING:`` import calls nothing
        if isinstance(node, ast.ImportFrom):
            base = _from_base(node, module)
            found += [(a.name, STAGE_ENTRIES[(base, a.name)]) for a in node.names if (base, a.name) in STAGE_ENTRIES]
        elif isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name):
            # ``from meshtool.hulls import compute`` then ``compute.compute_hulls(...)``
            for (entry_module, name), stage in STAGE_ENTRIES.items():
                if node.attr == name and entry_module.endswith(f".{node.value.id}"):
                    found.append((name, stage))
    return found


@pytest.mark.parametrize("path", package_files(*PACKAGES), ids=lambda p: p.relative_to(ROOT).as_posix())
def test_only_the_composer_calls_a_stage_entry(path):
    rel = _rel(path)
    if rel == "meshtool/pipeline.py":
        return
    wrong = [
        f"{name} ({stage})"
        for name, stage in stage_entry_uses(path.read_text(), module_name(path))
        if not rel.startswith(f"meshtool/{stage}/") and (rel, name) not in STAGE_ENTRY_EXCEPTIONS
    ]
    assert not wrong, f"{rel} calls stage entries {wrong}: go through meshtool/pipeline.py"


def test_the_stage_entry_check_sees_imports_and_attribute_calls():
    sample = (
        "from meshtool.hulls import compute\nfrom meshtool.packfile import pack\nx = compute.compute_hulls\n"
        "def f():\n    from meshtool.repair.convert import convert_asset\n    return struct.pack\n"
        "if TYPE_CHECKING:\n    from meshtool.read import read_mesh\n"
    )
    found = stage_entry_uses(sample, "meshtool.urdf.meshes")
    assert sorted(found) == [("compute_hulls", "hulls"), ("convert_asset", "repair"), ("pack", "packfile")]
    assert stage_entry_uses("from meshtool.read import read_mesh\n", "meshtool.urdf.meshes") == [("read_mesh", "read")]


def test_every_stage_entry_exists():
    """Each (module, function) of :data:`STAGE_ENTRIES` names a function there (a renamed entry fails here)."""
    import importlib
    import inspect

    for module, name in STAGE_ENTRIES:
        assert inspect.isfunction(getattr(importlib.import_module(module), name, None)), (module, name)
