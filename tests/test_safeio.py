"""simrun.safeio.read_regular: a bounded read of a regular file, without a buffer of the limit up front."""

from __future__ import annotations

import tracemalloc
from pathlib import Path

import pytest

from simrun.safeio import FileReadError, read_regular


def test_a_small_file_is_read_without_a_limit_sized_buffer(tmp_path: Path) -> None:
    path = tmp_path / "scene.toml"
    path.write_bytes(b"[world]\ntimestep = 0.002\n")
    tracemalloc.start()
    try:
        data = read_regular(path, "scene", limit=256 << 20)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert data == b"[world]\ntimestep = 0.002\n"
    assert peak < 1 << 20  # before: a 256 MiB buffer for a 26-byte scene


def test_a_file_over_the_limit_is_refused_naming_sizes(tmp_path: Path) -> None:
    path = tmp_path / "big.toml"
    path.write_bytes(b"#" * 1001)
    with pytest.raises(FileReadError, match=r"big.toml: scene is 1001 bytes, over the limit of 1000 bytes"):
        read_regular(path, "scene", limit=1000)
    assert read_regular(path, "scene", limit=1001) == b"#" * 1001


def test_a_regular_file_whose_size_reads_zero_is_read_whole() -> None:
    status = Path("/proc/self/status")  # a regular file that says it is empty
    if not status.exists():
        pytest.skip("no /proc")
    data = read_regular(status, "file", limit=1 << 20)
    assert data.startswith(b"Name:")
    with pytest.raises(FileReadError, match="grew past the limit of 10 bytes"):
        read_regular(status, "file", limit=10)
