"""meshtool validate: a hanging or crashing check costs one finding, not the run; workers die with their parent.

A deliberately slow physics plugin stands in for an asset that makes a rule hang: it sleeps for an hour
when the asset is named ``hang*.obj`` and kills its own process for ``crash*.obj``. In this process it is
patched in; for worker processes it is registered the way any plugin is, by an entry point of a
distribution found on ``sys.path`` (spawned workers inherit the parent's ``sys.path``).
"""

import json
import os
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest
from click.testing import CliRunner
from conftest import FIXTURES

from meshtool.cli.main import main
from meshtool.validate import ValidateOptions, load_config, render, validate
from meshtool.validate import task as task_module
from meshtool.validate.config import DEFAULT_TIMEOUT, ConfigError
from meshtool.validate.plugin_types import PhysicsOutcome

CLEAN = FIXTURES / "validate" / "clean"
PLUGIN = """
import os, signal, time
from pathlib import Path
from meshtool.validate.plugin_types import PhysicsOutcome

def check(mbin, name, limits, thumbnail):
    if name.startswith("hang"):
        folder = os.environ.get("SLOW_PLUGIN_PIDS")
        if folder:
            Path(folder, f"pid-{os.getpid()}").write_text(name)
        time.sleep(3600)
    if name.startswith("crash"):
        os.kill(os.getpid(), signal.SIGKILL)
    return PhysicsOutcome(notes=["slow plugin: nothing checked"])
"""


def slow_check(mbin, name, limits, thumbnail):
    if name.startswith("hang"):
        time.sleep(3600)
    return PhysicsOutcome(notes=["slow plugin: nothing checked"])


@pytest.fixture
def assets(tmp_path):
    """clean.obj and hang.obj (the same box) and a clean pack, in one folder."""
    folder = tmp_path / "assets"
    folder.mkdir()
    for name in ("box.obj", "box.mtl", "box.png", "box.mbin"):
        shutil.copy(CLEAN / name, folder / name)
    shutil.copy(CLEAN / "box.obj", folder / "hang.obj")
    return folder


@pytest.fixture
def plugin_on_path(tmp_path, monkeypatch):
    """Register the slow plugin as the first ``physics`` entry point for spawned workers."""
    site = tmp_path / "site"
    (site / "slow_plugin-1.0.dist-info").mkdir(parents=True)
    (site / "slow_plugin.py").write_text(PLUGIN)
    (site / "slow_plugin-1.0.dist-info" / "METADATA").write_text(
        "Metadata-Version: 2.1\nName: slow-plugin\nVersion: 1.0\n"
    )
    (site / "slow_plugin-1.0.dist-info" / "entry_points.txt").write_text(
        "[meshtool.validate]\nphysics = slow_plugin:check\n"
    )
    monkeypatch.syspath_prepend(str(site))
    return site


def codes(report):
    return {Path(a.path).name: sorted(f.code for f in a.findings) for a in report.assets}


def test_in_process_a_hanging_check_is_x002_and_the_run_goes_on(assets, monkeypatch):
    monkeypatch.setattr(task_module, "physics_plugin", lambda: slow_check)
    report = validate([assets], ValidateOptions(jobs=1, timeout=1.5))
    assert codes(report) == {"box.mbin": [], "box.obj": [], "hang.obj": ["X002"]}
    hang = next(a for a in report.assets if a.path.endswith("hang.obj"))
    assert "did not finish within 1.5 s" in hang.findings[0].message
    box = next(a for a in report.assets if a.path.endswith("box.obj"))
    assert "slow plugin: nothing checked" in box.notes  # the others were checked to the end
    assert report.failed(strict=False) and report.internal_errors() == 0
    assert json.loads(render(report, "json"))["summary"]["errors"] == 1


def test_workers_are_killed_at_the_deadline_and_replaced(assets, plugin_on_path):
    shutil.copy(CLEAN / "box.obj", assets / "hang2.obj")
    report = validate([assets], ValidateOptions(jobs=2, timeout=3))
    assert codes(report) == {"box.mbin": [], "box.obj": [], "hang.obj": ["X002"], "hang2.obj": ["X002"]}
    box = next(a for a in report.assets if a.path.endswith("box.obj"))
    assert "slow plugin: nothing checked" in box.notes  # the plugin on sys.path did run in the workers


def test_a_worker_that_dies_is_x001_for_its_asset_only(assets, plugin_on_path):
    os.rename(assets / "hang.obj", assets / "crash.obj")
    report = validate([assets], ValidateOptions(jobs=2, timeout=60))
    assert codes(report) == {"box.mbin": [], "box.obj": [], "crash.obj": ["X001"]}
    crash = next(a for a in report.assets if a.path.endswith("crash.obj"))
    assert "worker process checking it died (signal 9)" in crash.findings[0].message


def test_cli_timeout_writes_the_report_and_exits_1(assets, plugin_on_path, tmp_path):
    out = tmp_path / "report.json"
    args = ["validate", str(assets), "--timeout", "3", "-j", "2", "--no-cache", "--format", "json", "-o", str(out)]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 1, result.output
    document = json.loads(out.read_text())
    found = {Path(a["path"]).name: [f["rule"] for f in a["findings"]] for a in document["assets"]}
    assert found == {"box.mbin": [], "box.obj": [], "hang.obj": ["X002"]}
    assert "Traceback" not in result.output


def test_timeout_from_the_configuration(assets, plugin_on_path, tmp_path, monkeypatch):
    config = tmp_path / "meshtool.toml"
    config.write_text("[validate]\ntimeout = 2.5\n")
    assert load_config(config).timeout == 2.5
    assert load_config(None).timeout == DEFAULT_TIMEOUT == 300
    options = ValidateOptions(config=load_config(config), jobs=2)
    assert options.effective_timeout() == 2.5
    assert ValidateOptions(config=load_config(config), timeout=0).effective_timeout() is None  # 0: no limit
    report = validate([assets / "hang.obj", assets / "box.obj"], options)
    assert codes(report) == {"box.obj": [], "hang.obj": ["X002"]}
    for bad in ("-1", "'soon'", "true", "inf"):
        config.write_text(f"[validate]\ntimeout = {bad}\n")
        with pytest.raises(ConfigError, match="timeout must be a number of seconds"):
            load_config(config)
    result = CliRunner().invoke(main, ["validate", str(assets), "--timeout", "-1"])
    assert result.exit_code == 2


def test_timed_out_results_are_not_cached(assets, monkeypatch, tmp_path):
    monkeypatch.setattr(task_module, "physics_plugin", lambda: slow_check)
    options = ValidateOptions(jobs=1, timeout=1.0, cache_dir=tmp_path / "cache")
    first = validate([assets / "hang.obj"], options)
    assert codes(first) == {"hang.obj": ["X002"]}
    monkeypatch.setattr(task_module, "physics_plugin", lambda: None)
    # the timeout is not part of the cache key; a generous one keeps a loaded machine's slow first check (its
    # imports) from timing out again, which would pass this test for the wrong reason or fail it
    second = validate([assets / "hang.obj"], ValidateOptions(jobs=1, timeout=120.0, cache_dir=tmp_path / "cache"))
    assert second.cache_hits == 0 and codes(second) == {"hang.obj": []}
    third = validate([assets / "hang.obj"], options)
    assert third.cache_hits == 1 and codes(third) == {"hang.obj": []}  # the same key: a fresh result is cached


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
def test_a_fifo_named_obj_does_not_block_the_run(assets):
    os.mkfifo(assets / "pipe.obj")
    for jobs in (1, 2):
        report = validate([assets], ValidateOptions(jobs=jobs, timeout=60))
        found = codes(report)
        assert found["pipe.obj"] == ["S001"] and found["box.obj"] == []
        pipe = next(a for a in report.assets if a.path.endswith("pipe.obj"))
        assert "not a regular file" in pipe.findings[0].message


def _state(pid):
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (FileNotFoundError, ProcessLookupError):
        return "gone"


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_workers_die_when_the_parent_is_killed(assets, plugin_on_path, tmp_path):
    """kill -9 of a validate run with -j 2: its workers (stuck in a hanging check) go too."""
    shutil.copy(CLEAN / "box.obj", assets / "hang2.obj")
    pids = tmp_path / "pids"
    pids.mkdir()
    script = textwrap.dedent(
        f"""
        import sys
        sys.path.insert(0, {str(plugin_on_path)!r})
        from pathlib import Path
        from meshtool.validate import ValidateOptions, validate
        validate([Path({str(assets / "hang.obj")!r}), Path({str(assets / "hang2.obj")!r})],
                 ValidateOptions(jobs=2, timeout=0))
        """
    )
    env = dict(os.environ, SLOW_PLUGIN_PIDS=str(pids))
    parent = subprocess.Popen([sys.executable, "-c", script], env=env)
    try:
        for _ in range(600):  # both workers inside the hanging check (the run is not timed, only bounded)
            if len(list(pids.iterdir())) == 2 or parent.poll() is not None:
                break
            time.sleep(0.2)
        workers = [int(p.name.removeprefix("pid-")) for p in pids.iterdir()]
        assert len(workers) == 2, parent.poll()
        assert all(_state(pid) not in ("gone", "Z") for pid in workers)
    finally:
        parent.send_signal(signal.SIGKILL)
        parent.wait()
    for _ in range(300):
        if all(_state(pid) in ("gone", "Z") for pid in workers):
            break
        time.sleep(0.1)
    assert [_state(pid) for pid in workers] in (["gone", "gone"], ["gone", "Z"], ["Z", "gone"], ["Z", "Z"])
