"""simrun/world/assets.py: an ``.mbin``'s arrays handed to MjSpec (as in-memory ``.msh``) compile to the mesh MuJoCo
makes of the same mesh from an OBJ file (MuJoCo's own loader is the ground truth)."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import mujoco
import numpy as np
import pytest

from meshtool.packfile import load
from simrun import MeshEntity, Pose, World

GOLDEN = Path(__file__).resolve().parent.parent / "fixtures" / "golden"


def _obj(positions: np.ndarray, faces: np.ndarray, normals: np.ndarray | None, uvs: np.ndarray | None) -> str:
    """OBJ text of per-vertex arrays (every corner uses one index for v, vt and vn); exact float32 decimals."""
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in np.asarray(positions, np.float64).tolist()]
    if uvs is not None:
        lines += [f"vt {u!r} {v!r}" for u, v in np.asarray(uvs, np.float64).tolist()]
    if normals is not None:
        lines += [f"vn {x!r} {y!r} {z!r}" for x, y, z in np.asarray(normals, np.float64).tolist()]

    def corner(k: int) -> str:
        return (
            f"{k}/{k if uvs is not None else ''}/{k}"
            if normals is not None
            else (f"{k}/{k}" if uvs is not None else f"{k}")
        )

    lines += ["f " + " ".join(corner(k + 1) for k in face) for face in np.asarray(faces).tolist()]
    return "\n".join(lines) + "\n"


def _mujoco_obj(path: Path, scale: float, inertia: mujoco.mjtMeshInertia) -> mujoco.MjModel:
    """MuJoCo compiling one OBJ mesh (a fresh file name: its mesh cache is keyed by name)."""
    spec = mujoco.MjSpec()
    mesh = spec.add_mesh(name="m", file=str(path))
    mesh.scale = [scale] * 3
    mesh.inertia = inertia
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname="m", contype=0, conaffinity=0)
    return spec.compile()


def _mesh(model: mujoco.MjModel, k: int) -> dict[str, np.ndarray]:
    """The compiled arrays of mesh ``k``: vertices, faces, normals, texture coordinates, frame."""
    v0, nv = model.mesh_vertadr[k], model.mesh_vertnum[k]
    f0, nf = model.mesh_faceadr[k], model.mesh_facenum[k]
    t0, nt = model.mesh_texcoordadr[k], model.mesh_texcoordnum[k]
    n0, nn = model.mesh_normaladr[k], model.mesh_normalnum[k]
    return {
        "vert": model.mesh_vert[v0 : v0 + nv],
        "face": model.mesh_face[f0 : f0 + nf],
        "texcoord": model.mesh_texcoord[t0 : t0 + nt] if t0 >= 0 else np.empty((0, 2)),
        "normal": model.mesh_normal[n0 : n0 + nn],
        "pos": model.mesh_pos[k],
        "quat": model.mesh_quat[k],
    }


@pytest.mark.parametrize("scale", [1.0, 2.5])
@pytest.mark.parametrize("name", ["head-1.1", "features-1.1", "crate_quantized-1.1"])
def test_mbin_meshes_compile_as_mujoco_compiles_their_obj(name: str, scale: float, tmp_path: Path) -> None:
    """Every visual part and hull of a world's MeshEntity equals MuJoCo's compile of an OBJ of the same arrays:
    vertices, faces, normals, texture coordinates (MuJoCo's OBJ reader flips v as the .msh hand-off must) and the
    mesh frame, exactly. Parts are a submesh's triangles with the vertices they use, in pack order."""
    shutil.copy(GOLDEN / f"{name}.mbin", tmp_path / "a.mbin")
    world = World(base_dir=tmp_path)
    world.model_cache = None
    world.insert(MeshEntity(name="e", asset="a.mbin", scale=scale, pose=Pose((0.0, 0.0, 0.5))))
    model = world.model
    names = [model.mesh(k).name for k in range(model.nmesh)]
    with load(tmp_path / "a.mbin") as packed:
        indices = np.asarray(packed.indices, np.int64).reshape(-1, 3)
        cases = []
        for part, (first, count, _, _) in enumerate(np.asarray(packed.submeshes).tolist()):
            used = np.unique(indices[first : first + count])
            remap = np.full(len(packed.positions), -1)
            remap[used] = np.arange(len(used))
            arrays = (
                np.asarray(packed.positions)[used],
                remap[indices[first : first + count]],
                None if packed.normals is None else np.asarray(packed.normals)[used],
                None if packed.uvs is None else np.asarray(packed.uvs)[used],
            )
            cases.append((f"a@{scale:g}/visual{part}" if scale != 1.0 else f"a/visual{part}", arrays, "shell"))
        for k, (v, f) in enumerate(packed.hulls):
            cases.append((f"a@{scale:g}/hull{k}" if scale != 1.0 else f"a/hull{k}", (v, f, None, None), "convex"))
    assert len(cases) == model.nmesh
    inertia = {
        "shell": mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL,
        "convex": mujoco.mjtMeshInertia.mjMESH_INERTIA_CONVEX,
    }
    for k, (mesh_name, arrays, mode) in enumerate(cases):
        obj = tmp_path / f"{k}.obj"
        obj.write_text(_obj(*arrays))
        truth = _mesh(_mujoco_obj(obj, scale, inertia[mode]), 0)
        ours = _mesh(model, names.index(mesh_name))
        for key, expected in truth.items():
            assert np.array_equal(ours[key], expected), f"{mesh_name}: {key}"


def test_one_mesh_at_two_scales_and_both_collision_modes(tmp_path: Path) -> None:
    """The in-memory mesh files are named by content: the same arrays at another scale or inertia mode (MuJoCo's
    mesh cache, keyed by file name) still compile to what a world holding only that entity compiles."""
    shutil.copy(GOLDEN / "head-1.1.mbin", tmp_path / "a.mbin")
    entities = [
        MeshEntity(name="big", asset="a.mbin", scale=3.0, collision="convex", pose=Pose((0.0, 0.0, 0.5))),
        MeshEntity(name="small", asset="a.mbin", pose=Pose((1.0, 0.0, 0.5))),
    ]
    both = World(base_dir=tmp_path)
    both.model_cache = None
    for entity in entities:
        both.insert(entity)
    for entity in entities:
        mujoco.mj_clearCache(mujoco.mj_getCache())
        alone = World(base_dir=tmp_path)
        alone.model_cache = None
        alone.insert(entity)
        for k in range(alone.model.nmesh):
            name = alone.model.mesh(k).name
            ours, truth = _mesh(both.model, both.model.mesh(name).id), _mesh(alone.model, k)
            for key, expected in truth.items():
                assert np.array_equal(ours[key], expected), f"{name}: {key}"
        body = alone.model.body(entity.name)
        assert body.mass == pytest.approx(both.model.body(entity.name).mass, rel=1e-12)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_msh_bytes_is_mujocos_layout(dtype: type) -> None:
    """Counts, float32 positions/normals/uvs (v flipped) and int32 faces, little-endian, as MuJoCo reads them."""
    import struct

    from simrun.world.assets import msh_bytes

    rng = np.random.default_rng(3)
    v = rng.normal(size=(7, 3)).astype(dtype)
    n = rng.normal(size=(7, 3)).astype(dtype)
    t = rng.random((7, 2)).astype(dtype)
    f = rng.integers(0, 7, (5, 3)).astype(np.uint32)
    flipped = np.stack([t[:, 0], 1 - t[:, 1]], axis=1)
    expected = (
        struct.pack("<4i", 7, 7, 7, 5)
        + b"".join(np.asarray(a, "<f4").tobytes() for a in (v, n, flipped))
        + np.asarray(f, "<i4").tobytes()
    )
    assert msh_bytes(v, f, n, t) == expected
    assert (
        msh_bytes(v, f)
        == struct.pack("<4i", 7, 0, 0, 5) + np.asarray(v, "<f4").tobytes() + np.asarray(f, "<i4").tobytes()
    )


def test_asset_paths_resolve_as_path_resolve(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """AssetLibrary.real resolves each folder once and each file by one lstat: the same paths as resolve()."""
    from simrun.world.assets import AssetLibrary

    monkeypatch.chdir(tmp_path)
    shutil.copy(GOLDEN / "head.mbin", tmp_path / "a.mbin")

    (tmp_path / "real").mkdir()
    shutil.copy(GOLDEN / "head.mbin", tmp_path / "real" / "a.mbin")
    (tmp_path / "linked").symlink_to(tmp_path / "real")
    (tmp_path / "real" / "b.mbin").symlink_to(tmp_path / "real" / "a.mbin")
    library = AssetLibrary(mujoco.MjSpec())
    for path in (
        tmp_path / "linked" / "a.mbin",  # a linked folder
        tmp_path / "real" / "b.mbin",  # a linked file
        tmp_path / "real" / "missing.mbin",
        tmp_path / "linked" / "..",
        tmp_path / "real" / "." / "a.mbin",
        tmp_path / "linked" / ".." / "real" / "a.mbin",  # '..' after a link: the link's target's folder
        Path("//" + str(tmp_path).lstrip("/")) / "real" / "a.mbin",  # two leading slashes
        Path("relative.mbin"),
        Path("real") / "a.mbin",  # relative, existing (the working folder is tmp_path)
        Path("a.mbin"),  # in the working folder itself
        Path("/etc/passwd"),  # a file of a folder of the root
        Path("/" + tmp_path.parts[1]),  # an entry of the root folder itself
    ):
        assert library.real(path) == path.resolve(), path
        assert AssetLibrary(mujoco.MjSpec()).real(path) == path.resolve(), path  # a fresh library: same
    assert library.real(tmp_path / "linked" / "a.mbin") == tmp_path.resolve() / "real" / "a.mbin"


def test_hull_volumes_are_computed_when_a_mass_needs_them(tmp_path: Path) -> None:
    """Hull volumes (scaled) are computed on first use, the same numbers as computed when the mesh is added."""
    from meshtool.hulls import surface
    from simrun.world.assets import AssetLibrary

    shutil.copy(GOLDEN / "head-1.1.mbin", tmp_path / "head.mbin")  # one hull
    asset = AssetLibrary(mujoco.MjSpec()).mesh(tmp_path / "head.mbin", 2.0)
    assert asset._volumes is None
    hulls = load(tmp_path / "head.mbin").hulls
    assert asset.hull_volumes == [surface.volume(v, f) * 8.0 for v, f in hulls] and asset.hull_volumes
    world = World(base_dir=tmp_path)
    world.insert(MeshEntity(name="heavy", asset="head.mbin", scale=2.0, mass=3.0, pose=Pose((0.0, 0.0, 1.0))))
    world.insert(MeshEntity(name="light", asset="head.mbin", pose=Pose((1.0, 0.0, 1.0))))
    model = world.build_spec().compile()
    assert model.body("heavy").mass[0] == pytest.approx(3.0)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
@pytest.mark.parametrize("name", ["pipe.mbin", "pipe.obj"])
def test_a_fifo_mesh_asset_is_refused_as_a_mesh_asset(tmp_path: Path, name: str) -> None:
    """A FIFO named as a mesh (a pack or a mesh file) is refused by the library, naming it a mesh asset."""
    from simrun.errors import EntityError
    from simrun.world.assets import AssetLibrary

    os.mkfifo(tmp_path / name)
    with pytest.raises(EntityError) as caught:
        AssetLibrary(mujoco.MjSpec()).mesh(tmp_path / name, 1.0)
    assert str(caught.value) == f"{tmp_path / name}: mesh asset is a FIFO (named pipe), not a regular file; name a file"
