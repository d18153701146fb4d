"""The validate cache keys on the consumers under the index root (issue 38): a mesh is checked again when a
URDF/SDF/MJCF that uses it changes, and not when a description file that does not use it changes.

The layout is a vendor's: one repository (``.git``) with ``robots/NAME/NAME.xml`` two folders above
``meshes/NAME/part.obj`` (``<compiler meshdir="../../meshes"/>``), outside every folder the asset's own
listings cover. Ground truth: what the edited file says (the scale MuJoCo would apply) and a fresh check of
the same files without the cache, which a cached run must equal finding for finding.

An edit of a consumer the check already read is also caught by the result's ``deps`` (the check records the
consumer file it took the frame from); a consumer that appears or goes is caught only by the key's
:func:`meshtool.validate.snapshot.consumer_state` (without it the second test's run after adding
``trolley.xml`` answers from the cache: checked 0).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from meshtool.validate import ValidateOptions
from meshtool.validate.runner import validate

MJCF = """<mujoco model="{name}">
  <compiler meshdir="../../meshes"/>
  <asset>
    <mesh name="part" file="{mesh}"{scale}/>
  </asset>
  <worldbody>
    <body name="part"><geom type="mesh" mesh="part"/></body>
  </worldbody>
</mujoco>
"""
SPARE = """<mujoco model="spare">
  <worldbody>
    <geom type="box" size="0.1 0.1 0.1"/>
  </worldbody>
</mujoco>
"""


def cube(size: float) -> str:
    """An OBJ cube of edge ``size`` (file units), faces wound outwards."""
    corners = [(x, y, z) for x in (0, size) for y in (0, size) for z in (0, size)]
    quads = [(1, 2, 4, 3), (5, 7, 8, 6), (1, 5, 6, 2), (3, 4, 8, 7), (1, 3, 7, 5), (2, 6, 8, 4)]
    return "".join(f"v {x:g} {y:g} {z:g}\n" for x, y, z in corners) + "".join(
        "f " + " ".join(map(str, q)) + "\n" for q in quads
    )


@pytest.fixture
def repo(tmp_path: Path) -> Path:
    root = tmp_path / "repo"
    (root / ".git").mkdir(parents=True)
    for name, mesh, edge in (("arm", "arm/link.obj", 80), ("cart", "cart/body.obj", 0.3)):
        (root / "meshes" / name).mkdir(parents=True)
        (root / "meshes" / mesh).write_text(cube(edge))
        (root / "robots" / name).mkdir(parents=True)
        (root / "robots" / name / f"{name}.xml").write_text(MJCF.format(name=name, mesh=mesh, scale=""))
    (root / "robots" / "spare").mkdir()
    (root / "robots" / "spare" / "spare.xml").write_text(SPARE)
    return root


def findings(report) -> dict[str, list[tuple[str, str]]]:
    return {a.path.rsplit("/", 1)[-1]: sorted((f.code, f.message) for f in a.findings) for a in report.assets}


def test_editing_a_consumer_rechecks_its_mesh_and_an_unrelated_edit_does_not(repo: Path, tmp_path: Path) -> None:
    cached = ValidateOptions(jobs=1, cache_dir=tmp_path / "cache")
    first = validate([repo / "meshes"], cached)
    assert (first.checked, first.cache_hits) == (2, 0)
    again = validate([repo / "meshes"], cached)
    assert (again.checked, again.cache_hits) == (0, 2)
    # an 80-unit link: 80 m without a scale; the arm's MJCF now says millimetres (0.08 m)
    arm = repo / "robots" / "arm" / "arm.xml"
    arm.write_text(MJCF.format(name="arm", mesh="arm/link.obj", scale=' scale="0.001 0.001 0.001"'))
    edited = validate([repo / "meshes"], cached)
    assert (edited.checked, edited.cache_hits) == (1, 1)  # the link, not the cart's body
    fresh = validate([repo / "meshes"], ValidateOptions(jobs=1))
    assert findings(edited) == findings(fresh)
    assert findings(edited)["link.obj"] != findings(first)["link.obj"]  # the scale changed what the check says
    assert any("arm.xml (MJCF, scale 0.001 0.001 0.001)" in m for _, m in findings(fresh)["link.obj"])
    # a description file that uses neither mesh, and a file that is no description: nothing checked again
    spare = repo / "robots" / "spare" / "spare.xml"
    spare.write_text(SPARE.replace("0.1 0.1 0.1", "0.2 0.2 0.2"))
    (repo / "robots" / "README.md").write_text("the robots\n")
    unrelated = validate([repo / "meshes"], cached)
    assert (unrelated.checked, unrelated.cache_hits) == (0, 2)
    assert findings(unrelated) == findings(fresh)


def test_a_new_consumer_and_a_removed_one_recheck_the_mesh(repo: Path, tmp_path: Path) -> None:
    cached = ValidateOptions(jobs=1, cache_dir=tmp_path / "cache")
    validate([repo / "meshes" / "cart"], cached)
    second = repo / "robots" / "trolley"
    second.mkdir()
    (second / "trolley.xml").write_text(MJCF.format(name="trolley", mesh="cart/body.obj", scale=' scale="2 2 2"'))
    added = validate([repo / "meshes" / "cart"], cached)
    assert (added.checked, added.cache_hits) == (1, 0)
    assert findings(added) == findings(validate([repo / "meshes" / "cart"], ValidateOptions(jobs=1)))
    (second / "trolley.xml").unlink()
    removed = validate([repo / "meshes" / "cart"], cached)
    assert (removed.checked, removed.cache_hits) == (0, 1)  # the first run's entry answers again
