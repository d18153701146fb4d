"""Work of the OBJ pipeline obj2bin runs (issue 28), counted in bytes allocated, not timed.

``tracemalloc`` sees numpy's buffers: the peak of one call is what it allocated at once.
"""

from __future__ import annotations

import tracemalloc
from collections.abc import Callable
from typing import Any

import numpy as np

from meshtool.read.obj.lines import token_counts, values_per_line
from meshtool.repair.smallparts import MIN_VERTICES, _count_distinct


def _peak(call: Callable[[], Any]) -> tuple[Any, int]:
    tracemalloc.start()
    try:
        result = call()
        return result, tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def _face_block(lines: int) -> bytes:
    rng = np.random.default_rng(3)
    corners = rng.integers(1, 10**6, size=(lines, 3))
    return b"".join(b"f %d %d %d\n" % tuple(row) for row in corners.tolist())


def test_counting_numbers_per_line_allocates_about_the_numbers_not_8_bytes_per_byte() -> None:
    """``values_per_line`` made an int64 per byte of text (224 MB for the 43 MB bunny): now per number."""
    lines = 100_000
    block = _face_block(lines)
    counts, peak = _peak(lambda: values_per_line(block, 3 * lines))
    assert counts.tolist() == [3] * lines
    assert peak < 4 * len(block)  # the byte mask (1 per byte), offsets of spaces and lines (8 each); was 8+
    ragged = block.replace(b" ", b"\t", 10)  # tabs: the token path
    counts, peak = _peak(lambda: token_counts(ragged))
    assert counts.tolist() == [4] * lines
    assert peak < 5 * len(block)


def test_distinct_vertices_of_a_large_part_are_counted_from_its_first_rows() -> None:
    """One part of 300k vertices: counted among its first rows, not with MIN_VERTICES passes over all."""
    points = np.random.default_rng(4).normal(size=(300_000, 3))
    owner = np.zeros(len(points), dtype=np.int64)
    distinct, peak = _peak(lambda: _count_distinct(owner, points, 1))
    assert distinct.tolist() == [MIN_VERTICES]
    assert peak < points.nbytes  # the old rounds copied points[left] (all rows) several times
    # a part whose first rows repeat one point is still counted over all its rows
    points[:1000] = points[0]
    owner = np.repeat([0, 1], [2000, len(points) - 2000])
    assert _count_distinct(owner, points, 2).tolist() == [MIN_VERTICES, MIN_VERTICES]
    points[:2000] = points[0]
    assert _count_distinct(owner, points, 2).tolist() == [1, MIN_VERTICES]
