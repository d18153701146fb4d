"""Issue 21 follow-ups: attacks an independent verifier re-ran after the first hardening round.

Each test builds its hostile input in ``tmp_path`` and runs the installed command line (or the library)
the way the verifier did; each must end with exit 0/1 and at most one ``error:`` line, never exit 3, a
traceback or a stray library warning.
"""

import io
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from PIL import Image

BIN = Path(sys.executable).parent
BOX = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"
TEXTURED = (
    b"mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nvt 0 0\nvt 1 0\nvt 0 1\n"
    b"usemtl x\nf 1/1 3/3 2/2\nf 1/1 2/2 4/3\nf 1/1 4/3 3/2\nf 2/1 3/2 4/3\n"
)


def png(size: tuple[int, int] = (8, 8), colour: tuple[int, int, int] = (10, 200, 30)) -> bytes:
    buf = io.BytesIO()
    Image.new("RGB", size, colour).save(buf, format="PNG")
    return buf.getvalue()


def run(*args: object, cwd: Path | None = None) -> subprocess.CompletedProcess[bytes]:
    """Run an installed command (``meshtool``, ``obj2bin``, ``simrun``) without debug variables."""
    env = {k: v for k, v in os.environ.items() if k not in ("MESHTOOL_DEBUG", "SIMRUN_DEBUG", "MESHTOOL_VERBOSE")}
    argv = [os.fspath(BIN / str(args[0])), *(a if isinstance(a, bytes) else os.fspath(a) for a in args[1:])]  # type: ignore[arg-type]
    return subprocess.run(argv, capture_output=True, timeout=300, env=env, cwd=cwd, check=False)


def clean_exit(proc: subprocess.CompletedProcess[bytes], code: int, report: bool = False) -> str:
    """The stderr of a run that ended with ``code`` and, when it failed, exactly one ``error:`` line.

    ``report``: the command reports findings on stdout (``validate``): exit 1 comes with no error line.
    """
    stderr = proc.stderr.decode("utf-8")  # strict: a name's stray bytes are shown as \xNN
    assert "Traceback" not in stderr and "internal error" not in stderr, stderr
    assert proc.returncode == code, stderr
    if report:
        assert stderr == "", stderr
    elif code in (1, 2):
        lines = [line for line in stderr.splitlines() if line.strip()]
        assert len(lines) == 1 and lines[0].startswith(("error:", "usage error:", "Error:")), stderr
    return stderr


# -- 2. non-UTF-8 file names --------------------------------------------------------------------------------


def test_validate_a_folder_with_a_non_utf8_obj_name(tmp_path):
    folder = tmp_path / "nu"
    folder.mkdir()
    (folder / os.fsdecode(b"plain\xff.obj")).write_bytes(BOX)
    proc = run("meshtool", "validate", "nu", cwd=tmp_path)
    stdout = proc.stdout.decode("utf-8")
    clean_exit(proc, 0)
    assert "X001" not in stdout and "nu/plain\\xff.obj" in stdout
    assert "byte 0xff (not UTF-8)" in stdout  # S009 names the byte, not the backslash of its spelling
    for fmt in ("html", "json", "junit", "github"):
        proc = run("meshtool", "validate", "nu", "--format", fmt, "-o", f"r.{fmt}", cwd=tmp_path)
        clean_exit(proc, 0)
        text = (tmp_path / f"r.{fmt}").read_bytes().decode("utf-8")
        assert "plain\\xff.obj" in text or "plain\\\\xff.obj" in text, fmt
        assert "X001" not in text
    document = json.loads((tmp_path / "r.json").read_bytes())
    (entry,) = document["assets"]
    assert entry["path"] == "nu/plain\\xff.obj"


def test_validate_resolves_a_latin1_mtllib_like_normalize(tmp_path):
    """``mtllib t\\xe9x.mtl`` (Latin-1 bytes) naming a file whose name has those bytes."""
    folder = tmp_path / "a"
    folder.mkdir()
    (folder / "box.obj").write_bytes(TEXTURED.replace(b"mtllib m.mtl", b"mtllib t\xe9x.mtl"))
    (folder / os.fsdecode(b"t\xe9x.mtl")).write_bytes(b"newmtl x\nKd 1 0 0\nmap_Kd tex.png\n")
    (folder / "tex.png").write_bytes(png())
    normalize = run("meshtool", "normalize", folder / "box.obj", "-o", tmp_path / "out")
    clean_exit(normalize, 0)
    proc = run("meshtool", "validate", "a", "--format", "json", cwd=tmp_path)
    clean_exit(proc, 0)
    (entry,) = json.loads(proc.stdout)["assets"]
    rules = {f["rule"] for f in entry["findings"]}
    assert "X001" not in rules and "S002" not in rules, entry["findings"]
    assert "S010" in rules  # Latin-1 text, said once
    # the cache key covers the MTL by its real name: a second run is served from the cache
    cache = tmp_path / "cache"
    first = run("meshtool", "validate", "a", "--cache-dir", cache, cwd=tmp_path)
    second = run("meshtool", "validate", "a", "--cache-dir", cache, cwd=tmp_path)
    clean_exit(first, 0)
    clean_exit(second, 0)
    assert "1 from cache" in second.stdout.decode("utf-8")


SCENES = Path(__file__).resolve().parents[1] / "fixtures" / "scenes"


def test_replay_of_a_recording_with_a_non_utf8_name(tmp_path):
    from simrun.record.replay_html import DEFAULT_BUNDLE, VIEWER_VARIABLE

    log = os.fsdecode(b"r\xff.simlog")
    clean_exit(run("simrun", "play", SCENES / "boebot.toml", "--duration", "0.2", "--record", log, cwd=tmp_path), 0)
    missing = run("simrun", "replay", os.fsdecode(b"x\xfe.simlog"), "--html", "ok.html", cwd=tmp_path)
    assert "x\\xfe.simlog" in clean_exit(missing, 1)
    if not (os.environ.get(VIEWER_VARIABLE) or DEFAULT_BUNDLE.is_file()):
        pytest.skip("the three.js viewer bundle is not installed: run scripts/install_three_viewer.sh")
    proc = run("simrun", "replay", log, "--html", "ok.html", cwd=tmp_path)
    clean_exit(proc, 0)
    assert "from r\\xff.simlog" in proc.stdout.decode("utf-8")
    page = (tmp_path / "ok.html").read_bytes().decode("utf-8")
    assert "<title>r\\xff - simrun recording</title>" in page


# -- 3. files over the read limit ---------------------------------------------------------------------------


@pytest.mark.parametrize(("name", "rule"), [("big.obj", "S001"), ("big.stl", "S001"), ("big.mbin", "K001")])
def test_validate_a_3_gb_sparse_file_is_a_finding(tmp_path, name, rule):
    big = tmp_path / name
    big.write_bytes(b"v 0 0 0\n" if name.endswith(".obj") else b"")
    os.truncate(big, 3 << 30)  # sparse: no disk space used
    proc = run("meshtool", "validate", name, "--format", "json", "--no-cache", cwd=tmp_path)
    clean_exit(proc, 1, report=True)
    (entry,) = json.loads(proc.stdout)["assets"]
    rules = [f["rule"] for f in entry["findings"]]
    assert rules == [rule], entry["findings"]
    assert "is 3 GiB, over the 1 GiB limit" in entry["findings"][0]["message"]


# -- 4. over-long output and input names ---------------------------------------------------------------------

LONG = "y" * 300  # over NAME_MAX (255): every lookup of it fails with ENAMETOOLONG
LONG_NAME_COMMANDS = {
    "obj2bin-o-file": ["obj2bin", "box.obj", "-o", f"{LONG}.mbin"],
    "obj2bin-o-in-folder": ["obj2bin", "box.obj", "-o", f"{LONG}/x.mbin"],
    "obj2bin-folder": ["obj2bin", "in", "-o", LONG],
    "obj2bin-src": ["obj2bin", f"{LONG}.obj"],
    "normalize-o": ["meshtool", "normalize", "box.obj", "-o", LONG],
    "mjcf-o": ["meshtool", "mjcf", "box.mbin", "-o", LONG],
    "export-glb": ["meshtool", "export", "box.mbin", "--glb", f"{LONG}.glb"],
    "unpack-o": ["meshtool", "unpack", "box.mbin", "-o", LONG],
    "info": ["meshtool", "info", f"{LONG}.mbin"],
    "simrun-record": ["simrun", "play", "SCENE", "--duration", "0.1", "--record", f"{LONG}.simlog"],
    "simrun-video": ["simrun", "play", "SCENE", "--duration", "0.1", "--video", f"{LONG}.mp4"],
    "simrun-scene": ["simrun", "play", f"{LONG}.toml"],
}


@pytest.fixture(scope="module")
def long_name_folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("long")
    (folder / "box.obj").write_bytes(BOX)
    (folder / "in").mkdir()
    (folder / "in" / "box.obj").write_bytes(BOX)
    clean_exit(run("obj2bin", "box.obj", "-o", "box.mbin", cwd=folder), 0)
    return folder


@pytest.mark.parametrize("command", sorted(LONG_NAME_COMMANDS))
def test_a_300_character_name_is_one_error_line(long_name_folder, command):
    args = [str(SCENES / "boebot.toml") if a == "SCENE" else a for a in LONG_NAME_COMMANDS[command]]
    before = sorted(p.name for p in long_name_folder.iterdir())
    stderr = clean_exit(run(*args, cwd=long_name_folder), 1)
    assert "too long" in stderr
    assert sorted(p.name for p in long_name_folder.iterdir()) == before  # nothing left behind


# -- 5. deeply nested TOML and JSON --------------------------------------------------------------------------

DEEP_TOML = ("x = " + "[" * 600 + "]" * 600 + "\n").encode()  # about 1 KB


def simlog_with_header(header: bytes) -> bytes:
    import struct

    from simrun.record.simlog import MAGIC, MAJOR, MINOR

    return MAGIC + struct.pack("<HHI", MAJOR, MINOR, len(header)) + header


def deep_scene(folder: Path) -> list[object]:
    (folder / "deep.toml").write_bytes(DEEP_TOML)
    return ["simrun", "check", "deep.toml"]


def deep_scene_table(folder: Path) -> list[object]:  # parses (depth < the parser's stack), then refused
    (folder / "deep.toml").write_bytes(b"[world]\ngravity = " + b"[" * 100 + b"]" * 100 + b"\n")
    return ["simrun", "play", "deep.toml", "--duration", "0.1"]


def deep_commands(folder: Path) -> list[object]:
    (folder / "deep.commands.toml").write_bytes(DEEP_TOML)
    return ["simrun", "play", SCENES / "boebot.toml", "--duration", "0.1", "--commands", "deep.commands.toml"]


def deep_simlog(folder: Path) -> list[object]:
    (folder / "deep.simlog").write_bytes(simlog_with_header(b'{"a":' * 10000))
    return ["simrun", "replay", "deep.simlog", "--glb", "x.glb"]


def deep_simlog_resim(folder: Path) -> list[object]:
    (folder / "deep.simlog").write_bytes(simlog_with_header(b"[" * 10000 + b"]" * 10000))
    return ["simrun", "resim", "deep.simlog"]


def deep_meshtool_toml(folder: Path) -> list[object]:
    (folder / "a").mkdir()
    (folder / "a" / "box.obj").write_bytes(BOX)
    (folder / "meshtool.toml").write_bytes(b"[validate]\n" + DEEP_TOML)
    return ["meshtool", "validate", "a"]


def deep_pyproject(folder: Path) -> list[object]:
    (folder / "a").mkdir()
    (folder / "a" / "box.obj").write_bytes(BOX)
    (folder / "pyproject.toml").write_bytes(b"[tool.meshtool.validate]\n" + DEEP_TOML)
    return ["meshtool", "validate", "a"]


def deep_gltf(folder: Path) -> list[object]:
    (folder / "deep.gltf").write_bytes(b'{"asset": {"version": "2.0"}, "extras": ' + b"[" * 200 + b"]" * 200 + b"}")
    return ["meshtool", "normalize", "deep.gltf", "-o", "out"]


DEEP = {
    "scene": (deep_scene, 1),
    "scene-parsed": (deep_scene_table, 1),
    "commands": (deep_commands, 1),
    "simlog-header": (deep_simlog, 1),
    "simlog-header-resim": (deep_simlog_resim, 1),
    "meshtool-toml": (deep_meshtool_toml, 2),
    "pyproject": (deep_pyproject, 2),
    "gltf": (deep_gltf, 1),
}


@pytest.mark.parametrize("attack", sorted(DEEP))
def test_deep_nesting_is_one_error_line(tmp_path, attack):
    make, code = DEEP[attack]
    args = make(tmp_path)
    stderr = clean_exit(run(*args, cwd=tmp_path), code)
    assert "nested more than 64 levels deep" in stderr
    assert "deep" in stderr or "meshtool.toml" in stderr or "pyproject.toml" in stderr  # names the file


def test_nesting_limit_is_the_same_through_every_parser():
    import json
    import tomllib

    from meshtool.files.nesting import MAX_NESTING, NestingError, bounded, nesting_depth

    assert nesting_depth({"a": [1, [2, {}]]}) == 4 and nesting_depth(3) == 0
    inside = "[" * (MAX_NESTING - 1) + "]" * (MAX_NESTING - 1)  # the document itself is one level
    assert nesting_depth(bounded(lambda: json.loads(inside))) == MAX_NESTING - 1
    assert nesting_depth(bounded(lambda: tomllib.loads(f"x = {inside}"))) == MAX_NESTING
    for n in (MAX_NESTING + 1, 400, 100_000):  # parsed and counted, or the parser's stack ran out
        with pytest.raises(NestingError, match=f"nested more than {MAX_NESTING} levels"):
            bounded(lambda n=n: json.loads("[" * n + "]" * n))


# -- 7. a PNG with trailing bytes in simrun -------------------------------------------------------------------

TEXTURED_SCENE = """[[entities]]
type = "Ground"
name = "floor"

[[entities]]
type = "Sphere"
name = "globe"
free = true
mass = 1.0
radius = 0.1
texture = "tex.png"
"""


def test_simrun_refuses_a_png_with_trailing_bytes(tmp_path):
    """The verifier's attack: 20 MB of zeros after IEND were copied into `simrun export` output."""
    (tmp_path / "scene.toml").write_text(TEXTURED_SCENE)
    (tmp_path / "tex.png").write_bytes(png() + bytes(20 << 20))
    for args in (["export", "scene.toml", "--mjcf", "out/scene.xml"], ["check", "scene.toml"]):
        stderr = clean_exit(run("simrun", *args, cwd=tmp_path), 1)
        assert "tex.png" in stderr and f"{20 << 20} bytes after the end of the PNG image" in stderr
        assert f"byte {len(png())}" in stderr
    assert not (tmp_path / "out").exists()
    (tmp_path / "tex.png").write_bytes(png())  # the same image without the tail is fine
    clean_exit(run("simrun", "export", "scene.toml", "--mjcf", "out/scene.xml", cwd=tmp_path), 0)
    assert max(p.stat().st_size for p in (tmp_path / "out").iterdir()) < 1 << 20


def test_simrun_refuses_an_mbin_texture_with_trailing_bytes(tmp_path):
    """A pack's TEX section with bytes after IEND (checksums valid) is not copied into simrun's outputs."""
    from meshtool.packfile import parse

    folder = tmp_path / "a"
    folder.mkdir()
    (folder / "box.obj").write_bytes(TEXTURED)
    (folder / "m.mtl").write_bytes(b"newmtl x\nKd 1 0 0\nmap_Kd tex.png\n")
    (folder / "tex.png").write_bytes(png())
    clean_exit(run("obj2bin", folder / "box.obj", "-o", tmp_path / "box.mbin"), 0)
    sys.path.insert(0, str(Path(__file__).parent))
    try:
        from test_mbin_hostile import assemble, entry, read_sections
    finally:
        sys.path.pop(0)
    entries, flags = read_sections((tmp_path / "box.mbin").read_bytes())
    tex = entry(entries, b"TEX ")
    tex[7] = bytearray(bytes(tex[7]) + bytes(4096))
    tex[4] = len(tex[7])
    data = assemble(entries, flags)
    parse(data)  # a valid pack as far as the container goes
    (tmp_path / "box.mbin").write_bytes(data)
    (tmp_path / "scene.toml").write_text(
        '[assets]\nbox = "box.mbin"\n\n[[entities]]\ntype = "MeshEntity"\nname = "box"\nasset = "box"\n'
    )
    stderr = clean_exit(run("simrun", "export", "scene.toml", "--mjcf", "out/scene.xml", cwd=tmp_path), 1)
    assert "4096 bytes after the end of the PNG image" in stderr


# -- 8. no stray library warnings before the error line -------------------------------------------------------


def inf_stl(folder: Path) -> list[object]:
    import struct

    import numpy as np

    tris = np.array([[0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0], [0, 0, 1, 0, 0, 0, 3e38, 0, 0, 0, 3e38, 0]], "<f4")
    tris[1, 3] = np.inf
    body = b"".join(t.tobytes() + b"\0\0" for t in tris)
    (folder / "inf.stl").write_bytes(b"\0" * 80 + struct.pack("<I", 2) + body)
    return ["meshtool", "normalize", "inf.stl", "-o", "out"]


def xxe_urdf(folder: Path) -> list[object]:
    (folder / "xxe.urdf").write_text(
        '<?xml version="1.0"?>\n<!DOCTYPE r [<!ENTITY x SYSTEM "file:///etc/passwd">]>\n'
        '<robot name="r"><link name="a">&x;</link></robot>\n'
    )
    return ["meshtool", "urdf", "xxe.urdf", "-o", "out"]


def xxe_urdf_simrun(folder: Path) -> list[object]:
    xxe_urdf(folder)
    (folder / "scene.toml").write_text('[[entities]]\ntype = "UrdfRobot"\nname = "r"\nurdf = "xxe.urdf"\n')
    return ["simrun", "check", "scene.toml"]


@pytest.mark.parametrize("attack", [inf_stl, xxe_urdf, xxe_urdf_simrun], ids=lambda f: f.__name__)
def test_no_library_chatter_on_stderr(tmp_path, attack):
    args = attack(tmp_path)
    proc = run(*args, cwd=tmp_path)
    stderr = proc.stderr.decode("utf-8")
    assert "Traceback" not in stderr and "internal error" not in stderr, stderr
    for chatter in ("RuntimeWarning", "Warning:", "Entity 'x' not defined", "Using different parsing approach"):
        assert chatter not in stderr, stderr
    assert all(line.startswith(("error:", "warning:", "note:", "info:")) for line in stderr.splitlines()), stderr


def test_library_warnings_show_with_verbose(tmp_path):
    """-v keeps what libraries say (for a bug report); only the default run is quiet."""
    inf_stl(tmp_path)
    proc = run("meshtool", "normalize", "inf.stl", "-o", "out", "-v", cwd=tmp_path)
    assert "RuntimeWarning" in proc.stderr.decode("utf-8")


def test_urdf_robot_keeps_the_xml_parser_quiet(tmp_path, caplog):
    """The library itself (not only the CLI) drops yourdfpy's chatter about a refused XML entity."""
    import contextlib
    import logging

    from simrun.errors import SimrunError
    from simrun.scene.scene_file import load_scene

    xxe_urdf_simrun(tmp_path)
    with caplog.at_level(logging.DEBUG), contextlib.suppress(SimrunError):
        load_scene(tmp_path / "scene.toml").compile()
    assert not [r for r in caplog.records if r.name.startswith("yourdfpy")], caplog.text


# -- 9. a scale that collapses the mesh ---------------------------------------------------------------------


@pytest.mark.parametrize(
    "args",
    [
        ["obj2bin", "box.obj", "-o", "s.mbin", "--scale", "1e-300", "--no-check"],
        ["obj2bin", "box.obj", "-o", "s.mbin", "--scale", "1e-300"],
        ["meshtool", "normalize", "box.obj", "-o", "out", "--scale", "1e-300"],
        ["obj2bin", "box.obj", "-o", "s.mbin", "--units", "mm", "--scale", "1e-7", "--no-check"],
    ],
    ids=["obj2bin-no-check", "obj2bin", "normalize", "units-and-scale"],
)
def test_a_scale_that_collapses_the_mesh_is_refused(tmp_path, args):
    (tmp_path / "box.obj").write_bytes(BOX)
    stderr = clean_exit(run(*args, cwd=tmp_path), 1)
    assert "under the 1e-09 m minimum" in stderr and "--scale" in stderr
    assert not (tmp_path / "s.mbin").exists() and not (tmp_path / "out").exists()


def test_a_small_but_resolvable_scale_still_converts(tmp_path):
    """10 nm across is kept: float32 resolves it (the hull and positions are not all zero)."""
    from meshtool.packfile import load

    (tmp_path / "box.obj").write_bytes(BOX)
    clean_exit(run("obj2bin", "box.obj", "-o", "s.mbin", "--scale", "1e-8", "--no-check", cwd=tmp_path), 0)
    with load(tmp_path / "s.mbin") as packed:
        assert float(abs(packed.positions).max()) == pytest.approx(1e-8, rel=1e-6)
