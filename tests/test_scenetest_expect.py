"""[[expect]] tables: every kind passes and fails where physics or geometry says it must, errors name FILE:LINE.

Ground truth is analytic: a ball dropped from rest falls z(t) = z0 - g t^2 / 2 until it meets what is
below it; a box placed with a yaw keeps it; the laser of a robot in a 4 x 4 m room reads at most the
room's diagonal.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest

from simrun.errors import SceneError
from simrun.scenetest import TestOptions, run_tests
from simrun.scenetest.expect import Outcome

G = 9.81
DROP = """
[world]
timestep = 0.002

[[entities]]
type = "Ground"
name = "ground"

[[entities]]
type = "Sphere"
name = "ball"
free = true
mass = 1.0
radius = 0.1
pose = { position = [0.0, 0.0, 1.1] }

[[entities]]
type = "Box"
name = "crate"
dimensions = [0.2, 0.2, 0.2]
pose = { position = [2.0, 0.0, 0.1], orientation = [0.9659258262890683, 0.0, 0.0, 0.25881904510252074] }
"""


def outcomes(tmp_path: Path, expect: str, duration: float = 1.0, scene: str = DROP) -> dict[str, Outcome]:
    path = tmp_path / "scene.toml"
    path.write_text(f"{scene}\n[test]\nduration = {duration}\n{expect}", encoding="utf-8")
    report = run_tests([path], TestOptions())
    (run,) = report.runs
    assert run.result.error is None
    return {o.id: o for o in run.result.outcomes}


def fall_time(height: float) -> float:
    """Seconds for a ball at rest to fall ``height`` metres."""
    return math.sqrt(2 * height / G)


def test_position_region_and_windows_follow_free_fall(tmp_path: Path) -> None:
    t_cross = fall_time(0.45)  # the ball's centre passes z = 0.65
    found = outcomes(
        tmp_path,
        """
[[expect]]
id = "rest"
kind = "position"
body = "ball"
point = [0.0, 0.0, 0.1]
within = 0.005

[[expect]]
id = "high"
kind = "region"
body = "ball"
min = [-1.0, -1.0, 0.6]
max = [1.0, 1.0, 2.0]
always = [0.0, 0.2]

[[expect]]
id = "high-too-long"
kind = "region"
body = "ball"
min = [-1.0, -1.0, 0.65]
max = [1.0, 1.0, 2.0]
always = [0.0, 0.6]

[[expect]]
id = "passes-low"
kind = "region"
body = "ball"
min = [-1.0, -1.0, 0.0]
max = [1.0, 1.0, 0.3]
sometime = [0.0, "end"]

[[expect]]
id = "at-start"
kind = "position"
body = "ball"
point = "start"
within = 0.001
at = 0.0
""",
    )
    assert found["rest"].passed and found["high"].passed and found["passes-low"].passed and found["at-start"].passed
    miss = found["high-too-long"]
    assert not miss.passed
    # the first observation (every 20 ms) after the centre passes z = 0.65, missed by the depth below it
    assert miss.time == pytest.approx(math.ceil(t_cross / 0.02) * 0.02, abs=1e-9)
    expected_z = 1.1 - 0.5 * G * miss.time**2
    assert miss.miss == pytest.approx(0.65 - expected_z, abs=5e-3)
    assert "missed by" in miss.detail and "t = 0.320 s" in miss.detail


def test_heading_of_a_placed_box(tmp_path: Path) -> None:
    found = outcomes(
        tmp_path,
        """
[[expect]]
id = "thirty"
kind = "heading"
body = "crate"
yaw = 30.0
within = 0.5

[[expect]]
id = "zero"
kind = "heading"
body = "crate"
yaw = 0.0
within = 5.0
""",
        duration=0.1,
    )
    assert found["thirty"].passed
    assert not found["zero"].passed and found["zero"].miss == pytest.approx(25.0, abs=1e-6)


def test_no_contact_fails_when_the_ball_lands(tmp_path: Path) -> None:
    scene = DROP.replace("[2.0, 0.0, 0.1]", "[0.0, 0.0, 0.1]")  # the crate under the ball: lands on it at z 0.3
    found = outcomes(
        tmp_path,
        """
[[expect]]
id = "apart"
kind = "no_contact"
between = ["ball", "crate"]

[[expect]]
id = "apart-early"
kind = "no_contact"
between = ["ball", "crate"]
always = [0.0, 0.3]
""",
        scene=scene,
    )
    landed = found["apart"]
    assert not landed.passed and landed.time is not None
    assert landed.time == pytest.approx(fall_time(0.8), abs=0.03)
    assert "ball" in landed.detail and "crate" in landed.detail
    assert found["apart-early"].passed


def test_joint_sensor_finite_warnings_realtime(tmp_path: Path) -> None:
    room = (Path(__file__).parent.parent / "fixtures" / "scenes" / "pioneer_room.toml").read_text(encoding="utf-8")
    found = outcomes(
        tmp_path,
        """
[[expect]]
id = "laser-in-room"
kind = "sensor"
sensor = "laser"
field = "ranges"
min = 0.0
max = 5.66

[[expect]]
id = "laser-too-short"
kind = "sensor"
sensor = "laser"
field = "ranges"
index = 0
max = 0.01

[[expect]]
id = "left-wheel"
kind = "joint"
joint = "p3dx/left_wheel"
min = -0.1
max = 0.1

[[expect]]
id = "ok"
kind = "finite"

[[expect]]
id = "quiet"
kind = "no_warnings"

[[expect]]
id = "fast"
kind = "realtime"
min = 1e-6

[[expect]]
id = "impossible"
kind = "realtime"
min = 1e6
""",
        duration=0.5,
        scene=room,
    )
    for ident in ("laser-in-room", "left-wheel", "ok", "quiet", "fast"):
        assert found[ident].passed, found[ident].detail
    assert not found["laser-too-short"].passed and "sensor laser.ranges[0] =" in found["laser-too-short"].detail
    assert not found["impossible"].passed and "real-time factor" in found["impossible"].detail
    assert found["fast"].detail == "real-time factor at least 1e-06"  # no measured number: reports stay identical


@pytest.mark.parametrize(
    ("table", "message"),
    [
        ('id = "a"\nkind = "teleport"', "kind: expected one of position"),
        ('id = "a"\nkind = "position"\nbody = "ball"\npoint = [0, 0]', "missing 'within'"),
        ('id = "a"\nkind = "position"\nbody = "ball"\npoint = [0, 0]\nwithin = -1', "within: expected a positive"),
        ('id = "a"\nkind = "finite"\nat = 1\nalways = [0, 1]', "give one of at, always, sometime"),
        ('id = "a"\nkind = "realtime"\nmin = 2\nat = 1', "judges the whole run"),
        ('id = "a"\nkind = "heading"\nbody = "ball"\nyaw = 0\nwithin = 1\ncolour = 2', "unknown key for kind"),
        ('id = "a"\nkind = "region"\nbody = "ball"\nmin = [1, 1]\nmax = [0, 0]', "each min <= its max"),
        ('id = "a"\nkind = "finite"\nalways = [2, 1]', "ends (1 s) before it starts"),
    ],
)
def test_bad_tables_name_file_and_line(tmp_path: Path, table: str, message: str) -> None:
    path = tmp_path / "scene.toml"
    text = f"{DROP}\n[[expect]]\n{table}\n"
    path.write_text(text, encoding="utf-8")
    first = text.splitlines().index("[[expect]]") + 1
    with pytest.raises(SceneError) as caught:
        run_tests([path], TestOptions())
    # the line of the key at fault (or of the table)
    match = re.match(rf"{re.escape(path.as_posix())}:(\d+): expect\[0\] 'a': ", str(caught.value))
    assert match is not None, str(caught.value)
    assert first <= int(match.group(1)) <= first + table.count("\n") + 1
    assert message in str(caught.value)


@pytest.mark.parametrize(
    ("table", "message"),
    [
        ('kind = "position"\nbody = "nope"\npoint = [0, 0]\nwithin = 1', "no body named 'nope'"),
        ('kind = "joint"\njoint = "nope"\nmax = 1', "nope"),
        ('kind = "sensor"\nsensor = "nope"\nmax = 1', "no sensor named 'nope'"),
        ('kind = "no_contact"\nbetween = ["ball", "nope"]', "nope"),
        ('kind = "finite"\nat = 5', "after the end of the run (1 s)"),
    ],
)
def test_expectations_checked_against_the_world(tmp_path: Path, table: str, message: str) -> None:
    path = tmp_path / "scene.toml"
    text = f'{DROP}\n[test]\nduration = 1\n\n[[expect]]\nid = "b"\n{table}\n'
    path.write_text(text, encoding="utf-8")
    line = text.splitlines().index("[[expect]]") + 1
    with pytest.raises(SceneError) as caught:
        run_tests([path], TestOptions())
    assert str(caught.value).startswith(f"{path.as_posix()}:{line}: expect 'b': ")
    assert message in str(caught.value)


def test_commands_file_expectations_and_duplicate_ids(tmp_path: Path) -> None:
    (tmp_path / "plan.commands.toml").write_text('[[expect]]\nid = "a"\nkind = "finite"\n', encoding="utf-8")
    path = tmp_path / "scene.toml"
    path.write_text(f'{DROP}\n[test]\ncommands = "plan.commands.toml"\n\n[[expect]]\nid = "a"\nkind = "finite"\n')
    with pytest.raises(SceneError, match=r"plan.commands.toml:1: expect 'a': duplicate id \(also .*scene.toml:"):
        run_tests([path], TestOptions())


def test_scene_without_expectations_is_a_finite_smoke_test(tmp_path: Path) -> None:
    path = tmp_path / "scene.toml"
    path.write_text(DROP, encoding="utf-8")
    report = run_tests([path], TestOptions())
    (run,) = report.runs
    assert report.cases[0].implicit and report.cases[0].duration == 5.0
    assert [(o.id, o.kind, o.passed) for o in run.result.outcomes] == [("finite", "finite", True)]
