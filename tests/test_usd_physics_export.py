"""USD export keeps the motors, contact exclusions and couplings, or says what it dropped.

Ground truth: the compiled MuJoCo model's actuators (``actuator_*``), exclusions (``exclude_signature``) and
equalities, against the written file read back by usd-core (``pxr``) with the UsdPhysics schemas.
"""

import math
from pathlib import Path

import pytest

from simrun import load_scene
from simrun.export.usd import export_world_usd

pxr = pytest.importorskip("pxr")
SCENES = Path(__file__).resolve().parent.parent / "fixtures" / "scenes"


def test_arm_on_base_keeps_every_actuator_as_a_drive_every_exclusion_and_lists_the_coupling(tmp_path):
    from pxr import Usd, UsdPhysics

    world = load_scene(SCENES / "arm_on_base.toml")
    model = world.model
    out = tmp_path / "arm.usda"
    findings = export_world_usd(world, out)
    stage = Usd.Stage.Open(str(out))
    drives = {}
    pairs = set()
    names = {p.GetPath().pathString: p.GetAttribute("simrun:name").Get() for p in stage.Traverse()}
    for prim in stage.Traverse():
        for kind in ("angular", "linear"):
            if prim.HasAPI(UsdPhysics.DriveAPI, kind):
                drives[prim.GetAttribute("simrun:actuator").Get()] = (kind, UsdPhysics.DriveAPI(prim, kind))
        if prim.HasAPI(UsdPhysics.FilteredPairsAPI):
            for target in UsdPhysics.FilteredPairsAPI(prim).GetFilteredPairsRel().GetTargets():
                pairs.add(frozenset((names[prim.GetPath().pathString], names[target.pathString])))
    assert len(drives) == model.nu == 8  # 6 arm servos + 2 wheel motors
    for a in range(model.nu):
        kind, drive = drives[model.actuator(a).name]
        per = math.pi / 180 if kind == "angular" else 1.0
        assert drive.GetStiffnessAttr().Get() == pytest.approx(-model.actuator_biasprm[a][1] * per)
        assert drive.GetDampingAttr().Get() == pytest.approx(-model.actuator_biasprm[a][2] * per)
        assert drive.GetMaxForceAttr().Get() == pytest.approx(max(abs(model.actuator_forcerange[a])))
    expected = {frozenset((model.body(s >> 16).name, model.body(s & 0xFFFF).name)) for s in model.exclude_signature}
    assert pairs == expected and len(expected) == model.nexclude == 14
    assert model.neq == 1 and len(findings) == 1 and "finger_right" in findings[0] and "finger_left" in findings[0]
    assert list(stage.GetRootLayer().customLayerData["simrun:unmapped"]) == findings
