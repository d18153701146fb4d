"""meshtool validate --executor dask: files read here, workers anywhere.

The workers are started as separate ``dask worker`` processes in another working folder that holds a
decoy ``assets/`` (other files under the same relative names): a run that resolved paths on the workers
would check the decoys or fail to find the files.
"""

import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest
from click.testing import CliRunner
from conftest import FIXTURES

from meshtool.cli.main import main
from meshtool.validate import ValidateError, ValidateOptions, render, validate
from meshtool.validate.reports.text import summary_lines

distributed = pytest.importorskip("distributed")

ROOT = FIXTURES / "validate"
PICK = ["clean", "S003_texture_missing", "G005_winding_inconsistent", "K001_pack_corrupt", "K003_pack_stale"]
DASK = Path(sys.executable).parent / "dask"


def summary(report):
    return [(a.path, [f.to_dict() for f in a.findings]) for a in report.assets]


@pytest.fixture
def client_dir(tmp_path, monkeypatch):
    """The client's working folder with ``assets/`` (copies of some rule fixtures)."""
    here = tmp_path / "client"
    for name in PICK:
        shutil.copytree(ROOT / name, here / "assets" / name)
    monkeypatch.chdir(here)
    return here


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    """A scheduler in this process and two ``dask worker`` processes started in a folder with decoy assets."""
    elsewhere = tmp_path_factory.mktemp("workers")
    for name in PICK:  # same relative paths, other content: every OBJ is a broken file, every pack empty
        for path in (ROOT / name).rglob("*"):
            if path.is_file():
                decoy = elsewhere / "assets" / name / path.relative_to(ROOT / name)
                decoy.parent.mkdir(parents=True, exist_ok=True)
                decoy.write_bytes(b"decoy\n")
    with distributed.LocalCluster(n_workers=0, dashboard_address=None, host="127.0.0.1") as local:
        address = local.scheduler_address
        command = [str(DASK), "worker", address, "--nworkers", "1", "--nthreads", "1", "--no-dashboard"]
        env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
        workers = [
            subprocess.Popen(command, cwd=elsewhere, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            for _ in range(2)
        ]
        try:
            with distributed.Client(address) as client:
                client.wait_for_workers(2, timeout=120)
                addresses = sorted(client.scheduler_info()["workers"])
            yield address, addresses, elsewhere
        finally:
            for worker in workers:
                worker.terminate()
            for worker in workers:
                try:
                    worker.wait(30)
                except subprocess.TimeoutExpired:
                    worker.kill()


def test_workers_in_another_folder_check_what_the_client_sees(client_dir, cluster):
    address, workers, elsewhere = cluster
    assert Path.cwd() != elsewhere and (elsewhere / "assets").is_dir()
    local = validate([Path("assets")], ValidateOptions(jobs=1))
    remote = validate([Path("assets")], ValidateOptions(executor="dask", scheduler=address))
    assert summary(remote) == summary(local)
    assert render(remote, "json") == render(local, "json")
    assert remote.checked == len(local.assets) == 7
    # where: every asset judged by one of the two workers (the corrupt pack is refused while reading, here)
    assert set(remote.where) <= {*workers, "this process"}
    assert sum(remote.where.values()) == 7 and remote.where.get("this process") == 1
    assert set(remote.where) & set(workers)
    line = summary_lines(remote)[1]
    assert line.startswith("checked 7 (") and "1 in this process" in line


def test_everything_cached_claims_no_workers_and_contacts_no_scheduler(client_dir, cluster, tmp_path):
    address, _, _ = cluster
    cache = tmp_path / "cache"
    first = validate([Path("assets")], ValidateOptions(executor="dask", scheduler=address, cache_dir=cache))
    assert first.checked == 7
    unreachable = "tcp://127.0.0.1:9"  # nothing listens there: contacting it would fail
    second = validate([Path("assets")], ValidateOptions(executor="dask", scheduler=unreachable, cache_dir=cache))
    assert (second.checked, second.cache_hits, second.where) == (0, 7, {})
    line = summary_lines(second)[1]
    assert line.startswith("checked 0, 7 from cache") and "worker" not in line
    assert summary(second) == summary(first)


def test_unreachable_scheduler_is_one_error_line_and_exit_1(client_dir):
    options = ValidateOptions(executor="dask", scheduler="tcp://127.0.0.1:9", connect_timeout=2)
    with pytest.raises(ValidateError) as caught:
        validate([Path("assets")], options)
    assert caught.value.exit_code == 1 and not caught.value.usage
    args = ["validate", "assets", "--executor", "dask", "--scheduler", "tcp://127.0.0.1:9"]
    result = CliRunner().invoke(main, [*args, "--scheduler-timeout", "2", "--no-cache"])
    assert result.exit_code == 1
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: cannot reach the Dask scheduler at tcp://127.0.0.1:9")
    assert "dask scheduler" in lines[0] and "Traceback" not in result.output


def test_a_hanging_judgement_on_a_worker_is_x002(client_dir, cluster, monkeypatch):
    """The per-asset timeout holds on Dask too: the run stops waiting and reports X002."""
    address, _, _ = cluster
    with distributed.Client(address) as client:
        client.run(_install_slow_plugin)
    try:
        shutil.copy(ROOT / "clean" / "box.obj", client_dir / "assets" / "clean" / "hang.obj")
        options = ValidateOptions(executor="dask", scheduler=address, timeout=3)
        started = time.monotonic()
        report = validate([Path("assets/clean")], options)
        found = {Path(a.path).name: [f.code for f in a.findings] for a in report.assets}
        assert found == {"box.mbin": [], "box.obj": [], "hang.obj": ["X002"]}
        assert time.monotonic() - started < 600  # bounded, not timed: the run did not wait for the hour
    finally:
        with distributed.Client(address) as client:
            client.run(_remove_slow_plugin)


def _install_slow_plugin():
    from meshtool.validate import task
    from meshtool.validate.plugin_types import PhysicsOutcome

    real = task.physics_plugin

    def slow(mbin, name, limits, thumbnail):
        if name.startswith("hang"):
            time.sleep(3600)
        return PhysicsOutcome()

    task._real_physics_plugin = real
    task.physics_plugin = lambda: slow


def _remove_slow_plugin():
    from meshtool.validate import task

    task.physics_plugin = task._real_physics_plugin


@pytest.fixture
def odd_service():
    """Start a TCP service on 127.0.0.1 that is not Dask: ``odd_service(greeting)`` gives its address.

    ``greeting`` is sent on each connection and the connection closed; ``None`` accepts and stays silent.
    """
    import socket
    import threading

    servers = []

    def start(greeting):
        server = socket.create_server(("127.0.0.1", 0))
        held = []

        def serve():
            while True:
                try:
                    conn, _ = server.accept()
                except OSError:  # closed at the end of the test
                    return
                if greeting is None:
                    held.append(conn)  # never answers
                else:
                    conn.sendall(greeting)
                    conn.close()

        threading.Thread(target=serve, daemon=True).start()
        servers.append((server, held))
        return f"tcp://127.0.0.1:{server.getsockname()[1]}"

    yield start
    for server, held in servers:
        server.close()
        for conn in held:
            conn.close()


def test_a_service_that_is_not_dask_is_one_error_line_and_exit_1(client_dir, odd_service):
    address = odd_service(b"HTTP/1.1 400 Bad Request\r\n\r\n")
    args = ["validate", "assets", "--executor", "dask", "--scheduler", address, "--scheduler-timeout", "3"]
    result = CliRunner().invoke(main, [*args, "--no-cache"])
    assert result.exit_code == 1, result.output
    (line,) = result.output.strip().splitlines()
    assert line.startswith(f"error: cannot reach the Dask scheduler at {address}: the service there is not Dask")
    assert "HTTP/1.1 400 Bad Request" in line and "8786" in line
    assert "internal error" not in line and "Traceback" not in result.output


def test_a_silent_service_is_one_error_line_within_the_scheduler_timeout(client_dir, odd_service):
    """A listener that accepts and never answers: refused after --scheduler-timeout, not waited on for ever."""
    address = odd_service(None)
    command = [str(Path(sys.executable).parent / "meshtool"), "validate", "assets", "--executor", "dask"]
    command += ["--scheduler", address, "--scheduler-timeout", "2", "--no-cache"]
    # bounded, not timed: without the probe the run waited on the silent socket far past a minute
    result = subprocess.run(command, capture_output=True, text=True, timeout=60)
    assert result.returncode == 1, result.stderr
    (line,) = result.stderr.strip().splitlines()
    assert line.startswith(f"error: cannot reach the Dask scheduler at {address}: no Dask greeting within 2 s")
    assert "--scheduler-timeout" in line and result.stdout == ""


def test_fully_cached_run_says_the_dask_executor_was_not_contacted(client_dir, tmp_path):
    cache = tmp_path / "cache"
    first = validate([Path("assets")], ValidateOptions(jobs=1, cache_dir=cache))
    assert first.checked == 7
    unreachable = "tcp://127.0.0.1:9"  # nothing listens there: contacting it would fail
    args = ["validate", "assets", "--executor", "dask", "--scheduler", unreachable, "--cache-dir", str(cache)]
    result = CliRunner().invoke(main, args)
    last = result.output.strip().splitlines()[-1]
    assert last.startswith("checked 0, 7 from cache; dask executor not contacted: everything cached, "), last
    local = CliRunner().invoke(main, ["validate", "assets", "--cache-dir", str(cache)])
    assert "; local executor not used: everything cached, " in local.output.strip().splitlines()[-1]
