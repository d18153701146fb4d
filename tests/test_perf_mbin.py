"""``.mbin`` loads (issue 28): the Python-level checks run once per content, counted with cProfile, not timed.

A second load of the same bytes skips the JSON number hooks and the table, metadata, submesh and hull
checks (its checksums and the array reductions still run); a file that differs anywhere those checks
read is checked in full: the attacks below share the first file's metadata but not its arrays.
"""

from __future__ import annotations

import cProfile
import pstats
import struct
from pathlib import Path

import pytest

from meshtool.errors import PackFormatError
from meshtool.packfile import load, parse
from meshtool.packfile import read as reader

GOLDEN = Path(__file__).resolve().parent.parent / "fixtures" / "golden"
ENTRY = struct.Struct("<4sBBH2QQQII16s")


def _calls(run: object) -> dict[str, int]:
    """Calls per function name (``file:function``) made by ``run()``."""
    profile = cProfile.Profile()
    profile.runcall(run)  # type: ignore[arg-type]
    stats = pstats.Stats(profile).stats  # type: ignore[attr-defined]
    return {f"{Path(file).name}:{func}": calls[1] for (file, _line, func), calls in stats.items()}


def _count(calls: dict[str, int], *names: str) -> int:
    return sum(n for key, n in calls.items() if any(key.endswith(name) for name in names))


CHECKS = ("verify.py:check_meta", "verify.py:check_materials", "verify.py:check_submeshes", "verify.py:check_hulls")
HOOKS = ("verify.py:finite_float", "read.py:_entry", "read.py:_check_layout")


@pytest.mark.parametrize("name", ["features.mbin", "crate_quantized.mbin", "head.mbin"])
def test_a_second_load_of_the_same_bytes_skips_the_python_checks(name: str) -> None:
    reader.forget_checks()
    path = GOLDEN / name
    first = _calls(lambda: load(path).close())
    assert _count(first, *CHECKS) == 4 and _count(first, *HOOKS) > 10
    second = _calls(lambda: load(path).close())
    assert _count(second, *CHECKS) == 0 and _count(second, *HOOKS) == 0
    with load(path) as again, load(path) as other:  # the same values, not shared objects
        reader.forget_checks()
        with load(path) as fresh:
            assert again.meta == fresh.meta and again.materials == fresh.materials
        assert again.meta is not other.meta
        again.meta["name"] = "changed"
        assert other.meta.get("name") != "changed"


def _with_index(data: bytes, value: int) -> bytes:
    """``data`` with its first index set to ``value`` and the checksums recomputed (spec section 3)."""
    import zlib

    import xxhash

    minor = struct.unpack_from("<H", data, 10)[0]

    def checksum(blob: bytes) -> int:
        return zlib.crc32(blob) if minor == 0 else xxhash.xxh3_64_intdigest(blob) & 0xFFFFFFFF

    blob = bytearray(data)
    count = struct.unpack_from("<I", blob, 16)[0]
    for k in range(count):
        at = 64 + 64 * k
        fields = list(ENTRY.unpack_from(blob, at))
        if fields[0] == b"IDX ":
            offset, length = fields[6], fields[7]
            width = length // (fields[4] * fields[5])
            blob[offset : offset + width] = min(value, 256**width - 1).to_bytes(width, "little")
            fields[8] = checksum(bytes(blob[offset : offset + length]))
            ENTRY.pack_into(blob, at, *fields)
    table = bytes(blob[64 : 64 + 64 * count])
    struct.pack_into("<I", blob, 32, checksum(bytes(blob[:32]) + table))
    return bytes(blob)


def test_a_file_that_differs_in_its_arrays_is_still_checked_in_full() -> None:
    data = (GOLDEN / "features.mbin").read_bytes()
    parse(data)  # remembered
    with pytest.raises(PackFormatError, match="IDX"):
        parse(_with_index(data, 2**31))  # same metadata and hulls, an index out of range
    hostile = bytearray(data)
    hostile[ENTRY.unpack_from(data, 64)[6]] ^= 0xFF  # a byte of the first section: its checksum fails
    with pytest.raises(PackFormatError, match="checksum"):
        parse(bytes(hostile))


def test_the_caches_stay_bounded() -> None:
    reader.forget_checks()
    for k in range(reader.CACHE_ENTRIES + 20):
        reader._remember(reader._CONTENT_CHECKED, ("key", k), True)
    assert len(reader._CONTENT_CHECKED) == reader.CACHE_ENTRIES
    assert ("key", 0) not in reader._CONTENT_CHECKED
