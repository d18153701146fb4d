"""URDFs that MuJoCo's own importer loads and meshtool refused (issue 29), and messages for broken ones.

Ground truth: ``mujoco.MjModel.from_xml_path`` on the same URDF (MuJoCo's URDF importer), compared with the
model meshtool writes; and the URDF elements' own lines.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

from meshtool.urdf.import_robot import UrdfOptions, import_urdf
from meshtool.urdf.locate import UrdfError
from meshtool.urdf.write import write_import

INERTIAL = '<inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>'
HINGE = '<axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/>'


def _write(tmp_path: Path, body: str) -> Path:
    urdf = tmp_path / "r.urdf"
    urdf.write_text(f'<robot name="r">\n<link name="base"/>\n{body}</robot>\n')
    return urdf


def _ours(urdf: Path, tmp_path: Path) -> tuple[mujoco.MjModel, list[str]]:
    result = import_urdf(urdf, UrdfOptions())
    write_import(result, tmp_path / "out")
    return mujoco.MjModel.from_xml_path(str(tmp_path / "out" / "r.xml")), [f.code for f in result.findings]


def test_a_mimic_on_a_fixed_joint_is_ignored_with_a_warning_naming_that_joint(tmp_path: Path) -> None:
    """talos_*: exporters leave <mimic> on fixed joints; MuJoCo loads the robot, meshtool blamed the wrong joint."""
    urdf = _write(
        tmp_path,
        f'<link name="l1">{INERTIAL}</link>\n<link name="l2">{INERTIAL}</link>\n'
        f'<joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>{HINGE}</joint>\n'
        '<joint name="j2" type="fixed"><parent link="l1"/><child link="l2"/><mimic joint="j1"/></joint>\n',
    )
    result = import_urdf(urdf)
    (finding,) = [f for f in result.findings if f.code == "urdf-mimic-ignored"]
    assert finding.line == 6 and "joint 'j2' is 'fixed', not a moving joint" in finding.message
    ours, _ = _ours(urdf, tmp_path)
    theirs = mujoco.MjModel.from_xml_path(str(urdf))
    assert (ours.njnt, ours.neq) == (theirs.njnt, theirs.neq) == (1, 0)
    assert ours.body_mass.sum() == pytest.approx(theirs.body_mass.sum())


def test_a_mimic_naming_a_missing_joint_is_ignored(tmp_path: Path) -> None:
    """alex_psyonic_hands: MuJoCo warns and loads; meshtool refused."""
    urdf = _write(
        tmp_path,
        f'<link name="l1">{INERTIAL}</link>\n'
        f'<joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>{HINGE}<mimic joint="ghost"/>'
        "</joint>\n",
    )
    result = import_urdf(urdf)
    (finding,) = [f for f in result.findings if f.code == "urdf-mimic-ignored"]
    assert finding.line == 4 and "it names joint 'ghost', which does not exist" in finding.message
    ours, _ = _ours(urdf, tmp_path)
    assert (ours.njnt, ours.neq) == (1, 0) == (mujoco.MjModel.from_xml_path(str(urdf)).njnt, 0)


@pytest.mark.parametrize(
    ("geometry", "volume"),
    [
        ('<box size="0.1 0.2 0.3"/>', 0.1 * 0.2 * 0.3),
        ('<cylinder radius="0.05" length="0.4"/>', np.pi * 0.05**2 * 0.4),
        ('<sphere radius="0.07"/>', 4 / 3 * np.pi * 0.07**3),
    ],
    ids=["box", "cylinder", "sphere"],
)
def test_a_moving_link_without_inertial_gets_mass_from_its_collision_geometry(
    tmp_path: Path, geometry: str, volume: float
) -> None:
    """bravo7_gripper, fanuc: MuJoCo infers mass from the geometry (1000 kg/m^3); meshtool refused."""
    urdf = _write(
        tmp_path,
        f'<link name="l1"><collision><geometry>{geometry}</geometry></collision></link>\n'
        f'<joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>{HINGE}</joint>\n',
    )
    ours, codes = _ours(urdf, tmp_path)
    theirs = mujoco.MjModel.from_xml_path(str(urdf))
    assert "urdf-mass-from-geometry" in codes
    assert ours.body_mass[-1] == pytest.approx(1000 * volume, rel=1e-6)  # analytic
    assert ours.body_mass[-1] == pytest.approx(theirs.body_mass[-1], rel=1e-6)  # MuJoCo's own import
    np.testing.assert_allclose(ours.body_inertia[-1], theirs.body_inertia[-1], rtol=1e-6)


@pytest.mark.parametrize(
    ("text", "line", "message"),
    [
        ("<robot>\n</robot>\n", 1, "<robot> has no 'name' attribute, which URDF requires"),
        ('<robot name="r">\n<link/>\n</robot>\n', 2, "<link> has no 'name' attribute"),
        (
            '<robot name="r">\n<link name="a"/>\n<joint name="j" type="fixed"><parent link="a"/>'
            '<child link="nothere"/></joint>\n</robot>\n',
            3,
            "joint 'j' names unknown link 'nothere' as its child",
        ),
    ],
    ids=["empty-robot", "nameless-link", "missing-child-link"],
)
def test_broken_urdfs_name_the_element_and_its_line(tmp_path: Path, text: str, line: int, message: str) -> None:
    """An empty <robot> said `not a valid URDF: 'name'` (a leaked KeyError) with no line."""
    urdf = tmp_path / "r.urdf"
    urdf.write_text(text)
    with pytest.raises(UrdfError) as info:
        import_urdf(urdf)
    assert info.value.line == line and message in info.value.message


# -- the fuzzer's second round (make fuzz, target urdf, 10 minutes) -----------------------------------------


@pytest.mark.parametrize(
    ("joint_extra", "message"),
    [
        ('<dynamics damping="-inf"/>', "joint 'j1': <dynamics damping> is -inf; it must be a finite number >= 0"),
        ('<dynamics friction="-1"/>', "joint 'j1': <dynamics friction> is -1; it must be a finite number >= 0"),
        ('<axis xyz="0 1"/>', "joint 'j1' has axis '0 1'; an axis is 3 finite numbers, not all zero"),
    ],
    ids=["damping-minus-inf", "negative-friction", "two-value-axis"],
)
def test_joint_values_that_are_not_physical_are_errors_at_the_joint(
    tmp_path: Path, joint_extra: str, message: str
) -> None:
    """``damping="-inf"`` was written into the MJCF (exit 0); a 2-value axis raised IndexError (exit 3)."""
    hinge = HINGE if "<axis" not in joint_extra else '<limit lower="-1" upper="1" effort="1" velocity="1"/>'
    urdf = _write(
        tmp_path,
        f'<link name="l1">{INERTIAL}</link>\n'
        f'<joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>{hinge}{joint_extra}</joint>\n',
    )
    with pytest.raises(UrdfError) as info:
        import_urdf(urdf)
    assert info.value.line == 4 and message in info.value.message


def test_a_colour_of_three_values_is_an_error_naming_the_material(tmp_path: Path) -> None:
    """``rgba="1 0 0"`` raised ValueError while unpacking (exit 3)."""
    urdf = _write(
        tmp_path,
        '<material name="red"><color rgba="1 0 0"/></material>\n'
        '<link name="l1"><visual><geometry><box size="1 1 1"/></geometry><material name="red"/></visual></link>\n'
        '<joint name="j" type="fixed"><parent link="base"/><child link="l1"/></joint>\n',
    )
    with pytest.raises(UrdfError, match="material 'red' has rgba '1 0 0'; a colour is 4 finite numbers") as info:
        import_urdf(urdf)
    assert info.value.line == 3


@pytest.mark.parametrize("kind", ["link", "joint"])
def test_a_name_defined_twice_is_an_error(tmp_path: Path, kind: str) -> None:
    """Two joints named 'shoulder' made MjSpec raise ValueError (exit 3); two links silently lost one."""
    body = (
        f'<link name="l1">{INERTIAL}</link>\n<link name="l2">{INERTIAL}</link>\n'
        f'<joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>{HINGE}</joint>\n'
        f'<joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>{HINGE}</joint>\n'
    )
    body = body.replace('name="j2"', 'name="j1"') if kind == "joint" else body.replace('name="l2"', 'name="l1"')
    urdf = _write(tmp_path, body)
    with pytest.raises(UrdfError, match=f"{kind} 'l1' is defined twice|{kind} 'j1' is defined twice"):
        import_urdf(urdf)


def test_a_consumer_urdf_with_an_unknown_encoding_is_not_evidence(tmp_path: Path) -> None:
    """``encoding='utf0'`` in a URDF beside a mesh raised LookupError from normalize's consumer search (exit 3)."""
    from meshtool.repair.normalise import NormaliseOptions, prepare

    (tmp_path / "meshes").mkdir()
    mesh = tmp_path / "meshes" / "m.obj"
    mesh.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 4\n")
    (tmp_path / "r.urdf").write_text(
        "<?xml version='1.0' encoding='utf0'?>\n<robot name=\"r\"><link name=\"a\"><visual><geometry>"
        '<mesh filename="meshes/m.obj" scale="0.001 0.001 0.001"/></geometry></visual></link></robot>\n'
    )
    asset = prepare(mesh, NormaliseOptions())
    assert asset.mesh.positions.shape[0] == 4


def test_a_limit_that_is_not_a_number_is_an_error_at_the_joint(tmp_path: Path) -> None:
    """``damping="x"`` raised ValueError from float() (exit 3; the fuzzer's second urdf run)."""
    urdf = _write(
        tmp_path,
        f'<link name="l1">{INERTIAL}</link>\n'
        '<joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 0 1"/>'
        '<limit lower="-1" upper="1" effort="1" velocity="1"/><dynamics damping="x"/></joint>\n',
    )
    with pytest.raises(UrdfError, match="joint 'j1': <dynamics damping> is 'x', not a number") as info:
        import_urdf(urdf)
    assert info.value.line == 4
