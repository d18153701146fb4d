"""The one batch layer (meshtool/work/batch.py): this process, local workers and Dask give the same results.

Ground truth: the bytes of the packs each executor wrote, the process facts of a worker that dies or hangs
(its exit, the wall clock), and the indices of the tasks handed in.
"""

import json
import os
import shutil
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

from meshtool.cli.main import obj2bin
from meshtool.work.batch import BatchError, Executor, run_batch

pytest.importorskip("distributed")


def run(cmd, *args):
    return CliRunner().invoke(cmd, [str(a) for a in args], catch_exceptions=False)


@pytest.fixture(scope="module")
def assets(tmp_path_factory):
    """Mesh files of three formats (OBJ, STL, PLY) in a tree, one of them broken."""
    from pathlib import Path

    fixtures = Path(__file__).resolve().parent.parent / "fixtures"
    src = tmp_path_factory.mktemp("batch") / "assets"
    shutil.copytree(fixtures / "multi_material", src / "crate")
    shutil.copytree(fixtures / "head", src / "heads")
    shutil.copytree(fixtures / "bad_index", src / "broken")
    shutil.copytree(fixtures / "formats" / "stl", src / "stl")
    shutil.copytree(fixtures / "formats" / "ply", src / "ply")
    return src


def _packs(out):
    return {p.relative_to(out).as_posix(): p.read_bytes() for p in sorted(out.rglob("*.mbin"))}


def test_obj2bin_dir_writes_the_same_bytes_here_on_two_workers_and_on_dask(assets, tmp_path):
    runs = {
        "-j1": ["-j", "1"],
        "-j2": ["-j", "2"],
        "dask": ["--executor", "dask", "-j", "2"],
    }
    packs, counts = {}, {}
    for name, args in runs.items():
        out = tmp_path / name
        result = run(obj2bin, assets, "-o", out, "--units", "cm", "--no-cache", "--json", *args)
        assert result.exit_code == 1, result.output  # the broken asset fails, the others are written
        report = json.loads(result.stdout)
        counts[name] = report["counts"]
        packs[name] = _packs(out)
        assert [a["source"] for a in report["assets"]] == sorted(a["source"] for a in report["assets"])
    assert counts["-j1"] == counts["-j2"] == counts["dask"]
    assert counts["-j1"]["written"] == len(packs["-j1"]) >= 4
    assert packs["-j1"] == packs["-j2"] == packs["dask"]


def test_obj2bin_relative_dir_on_a_dask_cluster_started_in_another_folder(assets, tmp_path, monkeypatch):
    """A Dask worker's working folder is not the command's: relative DIR and -o still mean the command's."""
    distributed = pytest.importorskip("distributed")
    elsewhere = tmp_path / "cluster-cwd"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)  # the workers start here
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        work = tmp_path / "work"
        shutil.copytree(assets / "stl", work / "in" / "stl")
        monkeypatch.chdir(work)
        here = run(obj2bin, "in", "-o", "out-here", "--no-cache", "--json", "-j", "1")
        remote = run(
            obj2bin,
            "in",
            "-o",
            "out-dask",
            "--no-cache",
            "--json",
            "--executor",
            "dask",
            "--scheduler",
            cluster.scheduler_address,
        )
    assert here.exit_code == 0 and remote.exit_code == 0, remote.output
    assert _packs(work / "out-dask") == _packs(work / "out-here") and _packs(work / "out-here")
    shown = json.loads(remote.stdout)["assets"]
    assert [a["source"] for a in shown] == [a["source"] for a in json.loads(here.stdout)["assets"]]
    assert all(not Path(a["source"]).is_absolute() for a in shown)
    assert not list(elsewhere.rglob("*.mbin"))  # nothing written where the workers run


def test_scheduler_needs_the_dask_executor_and_an_unreachable_one_is_one_line(assets, tmp_path):
    usage = CliRunner().invoke(obj2bin, [str(assets), "-o", str(tmp_path / "a"), "--scheduler", "tcp://127.0.0.1:9"])
    assert usage.exit_code == 2 and "--scheduler needs --executor dask" in usage.output
    args = [str(assets), "-o", str(tmp_path / "b"), "--executor", "dask", "--scheduler", "tcp://127.0.0.1:9"]
    unreachable = CliRunner().invoke(obj2bin, [*args, "--scheduler-timeout", "2"])
    assert unreachable.exit_code == 1
    errors = [line for line in unreachable.stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and "cannot reach the Dask scheduler at tcp://127.0.0.1:9" in errors[0]
    assert "Traceback" not in unreachable.output
    assert not (tmp_path / "b").exists() or not list((tmp_path / "b").rglob("*.mbin"))


class Probe:
    """Tasks: ``("ok", n)`` gives n * n, ``("die", code)`` ends the worker process, ``("hang", s)`` sleeps."""

    def prepare(self):
        pass

    def __call__(self, task):
        kind, value = task
        if kind == "die":
            os._exit(value)
        if kind == "hang":
            time.sleep(value)
        return ("done", value * value)

    def lost(self, task, why):
        return ("lost", why)


@pytest.mark.parametrize("kind", ["local", "dask"])
def test_every_task_gets_one_result_by_its_index_and_a_hung_one_is_lost_at_the_deadline(kind):
    tasks = [("ok", 3), ("hang", 30.0), ("ok", 4), ("ok", 5)]
    start = time.monotonic()
    results = {i: (r, where) for i, r, where in run_batch(tasks, Probe(), Executor(kind, jobs=2, timeout=2.0))}
    elapsed = time.monotonic() - start
    assert sorted(results) == [0, 1, 2, 3]
    assert [results[i][0] for i in (0, 2, 3)] == [("done", 9), ("done", 16), ("done", 25)]
    assert results[1][0][0] == "lost" and "timed out after 2 s" in results[1][0][1]
    assert elapsed < 25  # not the 30 s the hung task asked for
    assert all(where != "this process" for _, where in results.values())


def test_a_worker_that_dies_is_lost_for_its_task_only_and_replaced():
    tasks = [("ok", 2), ("die", 7), ("ok", 6), ("ok", 7)]
    results = {i: r for i, r, _ in run_batch(tasks, Probe(), Executor("local", jobs=2))}
    assert results[1] == ("lost", "the worker process running it died (exit code 7)")
    assert [results[i] for i in (0, 2, 3)] == [("done", 4), ("done", 36), ("done", 49)]


def test_one_local_job_without_a_deadline_runs_here_in_order():
    out = list(run_batch([("ok", 1), ("ok", 2)], Probe(), Executor()))
    assert out == [(0, ("done", 1), "this process"), (1, ("done", 4), "this process")]


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"kind": "ray"}, "executor 'ray': expected one of local, dask"),
        ({"jobs": 0}, "jobs 0: expected at least 1"),
        ({"scheduler": "tcp://x:1"}, "a scheduler address needs the dask executor"),
    ],
)
def test_an_impossible_executor_is_refused_with_its_reason(kwargs, message):
    with pytest.raises(ValueError, match=message):
        Executor(**kwargs)


def test_an_unreachable_scheduler_is_a_batch_error_with_a_hint():
    with pytest.raises(BatchError) as caught:
        list(run_batch([("ok", 1)], Probe(), Executor("dask", scheduler="tcp://127.0.0.1:9", connect_timeout=2)))
    assert "cannot reach the Dask scheduler at tcp://127.0.0.1:9" in caught.value.message and caught.value.hint


#: How many times a :class:`Payload` was pickled in this process (each time it left for another process).
PICKLED = []


class Payload:
    """A shared payload that counts, in the process that sends it, each time it is pickled."""

    def __init__(self, size):
        self.data = bytes(size)

    def __getstate__(self):
        PICKLED.append(len(self.data))
        return {"data": self.data}

    def __setstate__(self, state):
        self.data = state["data"]


class Sized:
    """A shared work: the size of the payload and the process that ran the task (its pid)."""

    def prepare(self):
        pass

    def __call__(self, task, shared):
        kind, value = task
        if kind == "die":
            os._exit(value)
        return (len(shared.data) + value, os.getpid(), id(shared))

    def lost(self, task, why):
        return ("lost", why)


@pytest.mark.parametrize(("kind", "sent"), [("local", 2), ("dask", 1)])
def test_a_shared_payload_leaves_this_process_once_per_worker_not_per_task(kind, sent):
    """Eight tasks on two workers: the payload is pickled once per local worker (at its start) and once for
    Dask (scattered to every worker); each worker process holds one copy for all its tasks."""
    PICKLED.clear()
    tasks = [("ok", k) for k in range(8)]
    results = {i: r for i, r, _ in run_batch(tasks, Sized(), Executor(kind, jobs=2), shared=Payload(1 << 20))}
    assert [results[i][0] for i in range(8)] == [(1 << 20) + k for k in range(8)]
    assert len(PICKLED) == sent and set(PICKLED) == {1 << 20}
    copies = {}
    for _, pid, ident in results.values():
        copies.setdefault(pid, set()).add(ident)
    assert all(len(idents) == 1 for idents in copies.values()), copies
    assert os.getpid() not in copies


def test_a_replacement_worker_gets_the_shared_payload_too():
    PICKLED.clear()
    tasks = [("ok", 1), ("die", 9), ("ok", 2), ("ok", 3)]
    results = {i: r for i, r, _ in run_batch(tasks, Sized(), Executor("local", jobs=1, timeout=60), shared=Payload(8))}
    assert results[1] == ("lost", "the worker process running it died (exit code 9)")
    assert [results[i][0] for i in (0, 2, 3)] == [9, 10, 11]
    assert PICKLED == [8, 8]  # the first worker, then its replacement


def test_in_this_process_the_shared_payload_is_the_object_itself():
    payload = Payload(4)
    PICKLED.clear()
    out = list(run_batch([("ok", 0), ("ok", 1)], Sized(), Executor(), shared=payload))
    assert [(i, r[0], r[1], r[2], w) for i, r, w in out] == [
        (0, 4, os.getpid(), id(payload), "this process"),
        (1, 5, os.getpid(), id(payload), "this process"),
    ]
    assert PICKLED == []


def test_a_batch_takes_a_read_here_step_or_a_payload_not_both():
    from meshtool.work.batch import ReadHere

    here = ReadHere(lambda task: (True, task), Probe())
    with pytest.raises(ValueError, match="not both"):
        list(run_batch([("ok", 1)], Sized(), Executor("dask"), here, shared=Payload(1)))


@pytest.mark.parametrize("jobs", [1, 2])
def test_progress_ticks_once_per_task_with_its_label(jobs):
    ticks = []
    tasks = [("ok", k) for k in range(5)]
    order = [
        i
        for i, _, _ in run_batch(
            tasks, Probe(), Executor(jobs=jobs), progress=ticks.append, label=lambda t: f"task {t[1]}"
        )
    ]
    assert [t.done for t in ticks] == [1, 2, 3, 4, 5] and {t.total for t in ticks} == {5}
    assert [t.last for t in ticks] == [f"task {i}" for i in order]  # the task that had just finished
    assert ticks[-1].eta_s == 0 and ticks[-1].rate is not None and ticks[-1].rate > 0
    assert ticks[-1].line().startswith("[5/5] 100%  ") and ticks[-1].line().endswith(f"last: task {order[-1]}")


def test_the_batch_line_says_done_total_percent_rate_eta_and_the_last_name():
    from meshtool.work.progress import Meter, Tick

    line = Tick(37, 120, "crate.obj", 15.4, 2.4, 34.6).line()
    assert line == "[ 37/120] 30%  2.4 items/s  eta 0:35  last: crate.obj"
    assert Tick(1, 3, "a", 0.0, None, None).line() == "[1/3] 33%  - items/s  eta -  last: a"
    assert Tick(9, 9, "z", 4000.0, 0.002, 0.0).line() == "[9/9] 100%  0.0 items/s  eta 0:00  last: z"
    assert Tick(1, 900, "x", 1.0, 0.2, 4495.0).line().endswith("eta 1:14:55  last: x")
    now = [100.0]
    meter = Meter(10, clock=lambda: now[0])
    for _ in range(4):  # from a cache: at once, not counted in the rate
        meter.advance("cached", computed=False)
    now[0] += 3.0
    for _ in range(3):  # three checked in 3 s: 1 item/s, three left
        tick = meter.advance("checked")
    assert (tick.done, tick.rate, tick.eta_s, tick.elapsed_s) == (7, 1.0, 3.0, 3.0)
