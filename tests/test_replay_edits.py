"""``simrun replay`` of a recording with edits shows the edited world: bodies for their lifetimes, teleports followed.

A real ``simrun serve --lockstep --edit --record`` session on 127.0.0.1: a Boe-Bot and a box ``old``; after
0.5 s a crate is inserted, after 1.0 s it is teleported 1 m along +Y, after 1.5 s ``old`` is removed; 2 s in
all. Ground truth: the edit records' times in the ``.simlog`` (read with :class:`simrun.record.simlog.Simlog`),
the teleport's target, and the server's own pose answers. The GLB is read with pygltflib and checked by the
Khronos validator (when installed), the HTML page's embedded GLB likewise.
"""

from __future__ import annotations

import base64
import os
import re
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scene_text import boebot_scene
from serve_helpers import SIMRUN, serve
from test_replay_export import _gltf, _read, _validate

from simrun.client import Client
from simrun.record.simlog import Simlog
from simrun.world.edit_apply import EditRecord

SCENE = boebot_scene(
    entities="""
[[entities]]
type = "Box"
name = "old"
free = true
dimensions = [0.1, 0.1, 0.1]
pose = { position = [0.0, -1.0, 0.05] }
"""
)
CRATE = {"type": "Box", "name": "crate", "dimensions": [0.2, 0.2, 0.2], "mass": 2.0, "free": True,
         "pose": {"position": [1.0, 0.0, 0.1]}}  # fmt: skip


@pytest.fixture(scope="module")
def session(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    folder = tmp_path_factory.mktemp("edited")
    scene = folder / "edited.toml"
    scene.write_text(SCENE)
    record = folder / "run.simlog"
    poses = {}
    with serve(scene, "--lockstep", "--edit", "--record", str(record)) as server:
        sim = Client(server.url)
        sim.service("DriveService", "boebot").cmd_vel(0.1, 0.0)
        sim.step(seconds=0.5)
        sim.insert(CRATE)
        sim.step(seconds=0.5)
        poses["before"] = sim.pose("crate")
        sim.teleport("crate", [1.0, 1.0, 0.1])
        sim.step(seconds=0.5)
        poses["after"] = sim.pose("crate")
        sim.remove("old")
        sim.step(seconds=0.5)
    log = Simlog(record)
    try:
        edits = {r.command.kind: r.command.t for r in log.events() if isinstance(r.command, EditRecord)}
    finally:
        log.close()
    assert list(edits) == ["insert", "teleport", "remove"]
    return {"folder": folder, "record": record, "edits": edits, "poses": poses, "period": log.frame_period}


def _replay(session: dict[str, Any], flag: str, out: Path) -> None:
    env = dict(os.environ, MUJOCO_GL="egl")
    done = subprocess.run([SIMRUN, "replay", str(session["record"]), flag, str(out)], capture_output=True, text=True,
                          timeout=300, env=env)  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert out.stat().st_size > 0


def _lifetimes(data: bytes) -> tuple[Any, bytes, dict[str, tuple[list[float], list[float], list[float] | None]]]:
    """The glTF, its blob and, per node with a scale channel: (key times, scale x per key, static scale)."""
    gltf, blob = _gltf(data)
    out = {}
    for animation in gltf.animations:
        for channel in animation.channels:
            if channel.target.path != "scale":
                continue
            sampler = animation.samplers[channel.sampler]
            assert sampler.interpolation == "STEP"
            node = gltf.nodes[channel.target.node]
            times = _read(gltf, blob, sampler.input).tolist()
            values = _read(gltf, blob, sampler.output)
            assert np.all(values == values[:, :1])  # uniform scale: 0 or 1
            out[node.name] = (times, values[:, 0].tolist(), node.scale)
    return gltf, blob, out


def _check(session: dict[str, Any], data: bytes) -> None:
    gltf, blob, lives = _lifetimes(data)
    assert set(lives) == {"crate", "old"}  # only the bodies that did not exist throughout
    period = session["period"]
    times, scale, static = lives["crate"]
    assert static == [0.0, 0.0, 0.0] and scale == [0.0, 1.0]  # hidden at the start, shown from its insertion
    assert session["edits"]["insert"] - 1e-6 <= times[1] <= session["edits"]["insert"] + period + 1e-6  # float32 keys
    times, scale, static = lives["old"]
    assert static in (None, [1.0, 1.0, 1.0]) and scale == [1.0, 0.0]
    assert session["edits"]["remove"] - 1e-6 <= times[1] <= session["edits"]["remove"] + period + 1e-6
    # the crate's translation follows its recorded poses: beside the insertion point, then the teleport's target
    node = next(k for k, n in enumerate(gltf.nodes) if n.name == "crate")
    channel = next(
        c for a in gltf.animations for c in a.channels if c.target.node == node and c.target.path == "translation"
    )
    sampler = gltf.animations[0].samplers[channel.sampler]
    key_times, moved = _read(gltf, blob, sampler.input), _read(gltf, blob, sampler.output)
    teleport = session["edits"]["teleport"]
    before = moved[(key_times > session["edits"]["insert"] + period) & (key_times < teleport - 1e-6)]
    after = moved[key_times > teleport + period]
    assert len(before) and len(after)
    np.testing.assert_allclose(before[-1], session["poses"]["before"][:3], atol=2e-3)
    np.testing.assert_allclose(after[0][:2], [1.0, 1.0], atol=2e-3)  # the teleport's target, then it rests
    np.testing.assert_allclose(after[-1], session["poses"]["after"][:3], atol=2e-3)


def test_replay_glb_shows_the_inserted_body_only_after_its_insertion_and_the_validator_accepts_it(session):
    out = session["folder"] / "run.glb"
    _replay(session, "--glb", out)
    _check(session, out.read_bytes())
    issues = _validate(out)
    assert issues["numErrors"] == 0, issues["messages"][:5]


def test_replay_html_embeds_the_same_edited_animation(session):
    out = session["folder"] / "run.html"
    _replay(session, "--html", out)
    found = re.search(r'<script id="simrun-glb" type="application/octet-stream">([A-Za-z0-9+/=]+)</script>',
                      out.read_text(encoding="utf-8"))  # fmt: skip
    assert found is not None
    embedded = base64.b64decode(found.group(1))
    _check(session, embedded)
    glb = session["folder"] / "run.glb"
    if glb.exists():
        assert embedded == glb.read_bytes()  # one glTF for both outputs


def test_replay_usd_hides_each_body_outside_its_lifetime(session):
    pytest.importorskip("pxr", reason="usd-core is not installed")
    from pxr import Usd, UsdGeom

    out = session["folder"] / "run.usda"
    _replay(session, "--usd", out)
    stage = Usd.Stage.Open(str(out))
    rate = stage.GetTimeCodesPerSecond()
    prims = {p.GetName(): p for p in stage.Traverse()}

    def shown(name: str, seconds: float) -> str:
        return str(UsdGeom.Imageable(prims[name]).GetVisibilityAttr().Get(round(seconds * rate, 6)))

    insert, remove, period = session["edits"]["insert"], session["edits"]["remove"], session["period"]
    assert shown("crate", 0.0) == "invisible" and shown("crate", insert - period) == "invisible"
    assert shown("crate", insert + period) == "inherited" and shown("crate", 2.0) == "inherited"
    assert shown("old", 0.0) == "inherited" and shown("old", remove - period) == "inherited"
    assert shown("old", remove + period) == "invisible"
    assert shown("boebot", 1.0) == "inherited"  # bodies that exist throughout have no visibility samples
    assert not UsdGeom.Imageable(prims["boebot"]).GetVisibilityAttr().GetTimeSamples()


def test_replay_mcap_advertises_the_inserted_body_from_its_insertion(session):
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory

    out = session["folder"] / "run.mcap"
    _replay(session, "--mcap", out)
    frames: list[tuple[float, set[str]]] = []
    with out.open("rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        for _, _channel, message, decoded in reader.iter_decoded_messages(topics=["/tf"]):
            frames.append((message.log_time / 1e9, {t.child_frame_id for t in decoded.transforms}))
    insert, remove = session["edits"]["insert"], session["edits"]["remove"]
    assert frames and all(("crate" in names) == (t >= insert - 1e-6) for t, names in frames)
    assert all(("old" in names) == (t < remove - 1e-6) for t, names in frames)
