import json
import shutil
from pathlib import Path

import mujoco
import numpy as np
import pytest
import trimesh
from click.testing import CliRunner

from meshtool.cli.main import main, obj2bin
from meshtool.packfile import load, pack
from meshtool.packfile.export import Z_UP_TO_Y_UP
from meshtool.repair.normalise import NormaliseOptions, prepare

HEAD = Path("head") / "Head 1.obj"


def run(cmd, *args):
    return CliRunner().invoke(cmd, [str(a) for a in args], catch_exceptions=False)


def test_obj2bin_head_holds_mesh_material_and_png(fixtures, tmp_path):
    out = tmp_path / "head.mbin"
    result = run(obj2bin, fixtures / HEAD, "--units", "cm", "-o", out, "--json")
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    assert report["status"] == "ok" and report["stats"]["bytes"] == out.stat().st_size
    with load(out) as p:
        assert (p.positions.shape, p.indices.shape, len(p.materials), len(p.textures)) == ((61, 3), (80, 3), 1, 1)
        assert bytes(p.textures[0])[:8] == b"\x89PNG\r\n\x1a\n"
        extent = p.positions.max(axis=0) - p.positions.min(axis=0)
        np.testing.assert_allclose(extent, [0.16, 0.2, 0.24], rtol=1e-6)


def test_obj2bin_errors_and_default_output(fixtures, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    result = run(obj2bin, fixtures / "bad_index" / "bad.obj")
    assert result.exit_code == 1
    assert result.stderr.startswith("error: bad.obj:5: face refers to vertex 7")
    assert list(tmp_path.iterdir()) == []
    assert run(obj2bin, fixtures / HEAD, "--units", "cm").exit_code == 0
    assert (tmp_path / "head_1.mbin").is_file()
    (tmp_path / "into").mkdir()
    assert run(obj2bin, fixtures / HEAD, "--units", "cm", "-o", tmp_path / "into").exit_code == 0
    assert (tmp_path / "into" / "head_1.mbin").is_file()
    assert run(obj2bin, fixtures / HEAD, "--units", "furlong").exit_code == 2


def test_info_json(fixtures, tmp_path):
    out = tmp_path / "h.mbin"
    run(obj2bin, fixtures / HEAD, "--units", "cm", "-o", out)
    info = json.loads(run(main, "info", out, "--json").stdout)
    assert (info["version"], info["vertices"], info["triangles"], info["index_type"]) == ("1.1", 61, 80, "uint16")
    assert [s["kind"] for s in info["sections"]] == [
        "POS",
        "UV",
        "IDX",
        "SUBM",
        "HULT",
        "HULV",
        "HULF",
        "TEX",
        "MATL",
        "META",
    ]
    assert all(s["checksum"] == "ok" and s["offset"] % 64 == 0 for s in info["sections"])
    text = run(main, "info", out).stdout
    assert "61 vertices, 80 triangles (uint16)" in text


def test_info_on_a_damaged_file(fixtures, tmp_path):
    data = bytearray((fixtures / "golden" / "head.mbin").read_bytes())
    data[-10] ^= 1
    bad = tmp_path / "bad.mbin"
    bad.write_bytes(bytes(data))
    result = run(main, "info", bad)
    assert result.exit_code == 1
    assert result.stderr == f"error: {bad}: byte 2880: section 'META' checksum mismatch\n"


def test_unpack_round_trips_geometry_exactly(fixtures, tmp_path):
    for case, opts in ((HEAD, NormaliseOptions(units="cm")), (Path("features") / "features.obj", NormaliseOptions())):
        original = pack(prepare(fixtures / case, opts))
        src = tmp_path / "src.mbin"
        src.write_bytes(original)
        assert run(main, "unpack", src, "-o", tmp_path / "un").exit_code == 0
        again = pack(prepare(tmp_path / "un" / "src" / "src.obj", NormaliseOptions()))
        with load(src) as a:
            b = __import__("meshtool.packfile", fromlist=["parse"]).parse(again)
            np.testing.assert_array_equal(a.submeshes[:, :3], b.submeshes[:, :3])
            assert [a.meta["parts"][k] for k in a.submeshes[:, 3]] == [b.meta["parts"][k] for k in b.submeshes[:, 3]]
            for field in ("positions", "indices", "uvs", "normals", "colors"):
                x, y = getattr(a, field), getattr(b, field)
                assert (x is None) == (y is None), field
                if x is not None:
                    np.testing.assert_array_equal(x, y, err_msg=field)
            assert [m["name"] for m in a.materials] == [m["name"] for m in b.materials]
            assert [bytes(t) for t in a.textures] == [bytes(t) for t in b.textures]


def test_export_glb_and_msh(fixtures, tmp_path):
    src = tmp_path / "h.mbin"
    run(obj2bin, fixtures / HEAD, "--units", "cm", "-o", src)
    result = run(main, "export", src, "--glb", tmp_path / "h.glb", "--msh", tmp_path / "h.msh")
    assert result.exit_code == 0
    scene = trimesh.load(tmp_path / "h.glb")
    (mesh,) = scene.geometry.values()
    assert len(mesh.faces) == 80
    with load(src) as packed:
        np.testing.assert_array_equal(mesh.vertices, np.asarray(packed.positions, dtype=np.float64))
    (node,) = scene.graph.nodes_geometry
    np.testing.assert_array_equal(scene.graph[node][0], Z_UP_TO_Y_UP)  # upright in Y-up glTF viewers
    assert mesh.visual.material.baseColorTexture.size == (16, 16)
    spec = mujoco.MjSpec()
    spec.add_mesh(name="m", file=str(tmp_path / "h.msh"))
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname="m")
    model = spec.compile()
    assert (model.mesh_vertnum[0], model.mesh_facenum[0], model.mesh_texcoordnum[0]) == (61, 80, 61)
    assert run(main, "export", src).exit_code == 2


def test_mujoco_mesh_from_loaded_arrays_matches_mujoco_reading_the_obj(fixtures, tmp_path):
    folder = tmp_path / "n"
    from meshtool import normalise_to

    asset_folder, _ = normalise_to(fixtures / HEAD, folder, NormaliseOptions(units="cm"))
    data = pack(prepare(fixtures / HEAD, NormaliseOptions(units="cm")))
    (tmp_path / "h.mbin").write_bytes(data)
    with load(tmp_path / "h.mbin") as p:
        spec = mujoco.MjSpec()
        spec.add_mesh(
            name="packed", uservert=p.positions.ravel().tolist(), userface=p.indices.astype(np.int32).ravel().tolist()
        )
        spec.add_mesh(name="obj", file=str(asset_folder / "head_1.obj"))
        for name in ("packed", "obj"):
            body = spec.worldbody.add_body(name=name)
            body.add_freejoint()
            body.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname=name, density=1000)
        model = spec.compile()
    a, b = 0, 1
    assert model.mesh_vertnum[a] == model.mesh_vertnum[b] == 61
    assert model.mesh_facenum[a] == model.mesh_facenum[b] == 80
    va = model.mesh_vert[model.mesh_vertadr[a] : model.mesh_vertadr[a] + 61]
    vb = model.mesh_vert[model.mesh_vertadr[b] : model.mesh_vertadr[b] + 61]
    np.testing.assert_allclose(np.sort(va, axis=0), np.sort(vb, axis=0), atol=1e-7)
    np.testing.assert_allclose(model.body_mass[1], model.body_mass[2], rtol=1e-6)
    np.testing.assert_allclose(model.body_inertia[1], model.body_inertia[2], rtol=1e-5)


def test_folder_mode_converts_in_parallel_and_skips_unchanged(fixtures, tmp_path):
    src = tmp_path / "assets"
    shutil.copytree(fixtures / "multi_material", src / "crate")
    shutil.copytree(fixtures / "head", src / "heads")
    shutil.copytree(fixtures / "bad_index", src / "broken")
    out = tmp_path / "out"
    first = run(obj2bin, src, "-o", out, "-j", "2", "--units", "cm")
    assert first.exit_code == 1  # one asset failed, the others were written
    assert first.stdout.splitlines()[-1] == "2 written, 0 unchanged, 1 failed"
    assert sorted(p.relative_to(out).as_posix() for p in out.rglob("*.mbin")) == [
        "crate/crate.mbin",
        "heads/head_1.mbin",
    ]
    second = json.loads(run(obj2bin, src, "-o", out, "--units", "cm", "--json").stdout)
    assert second["counts"] == {"written": 0, "unchanged": 2, "failed": 1}
    (src / "crate" / "crate.mtl").write_text((src / "crate" / "crate.mtl").read_text().replace("0.8 0.1", "0.7 0.1"))
    third = json.loads(run(obj2bin, src, "-o", out, "--units", "cm", "--json").stdout)
    assert {a["source"].split("/")[-1]: a["status"] for a in third["assets"]} == {
        "crate.obj": "written",
        "Head 1.obj": "unchanged",
        "bad.obj": "failed",
    }
    fourth = json.loads(run(obj2bin, src, "-o", out, "--units", "mm", "--json").stdout)
    assert fourth["counts"]["written"] == 2  # other options: everything again
    with load(out / "crate" / "crate.mbin") as p:
        assert p.materials[0]["colors"]["Kd"] == [0.7, 0.1, 0.1]


@pytest.mark.parametrize("args", [["-j", "0"], []])
def test_folder_needs_output(fixtures, args):
    assert run(obj2bin, fixtures / "head", *args).exit_code in (1, 2)


def _slow_tree(root, count=12, n=60000):
    """``count`` OBJs of ``n`` random points on a sphere, a fan of triangles: each takes a worker a while."""
    rng = np.random.default_rng(5)
    for k in range(count):
        p = rng.normal(size=(n, 3))
        p /= np.linalg.norm(p, axis=1, keepdims=True)
        lines = [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in p]
        lines += [f"f 1 {i} {i + 1}" for i in range(2, n)]
        (root / f"ball_{k:02d}.obj").write_text("\n".join(lines) + "\n")


def test_killed_obj2bin_leaves_no_worker_behind(tmp_path):
    """kill -9 of `obj2bin DIR -o OUT -j 2`: its workers exit too (they used to block forever)."""
    import contextlib
    import signal
    import subprocess
    import sys
    import time

    psutil = pytest.importorskip("psutil")
    src = tmp_path / "src"
    src.mkdir()
    _slow_tree(src)
    command = [
        sys.executable,
        "-c",
        "from meshtool.cli.main import obj2bin; obj2bin()",
        str(src),
        "-o",
        str(tmp_path / "out"),
    ]
    parent = subprocess.Popen([*command, "-j", "2", "--no-cache"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120
        workers: list = []
        while len(workers) < 2 and time.monotonic() < deadline and parent.poll() is None:
            workers = psutil.Process(parent.pid).children()
            time.sleep(0.05)
        assert len(workers) >= 2, "the workers never started"
        parent.send_signal(signal.SIGKILL)
        parent.wait()
        deadline = time.monotonic() + 30

        def alive(p):
            try:
                return p.status() != psutil.STATUS_ZOMBIE
            except psutil.NoSuchProcess:
                return False

        while any(alive(w) for w in workers) and time.monotonic() < deadline:
            time.sleep(0.1)
        left = [w.pid for w in workers if alive(w)]
    finally:
        for w in workers:  # never leave a process behind, whatever happened (only the ones this test started)
            with contextlib.suppress(psutil.NoSuchProcess):
                w.kill()
        if parent.poll() is None:
            parent.kill()
    assert left == [], f"workers {left} outlived their killed parent"


@pytest.mark.parametrize("jobs", ["1", "2"])
def test_a_folder_conversion_prints_each_assets_warnings_under_its_name(fixtures, tmp_path, jobs):
    """``obj2bin DIR -j 2`` printed only ``[1/2] written: ...``: a head 100 times too large went unsaid (issue 26)."""
    import subprocess
    import sys

    src = tmp_path / "src"
    shutil.copytree(fixtures / "head", src / "a")
    shutil.copytree(fixtures / "head", src / "b")
    exe = str(Path(sys.executable).parent / "obj2bin")
    single = subprocess.run(
        [exe, str(src / "a" / "Head 1.obj"), "-o", str(tmp_path / "one.mbin")],
        capture_output=True,
        text=True,
        timeout=300,
    )
    warning = next(line for line in single.stderr.splitlines() if "scale-suspicious" in line)
    assert warning.startswith("warning: ")
    folder = subprocess.run(
        [exe, str(src), "-o", str(tmp_path / "out"), "-j", jobs], capture_output=True, text=True, timeout=300
    )
    assert folder.returncode == 0, folder.stderr
    lines = folder.stderr.splitlines()
    for name in ("a", "b"):
        at = lines.index(f"{src / name / 'Head 1.obj'}:")
        assert f"  {warning}" in lines[at + 1 : at + 3]  # after the up-axis rotation's warning (issue 31)
    quiet = subprocess.run(
        [exe, str(src), "-o", str(tmp_path / "q"), "-j", jobs, "-q"], capture_output=True, text=True, timeout=300
    )
    assert quiet.returncode == 0 and quiet.stdout == "" and quiet.stderr == ""
