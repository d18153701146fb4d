"""Every input the fuzz harness crashed on (``fixtures/fuzz/<target>/``) now gives the documented error or works.

Layout: ``fixtures/fuzz/obj/<case>/`` and ``fixtures/fuzz/mtl/<case>/`` are folders (the OBJ and the files
beside it); ``mbin/``, ``scene/`` and ``simlog/`` hold one file per case. The inputs are fed through the same
target functions as ``make fuzz`` (``tests/fuzz/targets.py``), with the same per-input deadline.
"""

import signal
import sys
from pathlib import Path

import pytest
from conftest import FIXTURES

sys.path.insert(0, str(Path(__file__).resolve().parent / "fuzz"))
from targets import targets

CASES = FIXTURES / "fuzz"
DEADLINE_S = 60  # a generous bound against hangs, not a timing


def inputs(target):
    folder = CASES / target
    if not folder.is_dir():
        return []
    out = []
    for case in sorted(folder.iterdir()):
        if case.name.startswith("."):
            continue
        if target in ("obj", "mtl"):
            objs = sorted(case.glob("*.obj"))
            files = {p.relative_to(case).as_posix(): p.read_bytes() for p in [*objs, *sorted(case.rglob("*"))]
                     if p.is_file()}  # fmt: skip
        elif target == "scene":
            files = {f"scenes/{case.name}": case.read_bytes()}
        elif target == "simlog":
            files = {"run.simlog": case.read_bytes()}
        else:
            files = {"asset.mbin": case.read_bytes()}
        out.append(pytest.param(target, files, id=f"{target}/{case.name}"))
    return out


ALL = [case for name in ("obj", "mtl", "mbin", "scene", "simlog") for case in inputs(name)]


def test_there_are_regression_cases():
    assert ALL, "fixtures/fuzz/ holds the inputs fuzzing crashed on"


@pytest.mark.parametrize(("target", "files"), ALL)
def test_crash_input_is_refused_cleanly_or_read(target, files, tmp_path):
    fuzz = targets()[target]
    allowed = fuzz.allowed()

    def on_alarm(_signum, _frame):
        raise TimeoutError(f"still running after {DEADLINE_S} s")

    previous = signal.signal(signal.SIGALRM, on_alarm)
    signal.alarm(DEADLINE_S)
    folder = tmp_path / "in"
    folder.mkdir()
    try:
        fuzz.run(files, folder)
    except allowed as exc:
        assert str(exc).strip() and "\n" not in str(exc).strip()  # one line
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
