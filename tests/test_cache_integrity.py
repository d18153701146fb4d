"""Caches that cannot lie (issue 27), and ``simrun play --record`` on a full disk.

Every cache entry (hulls, validate results, compiled models) is a :mod:`meshtool.files.cachefile` envelope. For
each cache, an entry that is truncated, has a flipped byte, wrong magic or version, is empty, or was copied
from another key is a miss: the result equals a run with an empty cache (the ground truth), the entry is
written again, the problem is described with the entry's path, and the command line exits as the fresh run
did, without a traceback. A recording that fills the disk is one ``error:`` line, exit 1, and no file.
"""

from __future__ import annotations

import json
import os
import resource
import shutil
import signal
import struct
import subprocess
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import FIXTURES

import meshtool.hulls.decompose
import meshtool.validate.runner
from meshtool.files import cachefile
from meshtool.hulls.compute import HullOptions, HullSet, compute_hulls
from meshtool.hulls.decompose import HULLS_KIND, PIECES_KIND, cache_key, decompose, read_hulls
from meshtool.repair.normalise import NormaliseOptions, prepare
from meshtool.validate import ValidateOptions, render, validate
from meshtool.validate.cache import ResultCache
from simrun import Box, MeshEntity, Pose, World
from simrun.world.model_cache import KIND as MODEL_KIND
from simrun.world.model_cache import ModelCache, model_bytes

SCENES = FIXTURES / "scenes"
BOX_DIR = FIXTURES / "validate" / "clean"


# -- damage ---------------------------------------------------------------------------------------------------


def _flip(data: bytes) -> bytes:
    out = bytearray(data)
    out[cachefile.HEADER_BYTES + (len(data) - cachefile.HEADER_BYTES) // 2] ^= 0x10  # inside the payload
    return bytes(out)


#: name -> what it does to an entry's bytes (the donor is another key's entry, for the forgery)
DAMAGE: dict[str, Callable[[bytes, bytes], bytes]] = {
    "truncated": lambda data, donor: data[: len(data) * 2 // 3],
    "header-only": lambda data, donor: data[: cachefile.HEADER_BYTES - 5],
    "flipped-byte": lambda data, donor: _flip(data),
    "wrong-magic": lambda data, donor: b"\x89NOTCACH" + data[8:],
    "wrong-version": lambda data, donor: data[:8] + struct.pack("<I", 99) + data[12:],
    "zero-length": lambda data, donor: b"",
    "copied-from-another-key": lambda data, donor: donor,
    "legacy-raw-payload": lambda data, donor: data[cachefile.HEADER_BYTES :],  # what the old caches wrote
}
CASES = sorted(DAMAGE)


def damage(path: Path, case: str, donor: Path) -> None:
    path.write_bytes(DAMAGE[case](path.read_bytes(), donor.read_bytes()))


def only(folder: Path, pattern: str) -> Path:
    (found,) = sorted(folder.rglob(pattern))
    return found


# -- running a command line in a child ------------------------------------------------------------------------

_ENTRY = {
    "meshtool": "meshtool.cli.main:main",
    "obj2bin": "meshtool.cli.main:obj2bin",
    "simrun": "simrun.cli.main:main",
}


def run(
    argv: Sequence[object], cwd: Path, env: dict[str, str] | None = None, file_size: int | None = None
) -> subprocess.CompletedProcess[str]:
    """Run a command line in a child; ``file_size`` caps the size of any file it writes (RLIMIT_FSIZE)."""
    module, _, func = _ENTRY[str(argv[0])].partition(":")
    code = f"import sys; sys.argv[0] = {str(argv[0])!r}; from {module} import {func}; sys.exit({func}())"

    def limit() -> None:  # pragma: no cover - runs in the child
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # writes past the limit fail with EFBIG instead
        if file_size is not None:
            resource.setrlimit(resource.RLIMIT_FSIZE, (file_size, file_size))

    return subprocess.run(
        [sys.executable, "-c", code, *map(str, argv[1:])],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=300,
        preexec_fn=limit,
        env={**os.environ, **(env or {})},
        stdin=subprocess.DEVNULL,
        check=False,
    )


def no_traceback(done: subprocess.CompletedProcess[str]) -> None:
    assert done.returncode != 3, done.stderr
    assert "Traceback" not in done.stderr and "internal error" not in done.stderr, done.stderr


# -- the envelope ---------------------------------------------------------------------------------------------


def test_envelope_round_trip_and_refusals(tmp_path: Path) -> None:
    path = tmp_path / "e"
    assert cachefile.read_entry(path, "k", "key") == cachefile.Entry(None, None)  # absent: a plain miss
    assert cachefile.write_entry(path, "k", "key", b"payload")
    assert cachefile.read_entry(path, "k", "key").payload == b"payload"
    assert "another key" in str(cachefile.read_entry(path, "k", "other").problem)
    assert "another key" in str(cachefile.read_entry(path, "other-kind", "key").problem)
    data = path.read_bytes()
    assert data.startswith(cachefile.MAGIC) and len(data) == cachefile.HEADER_BYTES + len(b"payload")
    assert "padded" in str(cachefile.unseal("k", "key", data + b"x").problem)
    assert not [p for p in tmp_path.iterdir() if p.name != "e"]  # no temporary file left
    (tmp_path / "fifo").mkdir()
    assert "cannot be read" in str(cachefile.read_entry(tmp_path / "fifo", "k", "key").problem)


# -- hull cache: in process, with a stand-in decomposition ----------------------------------------------------


def _halves(
    points: np.ndarray, faces: np.ndarray, options: HullOptions, timeout_s: float | None = None, problems: object = None
) -> tuple[list[np.ndarray], bool, None]:  # the two halves along x
    middle = float(np.median(points[:, 0]))
    return [points[points[:, 0] <= middle + 1e-9], points[points[:, 0] >= middle - 1e-9]], False, None


def _hulls(result: HullSet) -> tuple[list[tuple[bytes, bytes, int]], list[tuple[str, str]]]:
    return [(h.vertices.tobytes(), h.faces.tobytes(), h.part) for h in result.hulls], [
        (f.code, f.message) for f in result.findings if f.code not in ("hulls-made", "cache-entry-refused")
    ]


@pytest.mark.parametrize("case", CASES)
def test_hull_entry(case: str, monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setattr(meshtool.hulls.decompose, "decompose", _halves)
    bowl = prepare(FIXTURES / "bowl" / "bowl.obj", NormaliseOptions()).mesh
    box = prepare(BOX_DIR / "box.obj", NormaliseOptions()).mesh
    truth = _hulls(compute_hulls(bowl, HullOptions(mode="decompose", cache_dir=None), "bowl.obj"))
    options = HullOptions(mode="decompose", cache_dir=tmp_path / "bowl")
    compute_hulls(bowl, options, "bowl.obj")
    compute_hulls(box, HullOptions(mode="decompose", cache_dir=tmp_path / "box"), "box.obj")
    entry = only(tmp_path / "bowl", "*.hulls.npz")
    damage(entry, case, only(tmp_path / "box", "*.hulls.npz"))
    key = entry.name.removesuffix(".hulls.npz")
    problems: list[str] = []
    assert read_hulls(options.cache_dir, key, problems) is None
    assert len(problems) == 1 and str(entry) in problems[0]
    again = compute_hulls(bowl, options, "bowl.obj")
    assert again.cache_hits == 0 and _hulls(again) == truth
    notes = [f for f in again.findings if f.code == "cache-entry-refused"]  # said once, as a note
    assert [(n.severity.value, n.message) for n in notes] == [("info", problems[0])]
    healed = compute_hulls(bowl, options, "bowl.obj")  # the entry was written again
    assert healed.cache_hits == 1 and _hulls(healed) == truth


def test_hull_entry_of_the_other_kind_is_refused(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """The pieces of a key never stand in for its finished hulls (same key, other kind)."""
    key = "ab" * 32
    pieces = tmp_path / key[:2] / f"{key}.npz"
    meshtool.hulls.decompose._write(tmp_path, key, [np.eye(4, 3), np.eye(4, 3) + 1])
    shutil.copy(pieces, tmp_path / key[:2] / f"{key}.hulls.npz")
    problems: list[str] = []
    assert read_hulls(tmp_path, key, problems) is None and "another key" in problems[0]
    # a sound envelope whose payload is not a hull set (an attacker with the key): still a miss, no exception
    cachefile.write_entry(tmp_path / key[:2] / f"{key}.hulls.npz", HULLS_KIND, key, b"PK\x03\x04 not a zip")
    assert read_hulls(tmp_path, key, problems) is None and "not a hull set" in problems[-1]
    cachefile.write_entry(pieces, PIECES_KIND, key, b"not an npz")
    assert meshtool.hulls.decompose._read(tmp_path, key, problems) is None and "not a decomposition" in problems[-1]


def _fake_worker(args: list[str], timeout_s: float) -> tuple[int, bytes]:
    """CoACD's stand-in: the worker's output file holds the two halves of the input along x."""
    with np.load(args[2]) as job:
        points = job["points"]
    middle = float(np.median(points[:, 0]))
    np.savez(args[3], hull_0=points[points[:, 0] <= middle], hull_1=points[points[:, 0] >= middle])
    return 0, b""


@pytest.mark.parametrize("case", ["truncated", "flipped-byte", "copied-from-another-key", "wrong-magic"])
def test_decomposition_entry(case: str, monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setattr(meshtool.hulls.decompose, "_run_worker", _fake_worker)
    bowl = prepare(FIXTURES / "bowl" / "bowl.obj", NormaliseOptions()).mesh
    box = prepare(BOX_DIR / "box.obj", NormaliseOptions()).mesh
    options = HullOptions(mode="decompose", cache_dir=tmp_path)
    points, faces = np.asarray(bowl.positions, np.float64), np.asarray(bowl.faces, np.int64)
    truth, hit, problem = decompose(points, faces, HullOptions(mode="decompose"))
    assert not hit and problem is None
    decompose(points, faces, options)
    donor_points, donor_faces = np.asarray(box.positions, np.float64), np.asarray(box.faces, np.int64)
    decompose(donor_points, donor_faces, options)
    entry = tmp_path / (key := cache_key(points, faces, options))[:2] / f"{key}.npz"
    donor = (tmp_path / (other := cache_key(donor_points, donor_faces, options))[:2]) / f"{other}.npz"
    damage(entry, case, donor)
    problems: list[str] = []
    pieces, hit, problem = decompose(points, faces, options, problems=problems)
    assert not hit and problem is None and str(entry) in problems[0]
    assert [p.tobytes() for p in pieces] == [p.tobytes() for p in truth]
    pieces, hit, _ = decompose(points, faces, options)
    assert hit and [p.tobytes() for p in pieces] == [p.tobytes() for p in truth]


# -- hull cache: the command line (real CoACD once per mesh) --------------------------------------------------


@pytest.fixture(scope="module")
def hull_runs(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, bytes]:
    """A folder with bowl.obj and box.obj, a cache of each (``bowl-cache``, ``box-cache``), the bowl's pack."""
    folder = tmp_path_factory.mktemp("hulls")
    shutil.copy(FIXTURES / "bowl" / "bowl.obj", folder)
    for name in ("box.obj", "box.mtl", "box.png"):
        shutil.copy(BOX_DIR / name, folder)
    for name in ("bowl", "box"):
        done = run(_obj2bin(name, folder / f"{name}-cache", f"{name}.mbin"), folder)
        assert done.returncode == 0, done.stderr
    return folder, (folder / "bowl.mbin").read_bytes()  # made with an empty cache: the ground truth


def _obj2bin(name: str, cache: Path, out: str) -> list[object]:
    options = ["--hulls", "decompose", "--threshold", "0.1", "--no-check", "--cache-dir", cache]
    return ["obj2bin", f"{name}.obj", *options, "-o", out]


@pytest.mark.parametrize("case", ["truncated", "flipped-byte", "copied-from-another-key", "zero-length"])
def test_obj2bin_with_a_bad_hull_entry(case: str, hull_runs: tuple[Path, bytes], tmp_path: Path) -> None:
    folder, truth = hull_runs
    cache = tmp_path / "cache"
    shutil.copytree(folder / "bowl-cache", cache)
    entry = only(cache, "*.hulls.npz")
    damage(entry, case, only(folder / "box-cache", "*.hulls.npz"))
    done = run(_obj2bin("bowl", cache, str(tmp_path / "out.mbin")), folder)
    no_traceback(done)
    assert done.returncode == 0 and (tmp_path / "out.mbin").read_bytes() == truth
    key = entry.name.removesuffix(".hulls.npz")
    assert cachefile.read_entry(entry, HULLS_KIND, key).payload is not None  # written again


# -- validate cache ---------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def assets(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """``clean/`` (the clean box), ``broken/`` (a non-finite vertex: an error), a cache of each, the fresh report."""
    folder = tmp_path_factory.mktemp("assets")
    shutil.copytree(BOX_DIR, folder / "clean", ignore=shutil.ignore_patterns("*.mbin"))
    shutil.copytree(FIXTURES / "validate" / "G001_non_finite", folder / "broken")
    truth = render(validate([folder / "clean", folder / "broken"], ValidateOptions()), "json")
    assert json.loads(truth)["summary"]["by_status"]["error"] == 1
    for name in ("clean", "broken"):
        validate([folder / name], ValidateOptions(cache_dir=folder / f"{name}-cache"))
    return folder, truth


@pytest.mark.parametrize("case", CASES)
def test_validate_entry(case: str, assets: tuple[Path, str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    folder, truth = assets
    cache = tmp_path / "cache"
    shutil.copytree(folder / "clean-cache", cache)
    shutil.copytree(folder / "broken-cache", cache, dirs_exist_ok=True)
    entry = cache / only(folder / "broken-cache", "*.json").relative_to(folder / "broken-cache")
    damage(entry, case, only(folder / "clean-cache", "*.json"))  # forged: the clean box's PASSED result
    made: list[ResultCache] = []

    class Spy(ResultCache):
        def __init__(self, *args: Any, **kwargs: Any) -> None:
            super().__init__(*args, **kwargs)
            made.append(self)

    monkeypatch.setattr(meshtool.validate.runner, "ResultCache", Spy)
    paths = [folder / "clean", folder / "broken"]
    report = validate(paths, ValidateOptions(cache_dir=cache))
    assert report.checked == 1 and report.cache_hits == 1
    assert render(report, "json") == truth
    assert len(made[-1].problems) == 1 and str(entry) in made[-1].problems[0]
    again = validate(paths, ValidateOptions(cache_dir=cache))  # written again
    assert again.cache_hits == 2 and render(again, "json") == truth and made[-1].problems == []


@pytest.fixture(scope="module")
def fresh_validate(assets: tuple[Path, str]) -> subprocess.CompletedProcess[str]:
    done = run(["meshtool", "validate", "clean", "broken", "--format", "json", "--no-cache"], assets[0])
    assert done.returncode == 1, done.stderr  # the broken asset fails
    return done


@pytest.mark.parametrize("case", ["flipped-byte", "copied-from-another-key", "zero-length"])
def test_meshtool_validate_with_a_bad_entry(
    case: str, assets: tuple[Path, str], fresh_validate: subprocess.CompletedProcess[str], tmp_path: Path
) -> None:
    folder, _ = assets
    cache = tmp_path / "cache"
    shutil.copytree(folder / "clean-cache", cache)
    shutil.copytree(folder / "broken-cache", cache, dirs_exist_ok=True)
    entry = cache / only(folder / "broken-cache", "*.json").relative_to(folder / "broken-cache")
    damage(entry, case, only(folder / "clean-cache", "*.json"))
    done = run(["meshtool", "validate", "clean", "broken", "--format", "json", "--cache-dir", cache], folder)
    no_traceback(done)
    assert done.returncode == fresh_validate.returncode and done.stdout == fresh_validate.stdout
    notes = [line for line in done.stderr.splitlines() if line.startswith("note: cache entry ")]
    assert len(notes) == 1 and str(entry) in notes[0] and notes[0].endswith("; recomputed")


# -- compiled-model cache ----------------------------------------------------------------------------------------


@pytest.fixture
def folder(tmp_path: Path) -> Path:
    for k in range(2):
        shutil.copy(FIXTURES / "golden" / "head-1.1.mbin", tmp_path / f"a{k}.mbin")
    return tmp_path


def _world(folder: Path, cache: ModelCache | None, heavy: bool = False) -> World:
    world = World(base_dir=folder)
    world.model_cache = cache
    if heavy:  # another scene: one 500 kg box
        world.insert(Box(name="box", dimensions=(1.0, 1.0, 1.0), mass=500.0, free=True, pose=Pose((0.0, 0.0, 0.5))))
        return world
    for k in range(2):
        world.insert(MeshEntity(name=f"m{k}", asset=f"a{k}.mbin", pose=Pose((0.3 * k, 0.0, 0.2))))
    world.insert(Box(name="box", dimensions=(0.1, 0.1, 0.1), pose=Pose((0.0, 1.0, 0.1))))
    return world


@pytest.mark.parametrize("case", CASES)
def test_model_entry(case: str, folder: Path, tmp_path: Path) -> None:
    truth = model_bytes(_world(folder, None).model)
    cache = ModelCache(tmp_path / "cache")
    _world(folder, cache).compile()
    _world(folder, cache, heavy=True).compile()
    key, other = cache.key(_world(folder, None)), cache.key(_world(folder, None, heavy=True))
    assert key is not None and other is not None
    entry, donor = cache.folder / f"{key}.mjb", cache.folder / f"{other}.mjb"
    damage(entry, case, donor)
    cache = ModelCache(tmp_path / "cache")
    world = _world(folder, cache)
    assert model_bytes(world.model) == truth and (cache.hits, cache.misses) == (0, 1)
    assert len(cache.problems) == 1 and str(entry) in cache.problems[0]
    assert model_bytes(_world(folder, cache).model) == truth and cache.hits == 1  # written again


def test_model_entry_with_a_foreign_payload_is_a_miss(folder: Path, tmp_path: Path) -> None:
    """A sound envelope for the right key whose payload is not a model (an attacker who knows the key)."""
    truth = model_bytes(_world(folder, None).model)
    cache = ModelCache(tmp_path / "cache")
    key = cache.key(_world(folder, None))
    assert key is not None
    for payload in (b"", b"\xff\xff\xff\xff", struct.pack("<I", 2) + b"{}", struct.pack("<I", 4) + b"null"):
        cachefile.write_entry(cache.folder / f"{key}.mjb", MODEL_KIND, key, payload)
        assert model_bytes(_world(folder, cache).model) == truth
    assert cache.hits == 0 and len(cache.problems) == 4


def test_model_key_is_content_not_path_or_time(folder: Path, tmp_path: Path) -> None:
    cache = ModelCache(tmp_path / "cache")
    _world(folder, cache).compile()
    os.utime(folder / "a0.mbin", (1, 1))  # another time, the same bytes: a hit
    assert model_bytes(_world(folder, cache).model) == model_bytes(_world(folder, None).model) and cache.hits == 1
    # a link pointed at other bytes under the same name: a miss, and the new mesh compiles
    shutil.copy(FIXTURES / "golden" / "features-1.1.mbin", folder / "features.mbin")
    (folder / "a1.mbin").unlink()
    (folder / "a1.mbin").symlink_to("features.mbin")
    changed = _world(folder, cache)
    assert model_bytes(changed.model) == model_bytes(_world(folder, None).model) and cache.hits == 1
    assert cache.problems == []  # a changed input is an ordinary miss, not a damaged entry


def test_a_hit_without_memfd_is_the_same_model(folder: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Where the system has no anonymous in-memory files, a hit loads through MuJoCo's virtual file system."""
    cache = ModelCache(tmp_path / "cache")
    _world(folder, cache).compile()
    monkeypatch.delattr(os, "memfd_create", raising=False)
    assert model_bytes(_world(folder, cache).model) == model_bytes(_world(folder, None).model) and cache.hits == 1


def test_a_rebuilt_world_is_not_stored(folder: Path, tmp_path: Path) -> None:
    """A rebuild reuses the meshes read into memory by the first build: those bytes are not what the key sees."""
    cache = ModelCache(tmp_path / "cache")
    world = _world(folder, cache)
    world.compile()
    world.insert(Box(name="extra", dimensions=(0.1, 0.1, 0.1), pose=Pose((2.0, 0.0, 0.1))))
    world.compile()
    assert (cache.hits, cache.misses) == (0, 1) and len(list(cache.folder.glob("*.mjb"))) == 1
    fresh = _world(folder, None)
    fresh.insert(Box(name="extra", dimensions=(0.1, 0.1, 0.1), pose=Pose((2.0, 0.0, 0.1))))
    assert model_bytes(world.model) == model_bytes(fresh.model)


CHECK = ["simrun", "check", "head_on_table.toml", "--json", "--duration", "0.2"]


@pytest.fixture(scope="module")
def scenes(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """A folder with the head-on-table scene, the basic scene's model cache (``donor``: a 100 kg box), and
    what ``simrun check`` prints for the head scene without a cache."""
    folder = tmp_path_factory.mktemp("scenes")
    for name in ("head_on_table.toml", "head.mbin", "basic.toml", "globe.png"):
        shutil.copy(SCENES / name, folder)
    fresh = run(CHECK, folder)
    assert fresh.returncode == 0, fresh.stderr
    run(["simrun", "check", "basic.toml", "--duration", "0.2"], folder, {"SIMRUN_MODEL_CACHE": str(folder / "donor")})
    return folder, fresh.stdout


@pytest.mark.parametrize("case", ["truncated", "copied-from-another-key", "wrong-magic"])
def test_simrun_check_with_a_bad_model_entry(case: str, scenes: tuple[Path, str], tmp_path: Path) -> None:
    folder, fresh = scenes
    env = {"SIMRUN_MODEL_CACHE": str(tmp_path / "cache")}
    run(CHECK, folder, env)  # the entry, made here: its key covers simrun's source, which may change meanwhile
    entry = only(tmp_path / "cache", "*.mjb")
    damage(entry, case, only(folder / "donor", "*.mjb"))
    done = run(CHECK, folder, env)
    no_traceback(done)
    assert done.returncode == 0 and done.stdout == fresh
    assert cachefile.read_entry(entry, MODEL_KIND, entry.stem, 1 << 30).payload is not None  # written again
    notes = [line for line in done.stderr.splitlines() if line.startswith("note: cache entry ")]
    assert len(notes) == 1 and str(entry) in notes[0] and notes[0].endswith("; recomputed"), done.stderr


# -- a recording on a full disk ---------------------------------------------------------------------------------


def test_record_on_a_full_disk_is_one_error_and_no_file(tmp_path: Path) -> None:
    for name in ("basic.toml", "globe.png"):
        shutil.copy(SCENES / name, tmp_path)
    old = b"\x89SIMLOG\n an earlier recording"
    (tmp_path / "old.simlog").write_bytes(old)
    before = sorted(p.name for p in tmp_path.iterdir())
    argv = ["simrun", "play", "basic.toml", "--record"]
    for target in ("out.simlog", "old.simlog"):
        done = run([*argv, target, "--duration", "5"], tmp_path, file_size=16 * 1024)
        no_traceback(done)
        lines = done.stderr.strip().splitlines()
        assert done.returncode == 1 and len(lines) == 1, done.stderr
        assert lines[0].startswith(f"error: {target}: cannot write: File too large"), lines
        assert sorted(p.name for p in tmp_path.iterdir()) == before  # no .simlog, no temporary file
        assert (tmp_path / "old.simlog").read_bytes() == old  # the earlier recording is untouched
    done = run([*argv, "out.simlog", "--duration", "0.1"], tmp_path)  # room enough: written whole
    assert done.returncode == 0, done.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([*before, "out.simlog"])


# -- obj2bin's remembered MuJoCo checks (a fourth cache) --------------------------------------------------


def test_an_empty_damaged_or_copied_check_marker_is_a_miss(tmp_path: Path) -> None:
    """Any file with a marker's name used to count as a passing check; now it must answer its key."""
    from meshtool.mjcf.loadcheck import _marker, check_pack
    from meshtool.packfile import pack
    from meshtool.repair.normalise import NormaliseOptions, prepare

    tile = Path(__file__).resolve().parent.parent / "fixtures" / "realworld" / "normal_maps" / "tile.obj"
    asset = prepare(tile, NormaliseOptions())
    data = pack(asset, False, {}, [], None)
    other = pack(asset, False, {"note": "another pack"}, [], None)
    cache = tmp_path / "checks"
    assert check_pack(data, "tile.obj", cache)[0] == "compiled"
    assert check_pack(data, "tile.obj", cache)[0] == "cached"
    found = _marker(cache, data)
    assert found is not None
    marker = found[0]
    sealed = marker.read_bytes()
    assert check_pack(other, "other.obj", cache)[0] == "compiled"
    other_found = _marker(cache, other)
    assert other_found is not None
    for damage in (b"", sealed[:-1], sealed[:-1] + bytes([sealed[-1] ^ 1]), other_found[0].read_bytes()):
        marker.write_bytes(damage)
        assert check_pack(data, "tile.obj", cache)[0] == "compiled"  # compiled again, and the marker rewritten
        assert marker.read_bytes() == sealed
