"""Collision hulls: validity, coverage, budgets, decomposition (real CoACD), cache, MJCF, and physics."""

import json
from pathlib import Path

import mujoco
import numpy as np
import pytest
from click.testing import CliRunner

from meshtool.cli.main import main, obj2bin
from meshtool.hulls.compute import Hull, HullOptions, compute_hulls, convex_hull
from meshtool.hulls.decompose import decompose
from meshtool.packfile import load
from meshtool.pipeline import ConvertOptions, convert
from meshtool.repair.normalise import NormaliseOptions, prepare

BOWL = Path("bowl") / "bowl.obj"


def assert_convex(vertices, faces, tol=1e-9):
    """The strongest hull predicate: every vertex lies inside every face plane of its own hull."""
    tri = vertices[faces]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    excess = vertices @ normals.T - (normals * tri[:, 0]).sum(axis=1)
    scale = np.abs(vertices).max()
    assert excess.max() <= tol * max(scale, 1.0)
    # closed: every edge is shared by exactly two faces, in opposite directions
    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    assert len({tuple(e) for e in edges.tolist()}) == len(edges)
    assert {tuple(e) for e in edges.tolist()} == {tuple(e) for e in edges[:, ::-1].tolist()}


def outside(points, hull: Hull):
    tri = hull.vertices[hull.faces]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return np.maximum((points @ n.T - (n * tri[:, 0]).sum(axis=1)).max(axis=1), 0)


@pytest.fixture(scope="module")
def bowl_asset():
    return prepare(Path(__file__).resolve().parent.parent / "fixtures" / BOWL, NormaliseOptions(up="z"))


@pytest.fixture(scope="module")
def decomposed(bowl_asset, tmp_path_factory):
    cache = tmp_path_factory.mktemp("cache")
    options = HullOptions(mode="decompose", threshold=0.1, cache_dir=cache)
    return compute_hulls(bowl_asset.mesh, options), options, cache


def test_convex_hull_is_valid_and_covers_the_mesh(bowl_asset):
    options = HullOptions(max_hull_vertices=10000)
    (hull,) = compute_hulls(bowl_asset.mesh, options).hulls
    assert_convex(hull.vertices, hull.faces)
    assert outside(bowl_asset.mesh.positions, hull).max() < 1e-9


@pytest.mark.parametrize("budget", [4, 8, 32, 64])
def test_vertex_budget(bowl_asset, budget):
    vertices, faces, notes = convex_hull(bowl_asset.mesh.positions, HullOptions(max_hull_vertices=budget))
    assert len(vertices) <= budget and notes == ["reduced"]
    assert_convex(vertices, faces)


@pytest.mark.parametrize(
    "points",
    [
        np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0.0]]),  # flat
        np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0.0]]),  # collinear
        np.array([[0.5, 0.5, 0.5]]),  # a point
    ],
)
def test_flat_and_degenerate_sets_are_thickened(points):
    vertices, faces, notes = convex_hull(points, HullOptions(min_thickness=0.002))
    assert "thickened" in notes
    assert_convex(vertices, faces)
    spans = np.ptp(vertices, axis=0)
    assert spans.min() >= 0.002 * 0.999 or len(points) == 1


def test_decomposition_is_valid_and_covers_the_surface(bowl_asset, decomposed):
    result, options, _ = decomposed
    assert 2 <= len(result.hulls) <= options.max_hulls
    for hull in result.hulls:
        assert_convex(hull.vertices, hull.faces)
        assert len(hull.vertices) <= options.max_hull_vertices
    rng = np.random.default_rng(0)
    mesh = bowl_asset.mesh
    tri = mesh.positions[mesh.faces[rng.integers(0, len(mesh.faces), 500)]]
    w = rng.dirichlet([1, 1, 1], 500)
    samples = (tri * w[:, :, None]).sum(axis=1)
    distance = np.min([outside(samples, h) for h in result.hulls], axis=0)
    assert distance.max() < 1e-4  # the union of hulls contains the surface (within 0.1 mm)
    # and leaves the cavity open: the bowl's centre, 5 cm above the inner bottom, is in no hull
    centre = np.array([[0.0, 0.0, -0.04]])
    assert min(outside(centre, h)[0] for h in result.hulls) > 0.01


def test_cache_hit_and_determinism(bowl_asset, decomposed):
    result, options, cache = decomposed
    again = compute_hulls(bowl_asset.mesh, options)
    assert again.cache_hits == 1 and result.cache_hits == 0
    assert [h.vertices.tobytes() for h in again.hulls] == [h.vertices.tobytes() for h in result.hulls]
    entries = sorted(p.name for p in cache.rglob("*.npz"))  # the pieces and the finished hulls, one entry each
    assert len(entries) == 2 and entries[0].endswith(".hulls.npz") and not entries[1].endswith(".hulls.npz")
    fresh = compute_hulls(bowl_asset.mesh, HullOptions(mode="decompose", threshold=0.1, cache_dir=None))
    assert [h.vertices.tobytes() for h in fresh.hulls] == [h.vertices.tobytes() for h in result.hulls]


def test_bad_input_and_timeouts_fail_cleanly(bowl_asset):
    pieces, hit, problem = decompose(np.full((8, 3), np.nan), np.zeros((4, 3), dtype=np.int64), HullOptions())
    assert (pieces, hit, problem) == ([], False, "mesh is empty, too small or not finite")
    slow = compute_hulls(bowl_asset.mesh, HullOptions(mode="decompose", timeout_s=0.05))
    assert [f.code for f in slow.findings][:1] == ["decompose-failed"]
    assert "did not finish within 0 s" in slow.findings[0].message
    assert len(slow.hulls) == 1  # the part fell back to its convex hull


def test_objects_mode_gives_one_hull_per_part(fixtures):
    asset = prepare(fixtures / "multi_material" / "crate.obj")
    result = compute_hulls(asset.mesh, HullOptions(mode="objects"))
    assert [asset.mesh.part_names[h.part] for h in result.hulls] == ["Body", "Lid"]


def test_presets_and_bad_options():
    assert (HullOptions.preset("mjx").max_hulls, HullOptions.preset("mjx").max_hull_vertices) == (8, 32)
    assert HullOptions.preset("physx-gpu", max_hulls=3).max_hulls == 3
    with pytest.raises(ValueError):
        HullOptions(mode="spheres")
    with pytest.raises(ValueError):
        HullOptions.preset("bullet")


def test_mjcf_compiles_and_mass_comes_from_collision_only(fixtures, tmp_path):
    mbin = tmp_path / "crate.mbin"
    convert(fixtures / "multi_material" / "crate.obj", mbin, ConvertOptions(NormaliseOptions()))
    runner = CliRunner()
    result = runner.invoke(main, ["mjcf", str(mbin), "-o", str(tmp_path / "m"), "--mass", "1"])
    assert result.exit_code == 0, result.output
    model = mujoco.MjModel.from_xml_path(str(tmp_path / "m" / "crate" / "crate.xml"))
    assert model.body_mass[1] == pytest.approx(1.0)  # a 1 kg cube stays 1 kg
    visual = model.geom_group == 2
    assert visual.sum() == 4 and (model.geom_contype[visual] == 0).all() and (model.geom_conaffinity[visual] == 0).all()
    assert (model.geom_group == 3).sum() == 1 and model.nmat == 3 and model.ntex == 2
    result = runner.invoke(main, ["mjcf", str(mbin), "-o", str(tmp_path / "d")])
    model = mujoco.MjModel.from_xml_path(str(tmp_path / "d" / "crate" / "crate.xml"))
    assert model.body_mass[1] == pytest.approx(1000.0)  # 1 m^3 at 1000 kg/m^3


def bowl_and_ball(xml: Path, body: str) -> tuple[np.ndarray, np.ndarray, bool]:
    spec = mujoco.MjSpec.from_file(str(xml))
    spec.body(body).pos = [0, 0, 0.105]
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[1, 1, 0.1])
    ball = spec.worldbody.add_body(name="ball", pos=[0, 0, 0.055])
    ball.add_freejoint()
    ball.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.02, 0, 0], density=500)
    model = spec.compile()
    data = mujoco.MjData(model)
    while data.time < 2.0:
        mujoco.mj_step(model, data)
    ok = bool(np.isfinite(data.qpos).all()) and all(w.number == 0 for w in data.warning)
    return data.body(body).xpos.copy(), data.body("ball").xpos.copy(), ok


def test_decomposed_bowl_keeps_the_ball_and_a_single_hull_does_not(fixtures, tmp_path):
    runner = CliRunner()
    for mode in ("decompose", "convex"):
        out = tmp_path / f"{mode}.mbin"
        args = [str(fixtures / BOWL), "--up", "z", "--hulls", mode, "--threshold", "0.1", "--no-cache", "-o", str(out)]
        assert runner.invoke(obj2bin, args).exit_code == 0
        assert runner.invoke(main, ["mjcf", str(out), "-o", str(tmp_path / "mj"), "--free-joint"]).exit_code == 0
    bowl, ball, ok = bowl_and_ball(tmp_path / "mj" / "decompose" / "decompose.xml", "decompose")
    assert ok
    assert abs(bowl[2] - 0.1) < 0.01  # settled on the plane
    assert inside(ball, bowl)
    bowl, ball, ok = bowl_and_ball(tmp_path / "mj" / "convex" / "convex.xml", "convex")
    assert ok
    assert not inside(ball, bowl)  # pushed out of the cavity the full hull fills (aside, or under the bowl)


def inside(ball, bowl):
    """The ball rests in the bowl's cavity: centred, below the rim, above the bottom."""
    return np.linalg.norm(ball[:2] - bowl[:2]) < 0.02 and bowl[2] - 0.09 < ball[2] < bowl[2]


def test_hulls_are_stored_and_reported(fixtures, tmp_path):
    out = tmp_path / "b.mbin"
    result = CliRunner().invoke(obj2bin, [str(fixtures / BOWL), "--up", "z", "-o", str(out), "--json"])
    report = json.loads(result.stdout)["stats"]["hulls"]
    assert report["hulls"] == 1 and report["vertices_per_hull"] == [64] and report["volume_ratio"] > 3
    with load(out) as p:
        ((vertices, faces),) = p.hulls
        assert_convex(np.asarray(vertices, np.float64), np.asarray(faces, np.int64), tol=1e-6)
        assert p.meta["hull_quality"]["hulls"] == 1


def test_repair_merges_a_split_but_closed_mesh():
    from meshtool.hulls.decompose import repair

    box = __import__("trimesh").creation.box()
    split_points = box.vertices[box.faces].reshape(-1, 3)  # every triangle with its own three vertices
    split_faces = np.arange(len(split_points)).reshape(-1, 3)
    points, faces, manifold = repair(split_points, split_faces)
    assert manifold and len(points) == 8 and len(faces) == 12
    _, open_faces, manifold = repair(box.vertices, box.faces[:-1])
    assert not manifold and len(open_faces) == 11


def test_hulls_command_and_info(fixtures, tmp_path):
    runner = CliRunner()
    result = runner.invoke(main, ["hulls", str(fixtures / BOWL), "--up", "z", "--json"])
    report = json.loads(result.stdout)["hulls"]
    assert report["hulls"] == 1 and report["vertices_per_hull"] == [64]
    out = tmp_path / "b.mbin"
    runner.invoke(obj2bin, [str(fixtures / BOWL), "--up", "z", "-o", str(out), "--hulls", "objects"])
    assert "  hulls: 1 hull(s), vertices [64], hull/mesh volume" in runner.invoke(main, ["info", str(out)]).stdout


def test_convex_hull_of_many_points_needs_no_n_by_n_matrix():
    """The thickness check used a full SVD: (n, n) floats, 20 GB for 50 000 points."""
    points = np.random.default_rng(0).random((50_000, 3))
    vertices, _faces, notes = convex_hull(points, HullOptions())
    assert len(vertices) <= 64 and notes == ["reduced"]
    assert (vertices >= 0).all() and (vertices <= 1).all()


def test_reduced_hull_hugs_a_fine_sphere():
    """Farthest-point insertion keeps the surface close: under 2 % of the diagonal outside (qhull's early
    stop left 6.5 %)."""
    import trimesh

    from meshtool.hulls.compute import _outside_distance

    sphere = trimesh.creation.icosphere(subdivisions=3, radius=0.05)
    vertices, faces, notes = convex_hull(np.asarray(sphere.vertices), HullOptions(max_hull_vertices=64))
    assert notes == ["reduced"] and len(vertices) == 64
    samples, _ = trimesh.sample.sample_surface(sphere, 2000, seed=0)
    gap = _outside_distance(samples, Hull(vertices, faces, 0)).max()
    assert gap < 0.02 * np.linalg.norm(np.ptp(sphere.vertices, axis=0))
