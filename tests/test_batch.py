"""The one batch layer (meshtool/work/batch.py): this process, local workers and Dask give the same results.

Ground truth: the bytes of the packs each executor wrote, the process facts of a worker that dies or hangs
(its exit, the wall clock), and the indices of the tasks handed in.
"""

import json
import os
import shutil
import time

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
