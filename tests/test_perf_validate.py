"""``meshtool validate -j N`` (issue 28): workers get the largest assets first, so none is left with a long tail.

Counted, not timed: the order the tasks are handed out in, and that the report's order does not change.
"""

from __future__ import annotations

from pathlib import Path

from meshtool.validate.runner import largest_first
from meshtool.validate.task import AssetTask


def test_workers_take_the_largest_assets_first(tmp_path: Path) -> None:
    sizes = {"a.obj": 10, "b.obj": 5000, "c.obj": 10, "d.obj": 300}
    tasks = []
    for name, size in sizes.items():
        path = tmp_path / name
        path.write_bytes(b"v 0 0 0\n" * size)
        tasks.append(AssetTask(path, name))
    tasks.append(AssetTask(tmp_path / "missing.obj", "missing.obj"))
    order = [t.display for t in largest_first(tasks)]
    assert order == ["b.obj", "d.obj", "a.obj", "c.obj", "missing.obj"]
    assert [t.display for t in tasks][:4] == list(sizes)  # the caller's list is not reordered
