"""Recordings as animated glTF and USD: read back with pygltflib and pxr, compared with a fresh simulation.

Ground truth: the demo run (fixtures/scenes/boebot.toml driving square.commands.toml, as ``make demo``)
simulated again without a recorder, each body's pose from its ``qpos`` through ``mj_kinematics`` in a
separate ``MjData``, at five times. The exports come from the ``.simlog`` of the same run.
"""

from __future__ import annotations

import io
import json
import math
import shutil
import subprocess
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import pygltflib
import pytest
from click.testing import CliRunner
from PIL import Image

from meshtool.packfile.export import Z_UP_TO_Y_UP
from simrun.cli.main import main
from simrun.record.replay_export import export_recording
from simrun.run.play import load_commands, play
from simrun.scene.scene_file import load_scene

ROOT = Path(__file__).resolve().parent.parent
SCENES = ROOT / "fixtures" / "scenes"
DEMO, COMMANDS = SCENES / "boebot.toml", SCENES / "square.commands.toml"
DURATION = 40.0  # the Makefile's demo run
TIMES = (0.6, 4.0, 12.34, 25.0, 39.5)  # turning, driving, driving, turning, driving back
VALIDATOR = ROOT / "tools" / "gltf-validator" / "node_modules" / "gltf-validator"


def _record(scene: Path, folder: Path, duration: float, commands: Path | None = None) -> Path:
    log = folder / f"{scene.stem}.simlog"
    args = ["play", str(scene), "--duration", str(duration), "--record", str(log)]
    if commands is not None:
        args += ["--commands", str(commands)]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 0, result.output
    return log


@pytest.fixture(scope="module")
def demo(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _record(DEMO, tmp_path_factory.mktemp("demo"), DURATION, COMMANDS)


@pytest.fixture(scope="module")
def truth() -> dict[float, tuple[dict[str, np.ndarray], dict[str, np.ndarray]]]:
    """Body name -> world position and quaternion (w x y z) at each of TIMES, from a new simulation."""
    world = load_scene(DEMO)
    world.check_bindings()
    model = world.model
    scratch = mujoco.MjData(model)
    poses: dict[float, tuple[dict[str, np.ndarray], dict[str, np.ndarray]]] = {}

    def sink(data: Any) -> None:
        t = round(float(data.time), 9)
        if any(abs(t - s) < 1e-6 for s in TIMES):
            scratch.qpos[:] = data.qpos
            mujoco.mj_kinematics(model, scratch)
            names = [model.body(b).name for b in range(model.nbody)]
            poses[min(TIMES, key=lambda s: abs(s - t))] = (
                {n: scratch.xpos[b].copy() for b, n in enumerate(names)},
                {n: scratch.xquat[b].copy() for b, n in enumerate(names)},
            )

    play(world, DURATION, load_commands(COMMANDS), sink, fps=50.0)
    assert sorted(poses) == sorted(TIMES)
    return poses


def _gltf(data: bytes) -> tuple[pygltflib.GLTF2, bytes]:
    gltf = pygltflib.GLTF2.load_from_bytes(data)
    return gltf, gltf.binary_blob()


def _read(gltf: pygltflib.GLTF2, blob: bytes, index: int) -> np.ndarray:
    accessor = gltf.accessors[index]
    view = gltf.bufferViews[accessor.bufferView]
    width = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}[accessor.type]
    dtype = {5126: np.float32, 5123: np.uint16, 5125: np.uint32}[accessor.componentType]
    start = view.byteOffset + (accessor.byteOffset or 0)
    values = np.frombuffer(blob, dtype=dtype, count=accessor.count * width, offset=start)
    return values.reshape(accessor.count, width) if width > 1 else values


def _sample(times: np.ndarray, values: np.ndarray, t: float, rotation: bool) -> np.ndarray:
    """glTF LINEAR sampling: lerp, or slerp the shorter way for rotations (x y z w)."""
    k = int(np.clip(np.searchsorted(times, t, side="right") - 1, 0, len(times) - 2))
    s = float(np.clip((t - times[k]) / (times[k + 1] - times[k]), 0.0, 1.0))
    a, b = values[k].astype(np.float64), values[k + 1].astype(np.float64)
    if not rotation:
        return a + s * (b - a)
    if np.dot(a, b) < 0:
        b = -b
    theta = math.acos(min(1.0, float(np.dot(a, b))))
    if theta < 1e-12:
        return a
    out = (math.sin((1 - s) * theta) * a + math.sin(s * theta) * b) / math.sin(theta)
    return out / np.linalg.norm(out)


def _animated(gltf: pygltflib.GLTF2, blob: bytes) -> dict[str, dict[str, tuple[np.ndarray, np.ndarray]]]:
    """Node name -> path -> (key times, values)."""
    (animation,) = gltf.animations
    out: dict[str, dict[str, tuple[np.ndarray, np.ndarray]]] = {}
    for channel in animation.channels:
        sampler = animation.samplers[channel.sampler]
        assert sampler.interpolation == "LINEAR"
        name = gltf.nodes[channel.target.node].name
        out.setdefault(name, {})[channel.target.path] = (
            _read(gltf, blob, sampler.input),
            _read(gltf, blob, sampler.output),
        )
    return out


def _angle(q: np.ndarray, r: np.ndarray) -> float:
    """The rotation angle between two quaternions (normalised; either sign), well conditioned near 0."""
    q, r = q / np.linalg.norm(q), r / np.linalg.norm(r)
    if np.dot(q, r) < 0:
        r = -r
    return 4 * math.atan2(float(np.linalg.norm(q - r)), float(np.linalg.norm(q + r)))


def _validate(path: Path) -> dict[str, Any]:
    node = shutil.which("node")
    if node is None:
        pytest.skip("node is not installed (the Khronos glTF validator runs on Node.js)")
    if not VALIDATOR.is_dir():
        pytest.skip("gltf-validator is not installed: run scripts/install_gltf_validator.sh")
    run = subprocess.run([node, str(ROOT / "scripts" / "gltf_validate.cjs"), str(path)], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    issues: dict[str, Any] = json.loads(run.stdout)["issues"]
    return issues


def test_demo_glb_poses_equal_the_simulation_at_five_times(demo: Path, truth: Any, tmp_path: Path) -> None:
    out = tmp_path / "demo.glb"
    result = CliRunner().invoke(main, ["replay", str(demo), "--glb", str(out)])
    assert result.exit_code == 0, result.output
    gltf, blob = _gltf(out.read_bytes())
    (root,) = gltf.scenes[gltf.scene].nodes
    assert gltf.nodes[root].name == "simrun_world"
    x, y, z, w = gltf.nodes[root].rotation
    turn = np.zeros(9)
    mujoco.mju_quat2Mat(turn, np.array([w, x, y, z]))
    np.testing.assert_allclose(turn.reshape(3, 3), Z_UP_TO_Y_UP[:3, :3], atol=1e-12)  # Z-up world shown Y-up
    animated = _animated(gltf, blob)
    assert set(animated) >= {"boebot", "boebot/left_wheel", "boebot/right_wheel"}
    assert "ground" not in animated  # static bodies have no channel
    positions, quats = truth[TIMES[0]]
    assert np.linalg.norm(truth[TIMES[2]][0]["boebot"] - positions["boebot"]) > 0.2  # the robot did move
    for t in TIMES:
        positions, quats = truth[t]
        for name, channels in animated.items():
            p = _sample(*channels["translation"], t, rotation=False)
            qx, qy, qz, qw = _sample(*channels["rotation"], t, rotation=True)
            assert np.linalg.norm(p - positions[name]) < 1e-5, (name, t)
            assert _angle(np.array([qw, qx, qy, qz]), quats[name]) < 1e-5, (name, t)
    issues = _validate(out)
    assert (issues["numErrors"], issues["numWarnings"], issues["numInfos"], issues["numHints"]) == (0, 0, 0, 0), issues


def test_decimated_animation_stays_within_the_bound_at_every_frame(demo: Path, tmp_path: Path) -> None:
    full, thin = tmp_path / "full.glb", tmp_path / "thin.glb"
    export_recording(demo, {"glb": full})
    export_recording(demo, {"glb": thin}, fps=5.0, tolerance=1e-3)
    every = _animated(*_gltf(full.read_bytes()))
    fewer = _animated(*_gltf(thin.read_bytes()))
    assert set(every) == set(fewer)
    assert len(fewer["boebot"]["translation"][0]) < len(every["boebot"]["translation"][0]) / 2
    assert thin.stat().st_size < full.stat().st_size
    for name, channels in every.items():
        times, positions = channels["translation"]
        _, rotations = channels["rotation"]
        for k in range(len(times)):
            p = _sample(*fewer[name]["translation"], float(times[k]), rotation=False)
            q = _sample(*fewer[name]["rotation"], float(times[k]), rotation=True)
            assert np.linalg.norm(p - positions[k]) <= 1e-3 + 1e-6, (name, times[k])
            assert _angle(q[[3, 0, 1, 2]], rotations[k][[3, 0, 1, 2]].astype(np.float64)) <= 1e-3 + 1e-5
    _validate(thin)


def test_textures_and_meshes_of_a_textured_scene(tmp_path: Path) -> None:
    log = _record(SCENES / "basic.toml", tmp_path, 1.0)
    out = tmp_path / "basic.glb"
    export_recording(log, {"glb": out})
    gltf, blob = _gltf(out.read_bytes())
    nodes = {n.name: n for n in gltf.nodes}
    globe = gltf.meshes[nodes["globe/geom"].mesh].primitives[0]
    assert globe.attributes.TEXCOORD_0 is not None and globe.attributes.NORMAL is not None
    material = gltf.materials[globe.material]
    image = gltf.images[gltf.textures[material.pbrMetallicRoughness.baseColorTexture.index].source]
    view = gltf.bufferViews[image.bufferView]
    embedded = Image.open(io.BytesIO(blob[view.byteOffset : view.byteOffset + view.byteLength])).convert("RGB")
    source = Image.open(SCENES / "globe.png").convert("RGB")
    assert np.array_equal(np.asarray(embedded), np.asarray(source))  # MuJoCo's pixels, rows as in the PNG
    normals = _read(gltf, blob, globe.attributes.NORMAL)
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-6)
    ground = gltf.meshes[nodes["ground/plane"].mesh].primitives[0]
    assert gltf.materials[ground.material].pbrMetallicRoughness.baseColorTexture is not None  # the checker
    box = gltf.meshes[nodes["box/geom"].mesh].primitives[0]
    assert box.attributes.TEXCOORD_0 is None  # colour only
    assert gltf.materials[box.material].pbrMetallicRoughness.baseColorFactor == pytest.approx([0.8, 0.3, 0.2, 1.0])
    assert "globe" in _animated(gltf, blob)  # it falls
    issues = _validate(out)
    assert (issues["numErrors"], issues["numWarnings"], issues["numInfos"], issues["numHints"]) == (0, 0, 0, 0), issues[
        "messages"
    ][:5]


def test_gltf_file_holds_the_same_scene_and_outputs_are_deterministic(demo: Path, tmp_path: Path) -> None:
    a, b, c = tmp_path / "a.glb", tmp_path / "b.glb", tmp_path / "c.gltf"
    export_recording(demo, {"glb": a, "gltf": c})
    export_recording(demo, {"glb": b})
    assert a.read_bytes() == b.read_bytes()
    text = json.loads(c.read_text())
    assert text["buffers"][0]["uri"].startswith("data:application/octet-stream;base64,")
    binary = pygltflib.GLTF2.load_from_bytes(a.read_bytes())
    assert [n["name"] for n in text["nodes"]] == [n.name for n in binary.nodes]
    assert len(text["animations"][0]["channels"]) == len(binary.animations[0].channels)
    issues = _validate(c)
    assert (issues["numErrors"], issues["numWarnings"], issues["numInfos"], issues["numHints"]) == (0, 0, 0, 0), issues[
        "messages"
    ][:5]


def test_demo_usd_evaluates_to_the_simulation_at_five_times(demo: Path, truth: Any, tmp_path: Path) -> None:
    from pxr import Usd, UsdGeom, UsdPhysics, UsdValidation

    out = tmp_path / "demo.usda"
    result = CliRunner().invoke(main, ["replay", str(demo), "--usd", str(out)])
    assert result.exit_code == 0, result.output
    stage = Usd.Stage.Open(str(out))
    rate = stage.GetTimeCodesPerSecond()
    assert rate == 50.0 and stage.GetFramesPerSecond() == 50.0
    assert stage.GetStartTimeCode() == 0.0 and stage.GetEndTimeCode() == pytest.approx(39.98 * 50)
    bodies = {}
    for prim in stage.Traverse():
        name = prim.GetAttribute("simrun:name")
        if prim.HasAPI(UsdPhysics.RigidBodyAPI) and name:
            bodies[name.Get()] = UsdGeom.Xformable(prim)
    assert {"boebot", "boebot/left_wheel", "box", "ground"} <= set(bodies)
    assert stage.GetPrimAtPath("/World/boebot").HasAPI(UsdPhysics.ArticulationRootAPI)  # the static export's schema
    assert any(p.IsA(UsdPhysics.RevoluteJoint) for p in stage.Traverse())
    for t in TIMES:
        positions, quats = truth[t]
        for name, xform in bodies.items():
            matrix = xform.ComputeLocalToWorldTransform(Usd.TimeCode(t * rate))
            assert np.linalg.norm(np.array(matrix.ExtractTranslation()) - positions[name]) < 1e-6, (name, t)
            rotation = matrix.ExtractRotationQuat()
            q = np.array([rotation.GetReal(), *rotation.GetImaginary()])
            assert _angle(q, quats[name]) < 1e-6, (name, t)  # doubles: far inside the 1e-5 asked for
    assert bodies["boebot"].GetOrderedXformOps()[0].GetNumTimeSamples() == 2000
    assert bodies["ground"].GetOrderedXformOps()[0].GetNumTimeSamples() == 0
    found = UsdValidation.ValidationContext(UsdValidation.ValidationRegistry().GetOrLoadAllValidators()).Validate(stage)
    assert [e.GetMessage() for e in found if e.GetType() == UsdValidation.ValidationErrorType.Error] == []


def test_replay_command_line(demo: Path, tmp_path: Path) -> None:
    runner = CliRunner()
    assert runner.invoke(main, ["replay", str(demo)]).exit_code == 2  # no output named
    result = runner.invoke(main, ["replay", str(demo), "--glb", str(tmp_path / "x.gltf")])
    assert result.exit_code == 1 and result.output.count("\n") == 1 and "must end in .glb" in result.output
    foreign = tmp_path / "mine.glb"
    foreign.write_bytes(b"not simrun's")
    result = runner.invoke(main, ["replay", str(demo), "--glb", str(foreign)])
    assert result.exit_code == 1 and "--force" in result.output and foreign.read_bytes() == b"not simrun's"
    assert runner.invoke(main, ["replay", str(demo), "--glb", str(foreign), "--force"]).exit_code == 0
    result = runner.invoke(main, ["replay", str(demo), "--glb", str(tmp_path / "a.glb"), "--fps", "5"])
    assert result.exit_code == 0 and "keyframes" in result.output
    assert (
        runner.invoke(main, ["replay", str(demo), "--glb", str(tmp_path / "b.glb"), "--tolerance", "0"]).exit_code == 2
    )


def test_play_writes_the_recording_as_glb_and_usd_beside_it(tmp_path: Path) -> None:
    runner = CliRunner()
    log = tmp_path / "run.simlog"
    base = ["play", str(DEMO), "--duration", "3", "--commands", str(COMMANDS)]
    assert runner.invoke(main, [*base, "--record-as", "glb"]).exit_code == 2  # needs --record
    assert runner.invoke(main, [*base, "--record", str(log), "--record-as", "glb,mp3"]).exit_code == 2
    result = runner.invoke(main, [*base, "--record", str(log), "--record-as", "glb,usda"])
    assert result.exit_code == 0, result.output
    assert (tmp_path / "run.glb").read_bytes() == _export_bytes(log, tmp_path / "again.glb")
    assert (tmp_path / "run.usda").read_text().startswith("#usda")


def _export_bytes(log: Path, out: Path) -> bytes:
    export_recording(log, {"glb": out})
    return out.read_bytes()


def test_bad_inputs_are_one_error_line_and_write_nothing(demo: Path, tmp_path: Path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    runner = CliRunner()
    broken = tmp_path / "broken.simlog"
    broken.write_bytes(demo.read_bytes()[:5000])  # truncated inside a record
    (tmp_path / "boebot.toml").write_bytes(DEMO.read_bytes())  # the recorded scene path is relative
    out = tmp_path / "out.glb"
    result = runner.invoke(main, ["replay", str(broken), "--glb", str(out)])
    assert result.exit_code == 1 and result.output.startswith("error: ") and result.output.count("\n") == 1
    assert "byte" in result.output and not out.exists()
    monkeypatch.setenv("SIMRUN_VIEWER_JS", str(tmp_path / "missing.js"))
    result = runner.invoke(main, ["replay", str(demo), "--glb", str(out), "--html", str(tmp_path / "p.html")])
    assert result.exit_code == 1 and "install_three_viewer.sh" in result.output and result.output.count("\n") == 1
    assert not out.exists()  # checked before anything is written
    own = tmp_path / "own"
    own.mkdir()
    scene = own / "boebot.toml"
    scene.write_text(DEMO.read_text())
    log = _record(scene, own, 0.5)
    scene.write_text(DEMO.read_text() + "\n# edited\n")
    result = runner.invoke(main, ["replay", str(log), "--usd", str(own / "run.usda")])
    assert result.exit_code == 1 and "changed since" in result.output and not (own / "run.usda").exists()


def test_key_times_stay_strictly_increasing_in_float32_on_long_runs(tmp_path: Path) -> None:
    from simrun.record.replay_glb import recording_gltf
    from simrun.record.replay_tracks import Tracks, animation_keys

    world = load_scene(DEMO)
    world.compile()
    n, nbody = 40, world.model.nbody
    times = 1e5 + np.arange(n) * 1e-3  # float32 resolves 7.8 ms here
    positions = np.zeros((n, nbody, 3))
    positions[:, 2, 0] = np.linspace(0.0, 1.0, n)  # the robot slides 1 m along x
    quats = np.zeros((n, nbody, 4))
    quats[..., 0] = 1.0
    tracks = Tracks(times, positions, quats, 1e-3)
    out = tmp_path / "long.glb"
    out.write_bytes(recording_gltf(world, tracks, animation_keys(tracks)).glb())
    animated = _animated(*_gltf(out.read_bytes()))
    keys, values = animated["boebot"]["translation"]
    assert (np.diff(keys) > 0).all() and 5 <= len(keys) < n
    assert values[0][0] == 0.0 and keys[0] == np.float32(1e5)
    issues = _validate(out)
    assert (issues["numErrors"], issues["numWarnings"], issues["numInfos"], issues["numHints"]) == (0, 0, 0, 0), issues[
        "messages"
    ][:5]
