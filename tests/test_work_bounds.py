"""Work bounded by the size of the input (issue 27): each once super-linear, with generated inputs.

1. the convex hull of a flat disc (co-circular points): qhull's flat-facet merging was quadratic;
2. small-part fixing: a pass over the whole mesh per part;
3. an arm's servo design: the descendants of each segment found by walking the tree from every segment;
4. ``simrun test``'s run matrix (seeds x ``--vary`` grids): no cap.

Where a regression would hang, the work runs in a child process with a timeout far above the fixed code's
time and far below the old one's (no timings are asserted).
"""

from __future__ import annotations

import json
import math
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from bounded import run_bounded

from meshtool.hulls.compute import HullOptions, convex_hull
from meshtool.repair.mesh import TriMesh
from meshtool.repair.smallparts import fix_small_parts

TESTS = Path(__file__).resolve().parent
SQUARE = TESTS.parent / "fixtures" / "scenes" / "boebot_square.toml"


def _child(code: str, seconds: float = 120.0) -> str:
    """Run ``code`` in a fresh interpreter (this folder importable) and return its standard output."""
    done = subprocess.run(
        [sys.executable, "-c", f"import sys; sys.path.insert(0, {str(TESTS)!r})\n{code}"],
        capture_output=True,
        text=True,
        timeout=seconds,
        check=False,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout


# -- 1. the hull of a flat disc --------------------------------------------------------------------------------


def disc(count: int, radius: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """``count`` points on a circle and its centre, in a tilted plane (points, unit normal)."""
    angle = np.linspace(0.0, 2 * np.pi, count, endpoint=False)
    flat = np.vstack([np.c_[np.cos(angle), np.sin(angle), np.zeros(count)] * radius, [[0.0, 0.0, 0.0]]])
    tilt = math.radians(30)
    rotation = np.array([[1, 0, 0], [0, math.cos(tilt), -math.sin(tilt)], [0, math.sin(tilt), math.cos(tilt)]])
    return flat @ rotation.T + [0.5, -0.25, 2.0], rotation @ [0.0, 0.0, 1.0]


def test_the_hull_of_a_flat_disc_is_a_thin_antiprism_made_in_n_log_n(tmp_path: Path) -> None:
    """80 000 points on a circle: minutes per 20 000 before (qhull merging a flat facet point by point)."""
    out = tmp_path / "hull.npz"
    _child(
        "import numpy as np\n"
        "from test_work_bounds import disc\n"
        "from meshtool.hulls.compute import HullOptions, convex_hull\n"
        "points, _ = disc(80_000)\n"
        "vertices, faces, notes = convex_hull(points, HullOptions())\n"
        f"np.savez({str(out)!r}, vertices=vertices, faces=faces, notes=np.array(notes))\n"
    )
    saved = np.load(out)
    vertices, faces, notes = saved["vertices"], saved["faces"], saved["notes"].tolist()
    assert notes == ["thickened", "reduced"] and len(vertices) == 64
    _assert_convex(vertices, faces)
    _, normal = disc(3)
    height = (vertices - [0.5, -0.25, 2.0]) @ normal
    assert np.ptp(height) == pytest.approx(0.001, rel=1e-6)  # min thickness, centred on the disc's plane
    assert abs(height.max() + height.min()) < 1e-9
    radial = np.linalg.norm((vertices - [0.5, -0.25, 2.0]) - np.outer(height, normal), axis=1)
    np.testing.assert_allclose(radial, 1.0, rtol=1e-9)  # every vertex is a point of the rim
    from scipy.spatial import ConvexHull

    volume = ConvexHull(vertices).volume  # the disc's area times the thickness, less the rim's sagitta
    assert 0.99 * math.pi * 0.001 < volume < math.pi * 0.001


def test_the_hull_of_a_thick_finely_divided_cylinder_is_made_without_qhulls_merges(tmp_path: Path) -> None:
    """2 x 40 000 co-circular points on two rings: 16 s at 2 x 10 000 before (qhull merging the side facets)."""
    out = tmp_path / "hull.npz"
    _child(
        "import numpy as np\n"
        "from meshtool.hulls.compute import HullOptions, convex_hull\n"
        "t = np.linspace(0, 2 * np.pi, 40_000, endpoint=False)\n"
        "ring = np.c_[np.cos(t), np.sin(t)]\n"
        "points = np.r_[np.c_[ring, np.zeros(len(t))], np.c_[ring, np.full(len(t), 0.5)]]\n"
        "vertices, faces, notes = convex_hull(points, HullOptions())\n"
        f"np.savez({str(out)!r}, vertices=vertices, faces=faces, notes=np.array(notes))\n"
    )
    saved = np.load(out)
    vertices, faces, notes = saved["vertices"], saved["faces"], saved["notes"].tolist()
    assert notes == ["reduced"] and len(vertices) == 64
    _assert_convex(vertices, faces)
    np.testing.assert_allclose(np.linalg.norm(vertices[:, :2], axis=1), 1.0, rtol=1e-9)  # rim points only
    assert sorted(set(np.round(vertices[:, 2], 12))) == [0.0, 0.5]
    from scipy.spatial import ConvexHull

    volume = ConvexHull(vertices).volume  # the cylinder's, less 32 chords' segments per ring
    assert 0.99 * math.pi * 0.5 < volume < math.pi * 0.5


def test_a_small_flat_set_gets_the_prism_of_all_its_points() -> None:
    """Within the budget, the hull is what thickening gave before: every point moved by half the thickness."""
    square = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0.0]])
    vertices, faces, notes = convex_hull(square, HullOptions(min_thickness=0.002))
    assert notes == ["thickened"]
    _assert_convex(vertices, faces)
    lift = np.array([0, 0, 0.001])
    expected = np.vstack([square + lift, square - lift])
    got = vertices[np.lexsort(vertices.T[::-1])]
    np.testing.assert_allclose(got, expected[np.lexsort(expected.T[::-1])], atol=1e-15)


def _assert_convex(vertices: np.ndarray, faces: np.ndarray) -> None:
    """Every vertex inside every face plane, every edge shared by two faces in opposite directions."""
    tri = vertices[faces]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    excess = vertices @ normals.T - (normals * tri[:, 0]).sum(axis=1)
    assert excess.max() <= 1e-9 * max(float(np.abs(vertices).max()), 1.0)
    edges = {tuple(e) for e in np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]).tolist()}
    assert len(edges) == 3 * len(faces) and edges == {(b, a) for a, b in edges}


# -- 2. small parts --------------------------------------------------------------------------------------------

TETRA = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
TETRA_FACES = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]


def parts_mesh(pieces: list[tuple[int, int, np.ndarray, list[list[int]]]], materials: int, parts: list[str]) -> TriMesh:
    """A mesh of (material, part, positions, triangles) pieces, in that order."""
    positions, faces, material, part = [], [], [], []
    base = 0
    for m, p, pts, tris in pieces:
        positions.append(np.asarray(pts, dtype=np.float64))
        faces += [[base + i for i in t] for t in tris]
        material += [m] * len(tris)
        part += [p] * len(tris)
        base += len(pts)
    count = len(faces)
    return TriMesh(
        positions=np.vstack(positions),
        colors=None,
        texcoords=np.zeros((0, 2)),
        normals=np.zeros((0, 3)),
        faces=np.asarray(faces, dtype=np.int64),
        face_uv=np.full((count, 3), -1, dtype=np.int64),
        face_normal=np.full((count, 3), -1, dtype=np.int64),
        face_material=np.asarray(material, dtype=np.int64),
        face_part=np.asarray(part, dtype=np.int64),
        face_lines=np.arange(1, count + 1, dtype=np.int64),
        material_names=[f"m{k}" for k in range(materials)],
        part_names=parts,
        source_polygons=count,
        degenerate=0,
    )


def test_small_parts_are_merged_and_padded_as_before() -> None:
    """The reference numbers are the output of the per-part implementation this one replaced."""
    mesh = parts_mesh(
        [
            (0, 0, TETRA, TETRA_FACES),  # body: loads
            (0, 1, [[2.0, 0, 0], [2.5, 0, 0], [2, 0.5, 0], [2.0, 0, 0]], [[0, 1, 2], [3, 2, 1]]),  # dup: 3 distinct
            (0, 2, [[2.0, 0, 0], [2.5, 0, 0], [2, 0, 0.5]], [[0, 1, 2]]),  # fin: nearest to body
            (0, 3, [[2.75, 0, 0], [3.25, 0, 0], [3, 0.5, 0]], [[0, 1, 2]]),  # tie: 1.75 m from body and wing
            (0, 4, TETRA + np.array([5.0, 0, 0]), TETRA_FACES),  # wing: loads
            (1, 5, [[0.0, 0, 2], [0.5, 0, 2], [0, 0.5, 2]], [[0, 1, 2]]),  # badge: alone in its material
        ],
        2,
        ["body", "dup", "fin", "tie", "wing", "badge"],
    )
    findings = fix_small_parts(mesh, "ref.obj")
    assert [(f.code, f.message) for f in findings] == [
        *(
            (
                "part-merged",
                f"part {p!r} (3 distinct vertices, material 'm0') merged into part 'body' so MuJoCo can load it",
            )
            for p in ("dup", "fin", "tie")
        ),
        (
            "part-padded",
            "part 'badge' (material 'm1') has fewer than 4 distinct vertices: padded with a sliver triangle so "
            "MuJoCo can load it",
        ),
    ]
    assert mesh.face_part.tolist() == [0] * 8 + [4] * 4 + [5, 5]
    assert mesh.faces.tolist()[-2:] == [[18, 19, 20], [18, 19, 21]] and mesh.face_lines.tolist()[-2:] == [13, 13]
    assert mesh.positions[-1].tolist() == [0.0, 0.0, 2.0000707106781186] and len(mesh.positions) == 22


def scattered_parts(count: int, seed: int = 0) -> TriMesh:
    """``count`` parts of one material: half a single triangle (MuJoCo refuses it), half a tetrahedron."""
    rng = np.random.default_rng(seed)
    small = np.arange(count) % 2 == 0
    centres = rng.random((count, 3)) * 100
    pieces = []
    for k in range(count):
        if small[k]:
            pieces.append((0, k, centres[k] + rng.random((3, 3)) * 0.1, [[0, 1, 2]]))
        else:
            pieces.append((0, k, centres[k] + TETRA * 0.1 * (0.5 + rng.random()), TETRA_FACES))
    return parts_mesh(pieces, 1, [f"p{k:06d}" for k in range(count)])


def test_fifty_thousand_parts_are_fixed_in_n_log_n() -> None:
    """25 000 one-triangle parts merged into their nearest of 25 000 tetrahedra (4 000 parts took 227 s)."""
    out = _child(
        "import json\n"
        "from test_work_bounds import scattered_parts\n"
        "from meshtool.repair.smallparts import fix_small_parts\n"
        "print(json.dumps([f.message for f in fix_small_parts(scattered_parts(50_000), 'x.obj')]))\n"
    )
    merges = [re.match(r"part 'p(\d+)' .* merged into part 'p(\d+)'", m) for m in json.loads(out)]
    assert len(merges) == 25_000 and all(merges)
    pairs = np.array([[int(m.group(1)), int(m.group(2))] for m in merges if m])
    assert (pairs[:, 0] % 2 == 0).all() and (pairs[:, 1] % 2 == 1).all()
    mesh = scattered_parts(50_000)  # a sample checked against every candidate: each part's vertices in a row
    starts = np.concatenate([[0], np.cumsum(np.where(np.arange(50_000) % 2 == 0, 3, 4))[:-1]])
    lo, hi = np.minimum.reduceat(mesh.positions, starts), np.maximum.reduceat(mesh.positions, starts)
    loadable = np.arange(1, 50_000, 2)
    for small, target in pairs[np.random.default_rng(1).choice(len(pairs), 100, replace=False)]:
        d = np.maximum(np.maximum(lo[small], lo[loadable]) - np.minimum(hi[small], hi[loadable]), 0.0)
        gap = np.sqrt((d * d).sum(axis=1))
        assert target == loadable[np.lexsort((loadable, gap))[0]]


# -- 3. servo design -------------------------------------------------------------------------------------------

#: (inertia, kv) of every position servo, as the per-joint tree walk computed them (bit for bit).
SERVO_REFERENCE = {
    "KukaLBR3": {
        "a/link1": (3.0437133333333333, 54.435552450523694),
        "a/link2": (1.6387800000000003, 38.345642401480674),
        "a/link3": (0.7698466666666667, 20.81687597852182),
        "a/link4": (0.2969966666666666, 11.414192594272762),
        "a/link5": (0.08014666666666667, 3.6620373247327382),
        "a/link6": (0.01652166666666667, 0.8177825319144569),
        "a/link7": (0.010708333333333334, 0.5255628917943214),
    },
    "LynxL6": {
        "a/base_rotate": (0.02068657, 0.5432195581603533),
        "a/shoulder": (0.018946703333333335, 0.5155762070342442),
        "a/elbow": (0.012669503333333337, 0.370235553164489),
        "a/wrist": (0.010310303333333333, 0.2471975394509268),
        "a/wrist_rotate": (0.010056053333333334, 0.1805597500330845),
        "a/finger_left": (0.011, 2.63318042491699),
    },
    "tree": {
        "a/base": (0.2596184534557524, 8.19055353659952),
        "a/arm/x": (1.06, 12.560219778561036),
        "a/arm/ry": (0.08492041666666666, 0.23457389674183737),
        "a/arm/rz": (0.08492041666666666, 0.6064599236000796),
        "a/left": (0.15100000000000002, 0.45764114548890156),
        "a/right": (0.0105, 0.3),
    },
}


def _tree_arm() -> Any:
    from simrun.robots.arm import ArmJoint, ArticulatedArm, Segment, SixDof

    return ArticulatedArm(
        name="a",
        segments=(
            Segment("base", 0.2, 0.05, 1.0, ArmJoint(kp=100)),
            Segment(
                "arm",
                0.3,
                0.04,
                0.8,
                SixDof(x=ArmJoint(kp=50, armature=0.01), ry=ArmJoint(kp=30, damping_ratio=0.7), rz=ArmJoint(kp=20)),
                offset=(0.01, 0.0, 0.02),
            ),
            Segment("left", 0.1, 0.01, 0.1, ArmJoint(kind="slide", kp=10, armature=0.001), offset=(0.0, 0.02, 0.0)),
            Segment("right", 0.1, 0.01, 0.1, ArmJoint(kp=5, damping_ratio=None, kv=0.3), parent="arm"),
            Segment("tip", 0.05, 0.01, 0.05, ArmJoint(locked=True), parent="left"),
        ),
    )


@pytest.mark.parametrize("which", sorted(SERVO_REFERENCE))
def test_servo_design_keeps_its_numbers(which: str) -> None:
    from simrun.robots.arm import KukaLBR3, LynxL6, servo_design

    arm = {"KukaLBR3": lambda: KukaLBR3(name="a"), "LynxL6": lambda: LynxL6(name="a"), "tree": _tree_arm}[which]()
    design = servo_design(arm, "a")
    assert {name: (d["inertia"], d["kv"]) for name, d in design.items()} == SERVO_REFERENCE[which]


def test_servo_design_walks_the_tree_a_quadratic_number_of_steps() -> None:
    """A chain of 300 segments: at most n^2 parent look-ups (the walk from every segment to every other was
    n^3 / 6, 4.5 million; 1 600 segments took 80 s)."""
    from simrun.robots.arm import ArticulatedArm, Segment, servo_design

    class Counted(dict[str, str | None]):
        steps = 0

        def get(self, key: str, default: Any = None) -> Any:
            Counted.steps += 1
            return super().get(key, default)

        def __getitem__(self, key: str) -> str | None:
            Counted.steps += 1
            return super().__getitem__(key)

    class Chain(ArticulatedArm):
        def parents(self) -> dict[str, str | None]:
            return Counted(super().parents())

    n = 300
    design = servo_design(Chain(name="c", segments=tuple(Segment(f"s{k}", 0.1) for k in range(n))), "c")
    assert len(design) == n and 0 < Counted.steps <= n * n


def test_an_arm_over_the_segment_limit_is_refused_naming_the_entity(tmp_path: Path) -> None:
    """5 000 segments hung the servo design; 1 000 (the limit) compile and simulate."""
    from simrun.robots.arm import MAX_ARM_SEGMENTS

    def scene(count: int) -> Path:
        lines = ["[world]", "", "[[entities]]", 'type = "ArticulatedArm"', 'name = "snake"', ""]
        for k in range(count):
            lines += ["[[entities.segments]]", f'name = "s{k}"', "length = 0.01", ""]
        path = tmp_path / f"snake{count}.toml"
        path.write_text("\n".join(lines))
        return path

    refused = run_bounded(["simrun", "check", str(scene(5000))], seconds=120)
    assert refused.code == 1 and "Traceback" not in refused.err
    assert refused.err.strip().splitlines() == [
        f"error: {scene(5000).as_posix()}:3: entities[0] 'snake': 5000 segments, more than {MAX_ARM_SEGMENTS} "
        "(an arm's servo design grows with the square of its segments; split it into several arms)"
    ]
    out = _child(
        "from simrun.robots.arm import ArticulatedArm, Segment, servo_design\n"
        "arm = ArticulatedArm(name='c', segments=tuple(Segment(f's{k}', 0.01) for k in range(1000)))\n"
        "print(len(servo_design(arm, 'c')))\n"
    )
    assert out.strip() == "1000"


# -- 4. simrun test's run matrix -------------------------------------------------------------------------------


def test_the_run_matrix_is_capped_before_it_is_built() -> None:
    """Two grids of a million values: a MemoryError before; now one usage line naming the sizes."""
    done = run_bounded(
        ["simrun", "test", str(SQUARE), "--vary", "box.x=0:1:1000000", "--vary", "box.y=0:1:1000000"],
        seconds=120,
        memory_mb=1500,
    )
    assert done.code == 2 and "Traceback" not in done.err
    assert done.err.strip().splitlines() == [
        "usage error: 1 seed(s) x 1000000 values of box.x x 1000000 values of box.y = 1000000000000 runs per "
        "scene, more than --max-runs 10000 (use fewer seeds or grid values, or raise --max-runs, at most 1000000)"
    ]
    small = run_bounded(
        ["simrun", "test", str(SQUARE), "--seeds", "0:3", "--vary", "box.y=0.5:1.5:3", "--max-runs", "8"], seconds=120
    )
    assert small.code == 2 and "3 seed(s) x 3 values of box.y = 9 runs per scene, more than --max-runs 8" in small.err


def test_run_count_multiplies_seeds_and_grids_only() -> None:
    from simrun.scenetest.vary import MAX_RUNS, VaryError, check_run_count, parse_vary, run_count, variations

    axes = [parse_vary("box.y=0:1:11"), parse_vary("box.mass=uniform(1,2)"), parse_vary("box.x=0.5")]
    assert run_count(20, axes) == 220
    check_run_count(list(range(20)), axes, 220)  # at the cap: accepted
    with pytest.raises(VaryError, match=r"20 seed\(s\) x 11 values of box.y = 220 runs per scene"):
        check_run_count(list(range(20)), axes, 219)
    huge = [parse_vary(f"box.{k}=0:1:{MAX_RUNS}") for k in ("x", "y")]
    with pytest.raises(VaryError, match="grid variations"):
        variations(huge)  # refused before the cross product is made
