"""Hostile URDFs (issue 27): no read outside the robot, ``package://`` contained, bounded trees, checked masses.

Every input is generated here. CLI runs go through a child process with a memory and time bound
(:mod:`bounded`); the symlink race runs in-process against a thread that swaps a folder for a link.
"""

from __future__ import annotations

import os
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import trimesh
from bounded import run_bounded

from meshtool.errors import MeshtoolError
from meshtool.packfile.read import parse
from meshtool.urdf.import_robot import UrdfOptions, import_urdf
from meshtool.urdf.locate import MeshLocator, UrdfError

INSIDE_SIZE, OUTSIDE_SIZE = 0.1, 7.0


def _stl(path: Path, size: float) -> bytes:
    """A cube of edge ``size`` metres as binary STL, written to ``path``; its bytes."""
    path.parent.mkdir(parents=True, exist_ok=True)
    data: bytes = trimesh.creation.box(extents=(size, size, size)).export(file_type="stl")
    path.write_bytes(data)
    return data


def _robot(folder: Path, ref: str, name: str = "r") -> Path:
    """``folder/urdf/NAME.urdf``: one link whose visual is the mesh ``ref``."""
    urdf = folder / "urdf" / f"{name}.urdf"
    urdf.parent.mkdir(parents=True, exist_ok=True)
    urdf.write_text(
        f'<robot name="{name}">\n<link name="base">\n'
        f'  <visual><geometry><mesh filename="{ref}"/></geometry></visual>\n'
        "</link>\n</robot>\n"
    )
    return urdf


def _extent(result: object, key: str) -> float:
    packed = parse(result.mbins[key], key)  # type: ignore[attr-defined]
    positions = np.asarray(packed.positions, dtype=float)
    return float((positions.max(axis=0) - positions.min(axis=0)).max())


# -- the symlink race -------------------------------------------------------------------------------------


_FLIP = """
import os, sys
meshes, real, link = sys.argv[1:4]
while True:
    os.rename(meshes, real)  # the real folder steps aside...
    os.rename(link, meshes)  # ...the link takes its name
    os.rename(meshes, link)
    os.rename(real, meshes)
"""


class _Flipper:
    """Swaps ``pkg/meshes`` between a real folder (inside) and a symbolic link to an outside folder.

    The swapping runs in a child process (not a thread: the GIL would let it run only between the reader's
    steps); leaving the context stops it and puts the real folder back.
    """

    def __init__(self, pkg: Path, outside: Path) -> None:
        self.meshes = pkg / "meshes"
        self.real, self.link = pkg / ".meshes_real", pkg / ".meshes_link"
        self.real.mkdir()
        self.link.symlink_to(outside, target_is_directory=True)
        os.rename(self.real, self.meshes)
        self.child: subprocess.Popen[bytes] | None = None

    def __enter__(self) -> _Flipper:
        names = [str(self.meshes), str(self.real), str(self.link)]
        self.child = subprocess.Popen([sys.executable, "-c", _FLIP, *names])
        return self

    def __exit__(self, *exc: object) -> None:
        assert self.child is not None
        self.child.kill()
        self.child.wait()
        if not self.meshes.is_dir() or self.meshes.is_symlink():  # stopped mid-swap: the real folder back
            if self.meshes.is_symlink():
                os.rename(self.meshes, self.link)
            os.rename(self.real, self.meshes)


@dataclass
class Race:
    """A robot whose ``meshes/`` folder flips (once entered) to a link to an outside folder holding a 7 m cube."""

    urdf: Path
    flipper: _Flipper
    inside: bytes
    outside: bytes


@pytest.fixture
def race(tmp_path: Path) -> Race:
    pkg = tmp_path / "pkg"
    outside = _stl(tmp_path / "outside" / "part.stl", OUTSIDE_SIZE)
    pkg.mkdir()
    urdf = _robot(pkg, "package://pkg/meshes/part.stl")
    flipper = _Flipper(pkg, tmp_path / "outside")
    return Race(urdf, flipper, _stl(pkg / "meshes" / "part.stl", INSIDE_SIZE), outside)


def test_mesh_reads_against_a_flipping_symlink_never_leave_the_robot(race: Race) -> None:
    """10,000 reads of the mesh while ``meshes/`` flips to a link out of the robot: 0 outside bytes."""
    locator = MeshLocator(race.urdf, {})
    where = {"path": str(race.urdf), "line": 3}
    pkg = race.urdf.parent.parent
    inside = outside = refused = 0
    with race.flipper:
        for _ in range(10_000):
            try:
                found = locator.read("package://pkg/meshes/part.stl", where)
            except UrdfError:
                refused += 1
                continue
            assert pkg in found.path.parents
            if found.data == race.outside:
                outside += 1
            else:
                assert found.data == race.inside
                inside += 1
    assert outside == 0
    assert inside > 0 and refused > 0, (inside, refused)  # the race really ran both ways


def test_whole_imports_against_a_flipping_symlink_never_import_the_outside_mesh(race: Race) -> None:
    """The whole import (read, normalise, hull, pack) 150 times during the flips: never the 7 m cube."""
    imported = 0
    with race.flipper:
        for _ in range(150):
            try:
                result = import_urdf(race.urdf)
            except MeshtoolError:
                continue  # a clean refusal: the mesh changed while it was read, or was not there
            imported += 1
            assert _extent(result, "meshes/part.mbin") == pytest.approx(INSIDE_SIZE, rel=1e-6)
    assert imported > 0


# -- package:// stays inside the robot ---------------------------------------------------------------------


def test_package_named_dotdot_is_refused(tmp_path: Path) -> None:
    """``package://../x.stl`` used to make the URDF's parent folder the package (issue 27)."""
    _stl(tmp_path / "secret.stl", OUTSIDE_SIZE)
    urdf = _robot(tmp_path / "robot", "package://../secret.stl")
    with pytest.raises(UrdfError, match=r"'\.\.' is not a package name") as info:
        import_urdf(urdf)
    assert info.value.line == 3


def test_dotdot_inside_a_package_path_is_refused(tmp_path: Path) -> None:
    _stl(tmp_path / "secret.stl", OUTSIDE_SIZE)
    _stl(tmp_path / "robot" / "meshes" / "part.stl", INSIDE_SIZE)
    urdf = _robot(tmp_path / "robot", "package://robot/meshes/../../secret.stl")
    with pytest.raises(UrdfError, match=r"climbs out of its package with '\.\.'") as info:
        import_urdf(urdf)
    assert info.value.line == 3


def test_a_package_beside_an_ancestor_needs_an_explicit_option(tmp_path: Path) -> None:
    """``package://NAME`` is no longer looked for beside every folder above the robot (issue 27)."""
    _stl(tmp_path / "elsewhere" / "meshes" / "part.stl", OUTSIDE_SIZE)
    urdf = _robot(tmp_path / "deep" / "tree" / "robot", "package://elsewhere/meshes/part.stl")
    with pytest.raises(UrdfError, match="not the robot's own package") as info:
        import_urdf(urdf)
    assert info.value.hint is not None and "--package-dir elsewhere=FOLDER" in info.value.hint
    assert "--package-search" in info.value.hint
    searched = import_urdf(urdf, UrdfOptions(package_search=True))
    assert _extent(searched, "meshes/part.mbin") == pytest.approx(OUTSIDE_SIZE)
    mapped = import_urdf(urdf, UrdfOptions(package_dirs=(("elsewhere", tmp_path / "elsewhere"),)))
    assert _extent(mapped, "meshes/part.mbin") == pytest.approx(OUTSIDE_SIZE)


def test_an_ancestor_of_that_name_above_the_package_is_not_the_robot(tmp_path: Path) -> None:
    """A URDF under ``/.../home/...`` cannot read ``package://home/...``: only its own package answers."""
    _stl(tmp_path / "home" / "victim" / "part.stl", OUTSIDE_SIZE)
    urdf = _robot(tmp_path / "home" / "attacker" / "robot", "package://home/victim/part.stl")
    with pytest.raises(UrdfError, match="not the robot's own package"):
        import_urdf(urdf)


def test_the_package_xml_name_and_the_folder_name_both_answer(tmp_path: Path) -> None:
    pkg = tmp_path / "robot_description-main"
    _stl(pkg / "meshes" / "part.stl", INSIDE_SIZE)
    (pkg / "package.xml").write_text("<package>\n  <name> robot_description </name>\n</package>\n")
    for name in ("robot_description", "robot_description-main"):
        result = import_urdf(_robot(pkg, f"package://{name}/meshes/part.stl"))
        assert _extent(result, "meshes/part.mbin") == pytest.approx(INSIDE_SIZE)


def test_empty_package_name_maps_with_package_dir(tmp_path: Path) -> None:
    """``package:///...`` is the robot's own package, or the folder ``--package-dir =DIR`` names (issue 29)."""
    _stl(tmp_path / "robot" / "meshes" / "part.stl", INSIDE_SIZE)
    _stl(tmp_path / "assets" / "meshes" / "part.stl", OUTSIDE_SIZE)
    urdf = _robot(tmp_path / "robot", "package:///meshes/part.stl")
    assert _extent(import_urdf(urdf), "meshes/part.mbin") == pytest.approx(INSIDE_SIZE)
    mapped = import_urdf(urdf, UrdfOptions(package_dirs=(("", tmp_path / "assets"),)))
    assert _extent(mapped, "meshes/part.mbin") == pytest.approx(OUTSIDE_SIZE)
    out = run_bounded(
        ["meshtool", "urdf", str(urdf), "-o", str(tmp_path / "out"), "--package-dir", f"={tmp_path / 'assets'}"]
    )
    assert out.code == 0, out.err


def test_a_symlinked_mesh_leading_out_is_refused_by_the_cli(tmp_path: Path) -> None:
    _stl(tmp_path / "secret" / "part.stl", OUTSIDE_SIZE)
    (tmp_path / "robot" / "meshes").mkdir(parents=True)
    (tmp_path / "robot" / "meshes" / "part.stl").symlink_to(tmp_path / "secret" / "part.stl")
    urdf = _robot(tmp_path / "robot", "package://robot/meshes/part.stl")
    out = run_bounded(["meshtool", "urdf", str(urdf), "-o", str(tmp_path / "out")])
    assert out.code == 1 and "Traceback" not in out.err
    assert out.err.startswith(f"error: {urdf}:3: mesh 'package://robot/meshes/part.stl' is outside the robot's folder")
    assert not (tmp_path / "out").exists()


# -- trees, masses ----------------------------------------------------------------------------------------


def _chain(path: Path, n: int, mass: str = "1") -> Path:
    inertia = '<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/>'
    lines = ['<robot name="chain">']
    lines += [f'<link name="l{i}"><inertial><mass value="{mass}"/>{inertia}</inertial></link>' for i in range(n)]
    lines += [
        f'<joint name="j{i}" type="revolute"><parent link="l{i}"/><child link="l{i + 1}"/>'
        '<origin xyz="0 0 0.01"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>'
        for i in range(n - 1)
    ]
    path.write_text("\n".join([*lines, "</robot>", ""]))
    return path


def test_a_1000_link_chain_is_refused_without_recursion(tmp_path: Path) -> None:
    """A 1,000-link chain raised RecursionError (exit 3); MuJoCo's XML reader cannot nest it anyway."""
    urdf = _chain(tmp_path / "chain.urdf", 1000)
    out = run_bounded(["meshtool", "urdf", str(urdf), "-o", str(tmp_path / "out")], seconds=120, memory_mb=2000)
    assert out.code == 1, out.err
    assert out.err == (
        f"error: {urdf}:482: link 'l480' is 481 links deep; MuJoCo's XML reader nests bodies at most 480 deep "
        "(shorten the chain: merge links joined by fixed joints)\n"
    )


def test_a_chain_at_the_depth_limit_loads_in_mujoco(tmp_path: Path) -> None:
    """480 nested bodies: written, and MuJoCo loads the folder with every body (its own count, not ours)."""
    import mujoco

    urdf = _chain(tmp_path / "chain.urdf", 480)
    out = run_bounded(["meshtool", "urdf", str(urdf), "-o", str(tmp_path / "out")], seconds=300, memory_mb=3000)
    assert out.code == 0, out.err
    model = mujoco.MjModel.from_xml_path(str(tmp_path / "out" / "chain.xml"))
    assert (model.nbody, model.njnt) == (481, 479)
    assert model.body_parentid[480] == 479


@pytest.mark.parametrize(
    ("mass", "shown"), [("nan", "nan"), ("-5", "-5.0"), ("inf", "inf")], ids=["nan", "negative", "infinite"]
)
def test_a_mass_that_is_not_physical_is_an_error_at_its_link(tmp_path: Path, mass: str, shown: str) -> None:
    urdf = _chain(tmp_path / "m.urdf", 3)
    text = urdf.read_text().replace(
        '<link name="l1"><inertial><mass value="1"/>', f'<link name="l1"><inertial><mass value="{mass}"/>'
    )
    urdf.write_text(text)
    out = run_bounded(["meshtool", "urdf", str(urdf), "-o", str(tmp_path / "out")])
    assert out.code == 1
    assert out.err == (
        f"error: {urdf}:3: link 'l1' has mass {shown}; a mass must be a finite number >= 0 (kilograms) "
        "(fix the <mass value=...> of the link)\n"
    )


def test_a_non_finite_inertia_is_an_error_at_its_link(tmp_path: Path) -> None:
    urdf = _chain(tmp_path / "m.urdf", 3)
    urdf.write_text(urdf.read_text().replace('ixx="0.01"', 'ixx="nan"', 2))
    with pytest.raises(UrdfError, match="link 'l0' has an inertia or inertial origin that is not finite") as info:
        import_urdf(urdf)
    assert info.value.line == 2


def test_a_link_with_two_parents_is_an_error(tmp_path: Path) -> None:
    urdf = _chain(tmp_path / "c.urdf", 4)
    text = urdf.read_text().replace(
        "</robot>",
        '<joint name="again" type="fixed"><parent link="l0"/><child link="l2"/></joint>\n</robot>',
    )
    urdf.write_text(text)
    with pytest.raises(UrdfError, match=r"link 'l2' is the child of two joints \('j1' and 'again'\)") as info:
        import_urdf(urdf)
    assert info.value.line == 9


def test_a_cycle_cut_off_from_the_root_is_an_error(tmp_path: Path) -> None:
    """Two links that are each other's parent: both are children, so the root alone is not enough to see it."""
    urdf = tmp_path / "cycle.urdf"
    urdf.write_text(
        '<robot name="c">\n<link name="root"/>\n<link name="a"/>\n<link name="b"/>\n'
        '<joint name="ab" type="fixed"><parent link="a"/><child link="b"/></joint>\n'
        '<joint name="ba" type="fixed"><parent link="b"/><child link="a"/></joint>\n</robot>\n'
    )
    with pytest.raises(UrdfError, match="is not connected to the root link 'root'") as info:
        import_urdf(urdf)
    assert info.value.line == 3


# -- one frame for glTF, whatever the path (issue 26) -----------------------------------------------------


def test_gltf_visuals_land_on_their_collision_shapes(tmp_path: Path) -> None:
    """A glTF visual modelled Y-up (glTF 2.0, section 3.4) sits on the URDF's Z-up collision box.

    Ground truth: MuJoCo's own compiled geoms (world-space boxes after ``mj_forward``), and ``obj2bin`` on the
    same file giving the same vertices as the URDF's pack.
    """
    import mujoco

    pkg = tmp_path / "gltf_robot"
    box = trimesh.creation.box(extents=(0.1, 0.4, 0.06))  # tall along +Y: Y-up, standing on the ground
    box.apply_translation((0.05, 0.2, 0.0))
    (pkg / "meshes").mkdir(parents=True)
    (pkg / "meshes" / "post.glb").write_bytes(box.export(file_type="glb"))
    urdf = pkg / "urdf" / "r.urdf"
    urdf.parent.mkdir()
    urdf.write_text(
        '<robot name="r"><link name="base">\n'
        '<visual><geometry><mesh filename="package://gltf_robot/meshes/post.glb"/></geometry></visual>\n'
        '<collision><origin xyz="0.05 0 0.2"/><geometry><box size="0.1 0.06 0.4"/></geometry></collision>\n'
        '<inertial><mass value="1"/><inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial>\n'
        "</link></robot>\n"
    )
    out = run_bounded(["meshtool", "urdf", str(urdf), "-o", str(tmp_path / "out")])
    assert out.code == 0, out.err
    model = mujoco.MjModel.from_xml_path(str(tmp_path / "out" / "r.xml"))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)

    def world_box(g: int) -> tuple[np.ndarray, np.ndarray]:
        centre, half = model.geom_aabb[g, :3], model.geom_aabb[g, 3:]
        rot = data.geom_xmat[g].reshape(3, 3)
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half + centre
        world = corners @ rot.T + data.geom_xpos[g]
        return world.min(axis=0), world.max(axis=0)

    boxes = {int(model.geom_type[g]): world_box(g) for g in range(model.ngeom) if model.geom_group[g] in (2, 3)}
    visual = boxes[int(mujoco.mjtGeom.mjGEOM_MESH)]
    collision = boxes[int(mujoco.mjtGeom.mjGEOM_BOX)]
    np.testing.assert_allclose(visual[0], collision[0], atol=1e-6)
    np.testing.assert_allclose(visual[1], collision[1], atol=1e-6)

    single = run_bounded(["obj2bin", str(pkg / "meshes" / "post.glb"), "-o", str(tmp_path / "post.mbin")])
    assert single.code == 0, single.err
    from_urdf = parse((tmp_path / "out" / "meshes" / "post.mbin").read_bytes(), "post.mbin")
    alone = parse((tmp_path / "post.mbin").read_bytes(), "post.mbin")
    np.testing.assert_array_equal(
        np.unique(np.asarray(from_urdf.positions), axis=0), np.unique(np.asarray(alone.positions), axis=0)
    )


# -- the fuzzer's URDF crashes (make fuzz, target urdf) ---------------------------------------------------


@pytest.mark.parametrize("entry", ["ixy", "ixz"])
def test_an_inertia_near_the_float_limit_is_an_error_not_a_crash(tmp_path: Path, entry: str) -> None:
    """``ixy="1e308"`` made numpy's eigh raise LinAlgError (exit 3)."""
    urdf = _chain(tmp_path / "m.urdf", 3)
    urdf.write_text(urdf.read_text().replace(f'{entry}="0"', f'{entry}="1e308"', 1))
    out = run_bounded(["meshtool", "urdf", str(urdf), "-o", str(tmp_path / "out")])
    assert out.code == 1 and "Traceback" not in out.err
    assert out.err.startswith(f"error: {urdf}:2: link 'l0' has an inertia whose principal moments cannot be computed")


def test_a_robot_name_too_long_for_a_file_name_is_an_error(tmp_path: Path) -> None:
    """A 300-character robot name made the MJCF check fail with OSError 'File name too long' (exit 3)."""
    urdf = tmp_path / "long.urdf"
    urdf.write_text(f'<?xml version="1.0"?>\n<robot name="{"x" * 300}">\n<link name="base"/>\n</robot>\n')
    out = run_bounded(["meshtool", "urdf", str(urdf), "-o", str(tmp_path / "out")])
    assert out.code == 1
    assert out.err == (
        f"error: {urdf}:2: robot name is 300 bytes long; at most 200 (it names the MJCF file) "
        "(shorten the <robot name=...>)\n"
    )


def _one_shape(path: Path, geometry: str, origin: str = "", joint_origin: str = "") -> Path:
    path.write_text(
        '<robot name="r">\n<link name="a"/>\n<link name="b">\n'
        f"<collision>{origin}<geometry>{geometry}</geometry></collision>\n"
        '<inertial><mass value="1"/><inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial></link>\n'
        f'<joint name="j" type="revolute">{joint_origin}<parent link="a"/><child link="b"/><axis xyz="0 0 1"/>'
        '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint>\n</robot>\n'
    )
    return path


@pytest.mark.parametrize(
    ("geometry", "message"),
    [
        ('<box size="1 2 3 4"/>', "<box size> of a collision of link 'b' is '1.0 2.0 3.0 4.0'; 3 finite number(s)"),
        ('<box size="1 nan 1"/>', "<box size> of a collision of link 'b' is '1.0 nan 1.0'; 3 finite number(s)"),
        ('<sphere radius="0"/>', "<sphere radius> of a collision of link 'b' is '0.0'; 1 finite number(s) > 0"),
        ('<cylinder radius="1" length="-2"/>', "radius and length is '1.0 -2.0'; 2 finite number(s) > 0"),
    ],
    ids=["box-4-values", "box-nan", "sphere-zero", "cylinder-negative"],
)
def test_a_primitive_shape_with_bad_sizes_is_an_error_at_its_link(tmp_path: Path, geometry: str, message: str) -> None:
    """MuJoCo refused these without naming the element (``size 0 must be positive in geom``); a 4-value box
    raised TypeError from MjSpec (exit 3, found by the fuzzer)."""
    urdf = _one_shape(tmp_path / "r.urdf", geometry)
    with pytest.raises(UrdfError) as info:
        import_urdf(urdf)
    assert message in info.value.message and info.value.line == 3


@pytest.mark.parametrize(
    ("origin", "joint_origin", "line", "what"),
    [
        ('<origin xyz="nan 0 0"/>', "", 3, "the origin of a collision of link 'b'"),
        ('<origin rpy="0 inf 0"/>', "", 3, "the origin of a collision of link 'b'"),
        ("", '<origin xyz="0 0 nan"/>', 6, "the origin of joint 'j'"),
    ],
    ids=["visual-xyz-nan", "visual-rpy-inf", "joint-xyz-nan"],
)
def test_a_non_finite_origin_is_an_error_not_a_crash(
    tmp_path: Path, origin: str, joint_origin: str, line: int, what: str
) -> None:
    """A NaN origin made trimesh's quaternion_from_matrix raise LinAlgError (exit 3, found by the fuzzer)."""
    urdf = _one_shape(tmp_path / "r.urdf", '<box size="1 1 1"/>', origin, joint_origin)
    out = run_bounded(["meshtool", "urdf", str(urdf), "-o", str(tmp_path / "out")])
    assert out.code == 1
    assert out.err == f"error: {urdf}:{line}: {what} is not finite (fix the xyz and rpy of the <origin>)\n"
