"""Hostile MJCF models referenced from a scene (issue 42): each ``simrun check`` is refused with exit 1 and ONE
``error:`` line naming the element and the path (or attribute, or count and limit), quickly and small, and
nothing outside the scene's root (and no FIFO) is ever opened.

Each case runs ``simrun check SCENE`` in a child process under ``resource.setrlimit`` (address space
:data:`MEMORY_MB`, CPU :data:`CPU_S`); its wall time must stay within :data:`SLACK_S` of a benign scene's
check measured the same way (the benign one also compiles and steps 1 s). Before issue 42 these hung (FIFOs,
killed at 60 s), ran out of memory (``/dev/zero``, exit 3 after 20-30 s), took 44 s to over 300 s (2·10^4
bodies, 10^5 keyframes) or passed (reads outside the root, NaN gravity and mass).

What is opened is checked twice: in-process with an audit hook (``sys.addaudithook``, event ``open``: Python's
``open`` and ``os.open``, hence the reader's own opens) and, because MuJoCo's C code opens files with
``fopen`` where no audit hook sees it, with ``strace -f -e trace=open,openat,openat2`` on the command line
(skipped where strace is not installed: scripts/install_test_tools.sh installs it).
"""

from __future__ import annotations

import os
import re
import resource
import shutil
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from simrun.errors import EntityError
from simrun.robots.mjcf_read import ALLOW_ROOTS_ENV
from simrun.robots.mjcf_robot import MAX_MJCF_BYTES
from simrun.scene.scene_file import load_scene

ROOT = Path(__file__).resolve().parent.parent
PADDLE = ROOT / "fixtures" / "mjcf" / "included" / "meshes" / "paddle.obj"
GRID = ROOT / "fixtures" / "mjcf" / "included" / "textures" / "grid.png"
SIMRUN = Path(sys.executable).parent / "simrun"
MEMORY_MB = 1500
CPU_S = 60
SLACK_S = 5.0
FIFO = hasattr(os, "mkfifo")
STRACE = shutil.which("strace")
SCENE = '[[entities]]\ntype = "MjcfRobot"\nname = "r"\nfile = "m.xml"\n'


def _mesh_model(mesh: str, compiler: str = "") -> str:
    return (
        f"<mujoco>{compiler}<asset><mesh name='m' file='{mesh}'/></asset>"
        "<worldbody><body><geom type='mesh' mesh='m'/></body></worldbody></mujoco>"
    )


def _texture_model(texture: str) -> str:
    return (
        f"<mujoco><asset><texture name='t' type='2d' file='{texture}'/><material name='mat' texture='t'/></asset>"
        "<worldbody><body><geom size='0.1' material='mat'/></body></worldbody></mujoco>"
    )


def _hfield_model(file: str) -> str:
    return (
        f"<mujoco><asset><hfield name='h' file='{file}' size='1 1 0.1 0.1'/></asset>"
        "<worldbody><geom type='hfield' hfield='h'/></worldbody></mujoco>"
    )


def _skin_model(file: str) -> str:
    return (
        f"<mujoco><asset><skin name='s' file='{file}'/></asset>"
        "<worldbody><body name='b'><geom size='0.1'/></body></worldbody></mujoco>"
    )


def _bodies(n: int) -> str:
    return (
        "<mujoco><worldbody>"
        + "".join(f"<body pos='{k} 0 0'><geom size='0.1'/></body>" for k in range(n))
        + ("</worldbody></mujoco>")
    )


def _keyframes(n: int) -> str:
    keys = "".join("<key qpos='0.1'/>" for _ in range(n))
    return f"<mujoco><worldbody><body><joint/><geom size='0.1'/></body></worldbody><keyframe>{keys}</keyframe></mujoco>"


def _deep(n: int) -> str:
    return "<mujoco><worldbody>" + "<body><geom size='0.1'/>" * n + "</body>" * n + "</worldbody></mujoco>"


def _geoms(n: int) -> str:
    return "<mujoco><worldbody><body>" + "<geom size='0.1'/>" * n + "</body></worldbody></mujoco>"


#: (id, MJCF text (``{out}``: the folder outside the scene), extra ``simrun check`` arguments, the fragments the
#: one error line must hold). The scene's folder holds ``pipe`` (a FIFO) and ``link.obj`` (a link to the
#: outside mesh); the outside folder holds ``secret.obj``.
CASES: list[tuple[str, Callable[[Path], str], list[str], list[str]]] = [
    (
        "meshdir_absolute",
        lambda out: _mesh_model("secret.obj", f"<compiler meshdir='{out}'/>"),
        [],
        ["m.xml:1:", "mesh 'm'", "secret.obj", "outside the scene's folder"],
    ),
    (
        "meshdir_parent",
        lambda out: _mesh_model("secret.obj", "<compiler meshdir='../outside'/>"),
        [],
        ["mesh 'm'", "outside/secret.obj", "outside the scene's folder"],
    ),
    (
        "assetdir_parent",
        lambda out: _mesh_model("secret.obj", "<compiler assetdir='../outside'/>"),
        [],
        ["mesh 'm'", "outside/secret.obj", "outside the scene's folder"],
    ),
    (
        "mesh_absolute",
        lambda out: _mesh_model(f"{out}/secret.obj"),
        [],
        ["mesh 'm'", "outside/secret.obj", "outside the scene's folder"],
    ),
    ("mesh_symlink", lambda out: _mesh_model("link.obj"), [], ["mesh 'm'", "link.obj", "outside/secret.obj"]),
    (
        "include_environ",
        lambda out: "<mujoco><include file='/proc/self/environ'/></mujoco>",
        [],
        ["<include file='/proc/self/environ'>", "outside the scene's folder"],
    ),
    (
        "include_dev_zero",
        lambda out: "<mujoco><include file='/dev/zero'/></mujoco>",
        [],
        ["<include file='/dev/zero'>", "outside the scene's folder"],
    ),
    ("fifo_mesh", lambda out: _mesh_model("pipe"), [], ["mesh 'm'", "pipe", "FIFO"]),
    ("fifo_texture", lambda out: _texture_model("pipe"), [], ["texture 't'", "pipe", "FIFO"]),
    ("fifo_skin", lambda out: _skin_model("pipe"), [], ["skin 's'", "pipe", "FIFO"]),
    ("fifo_include", lambda out: "<mujoco><include file='pipe'/></mujoco>", [], ["<include file='pipe'>", "FIFO"]),
    ("zero_mesh", lambda out: _mesh_model("/dev/zero"), [], ["mesh 'm'", "/dev/zero", "outside the scene's folder"]),
    (
        "zero_texture",
        lambda out: _texture_model("/dev/zero"),
        [],
        ["texture 't'", "/dev/zero", "outside the scene's folder"],
    ),
    ("zero_hfield", lambda out: _hfield_model("/dev/zero"), [], ["hfield 'h'", "/dev/zero", "outside the scene's"]),
    # allowed, /dev/zero is still a device: never opened
    ("zero_mesh_allowed", lambda out: _mesh_model("/dev/zero"), ["--allow-root", "/dev"], ["character device"]),
    ("zero_texture_allowed", lambda out: _texture_model("/dev/zero"), ["--allow-root", "/dev"], ["character device"]),
    ("zero_hfield_allowed", lambda out: _hfield_model("/dev/zero"), ["--allow-root", "/dev"], ["character device"]),
    # found by make fuzz (target mjcf): MuJoCo allocates what these ask for (65536²: a segmentation fault)
    (
        "hfield_rows_65536",
        lambda out: (
            "<mujoco><asset><hfield name='h' nrow='65536' ncol='65536' size='1 1 .1 .1'/></asset>"
            "<worldbody><geom type='hfield' hfield='h'/></worldbody></mujoco>"
        ),
        [],
        ["<hfield> 'h'", "65,536 x 65,536", "4,294,967,296 pixels, more than the limit of 67,108,864"],
    ),
    (
        "texture_builtin_1e5",
        lambda out: (
            "<mujoco><asset><texture name='t' type='2d' builtin='checker' width='100000' height='100000'/>"
            "<material name='mat' texture='t'/></asset><worldbody><geom size='.1' material='mat'/></worldbody></mujoco>"
        ),
        [],
        ["<texture> 't'", "100,000 x 100,000", "more than the limit of 67,108,864"],
    ),
    (
        "skybox_builtin_2e4",
        lambda out: (
            "<mujoco><asset><texture name='s' type='skybox' builtin='gradient' width='20000'/></asset>"
            "<worldbody/></mujoco>"
        ),
        [],
        ["<texture> 's'", "6 faces of width 20,000", "more than the limit of 67,108,864"],
    ),
    (
        "bodies_2e4",
        lambda out: _bodies(20_000),
        [],
        ["<body>", "20,000 bodies", "limit of 10,000", "docs/limits.md"],
    ),
    (
        "replicated_bodies",
        lambda out: (
            "<mujoco><worldbody><replicate count='100000' offset='1 0 0'><body><geom size='.1'/></body>"
            "</replicate></worldbody></mujoco>"
        ),
        [],
        ["100,000 bodies", "<replicate>", "limit of 10,000"],
    ),
    ("keyframes_1e5", lambda out: _keyframes(100_000), [], ["<key>", "keyframes", "limit of 10,000"]),
    (
        "meshes_10001",
        lambda out: (
            "<mujoco><asset>"
            + "".join(f"<mesh name='m{k}' vertex='0 0 0 1 0 0 0 1 0 0 0 1'/>" for k in range(10_001))
            + "</asset></mujoco>"
        ),
        [],
        ["<mesh>", "10,001 meshes", "limit of 10,000", "docs/limits.md"],
    ),
    (
        "nkey_1e9",
        lambda out: "<mujoco><size nkey='1000000000'/><worldbody/></mujoco>",
        [],
        ["<size>", "1,000,000,000 keyframes", "limit of 10,000"],
    ),
    ("geoms_1e5", lambda out: _geoms(100_000), [], ["<geom>", "geoms", "limit of 20,000"]),
    ("deep_nesting", lambda out: _deep(100_000), [], ["nested 481 deep", "limit of 480"]),
    (
        "gravity_nan",
        lambda out: "<mujoco><option gravity='nan 0 0'/><worldbody/></mujoco>",
        [],
        ["m.xml:1:", "<option>", "attribute 'gravity' is not finite", "'nan'"],
    ),
    (
        "mass_nan",
        lambda out: "<mujoco><worldbody><body>\n<geom name='g' size='0.1' mass='nan'/></body></worldbody></mujoco>",
        [],
        ["m.xml:2:", "<geom> 'g'", "attribute 'mass' is not finite"],
    ),
    (
        "damping_inf",
        lambda out: "<mujoco><worldbody><body><joint damping='-inf'/><geom size='.1'/></body></worldbody></mujoco>",
        [],
        ["<joint>", "attribute 'damping' is not finite", "'-inf'"],
    ),
    (
        "pos_overflow",
        lambda out: "<mujoco><worldbody><body pos='1e999 0 0'><geom size='.1'/></body></worldbody></mujoco>",
        [],
        ["<body>", "attribute 'pos' is not finite", "1e999"],
    ),
]


def _layout(tmp_path: Path, text: str) -> Path:
    """The scene folder (scene, model, a FIFO, a link to the outside) and the outside folder; the scene."""
    scene, outside = tmp_path / "scene", tmp_path / "outside"
    scene.mkdir()
    outside.mkdir()
    shutil.copy(PADDLE, outside / "secret.obj")
    shutil.copy(PADDLE, scene / "ok.obj")
    if FIFO:
        os.mkfifo(scene / "pipe")
    (scene / "link.obj").symlink_to(outside / "secret.obj")
    (scene / "m.xml").write_text(text, encoding="utf-8")
    (scene / "s.toml").write_text(SCENE, encoding="utf-8")
    return scene / "s.toml"


def _check(scene: Path, *args: str, env: dict[str, str] | None = None) -> tuple[int, str, float]:
    """``simrun check SCENE ARGS`` in a child under RLIMIT_AS and RLIMIT_CPU: exit code, stderr, wall seconds."""
    limit = MEMORY_MB << 20

    def bound() -> None:  # pragma: no cover - runs in the child
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
        resource.setrlimit(resource.RLIMIT_CPU, (CPU_S, CPU_S))

    start = time.monotonic()
    done = subprocess.run(
        [str(SIMRUN), "check", str(scene), *args],
        capture_output=True,
        text=True,
        timeout=4 * CPU_S,
        preexec_fn=bound,
        env={**os.environ, "MUJOCO_GL": "egl", **(env or {})},
        stdin=subprocess.DEVNULL,
        check=False,
    )
    return done.returncode, done.stdout + done.stderr, time.monotonic() - start


@pytest.fixture(scope="module")
def benign_seconds(tmp_path_factory: pytest.TempPathFactory) -> float:
    """Wall time of a benign MJCF scene's ``simrun check`` here (start-up, compile, 1 s of steps)."""
    scene = _layout(tmp_path_factory.mktemp("benign"), _mesh_model("ok.obj"))
    code, output, seconds = _check(scene)
    assert code == 0, output
    return seconds


@pytest.mark.parametrize(("text", "args", "expected"), [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_hostile_mjcf_is_one_line_quickly(
    tmp_path: Path, benign_seconds: float, text: Callable[[Path], str], args: list[str], expected: list[str]
) -> None:
    if "pipe" in text(tmp_path) and not FIFO:
        pytest.skip("no FIFOs on this system")
    scene = _layout(tmp_path, text(tmp_path / "outside"))
    code, output, seconds = _check(scene, *args)
    assert "Traceback" not in output and "internal error" not in output, output
    assert code == 1, output
    lines = [line for line in output.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), output
    assert re.search(r"s\.toml:1: entities\[0\] 'r': \S*m\.xml:\d+: ", lines[0]), lines[0]
    for fragment in expected:
        assert fragment in lines[0], (fragment, lines[0])
    assert seconds < benign_seconds + SLACK_S, (seconds, benign_seconds)


def test_allowed_roots_load_what_they_allow(tmp_path: Path) -> None:
    """The mesh outside the scene loads with --allow-root, SIMRUN_ALLOW_ROOTS or the entity's allow_roots."""
    scene = _layout(tmp_path, _mesh_model("secret.obj", "<compiler meshdir='../outside'/>"))
    outside = tmp_path / "outside"
    assert _check(scene)[0] == 1
    code, output, _ = _check(scene, "--allow-root", str(outside))
    assert code == 0 and "1 meshes" in output, output
    code, output, _ = _check(scene, env={ALLOW_ROOTS_ENV: str(outside)})
    assert code == 0 and "1 meshes" in output, output
    scene.write_text(SCENE + 'allow_roots = ["../outside"]\n', encoding="utf-8")
    world = load_scene(scene)
    world.compile()
    assert outside / "secret.obj" in world.files_read()
    assert world.model.mesh_vertnum[0] == 8  # the paddle's vertices, as MuJoCo reads the file itself


@pytest.mark.parametrize("which", ["model", "include"])
def test_an_xml_file_over_the_size_limit_is_not_read(tmp_path: Path, benign_seconds: float, which: str) -> None:
    """A 64 MiB + 1 model or included file (sparse: nothing to read) is refused from its size, quickly."""
    scene = _layout(tmp_path, "<mujoco><include file='big.xml'/></mujoco>")
    big = scene.parent / ("m.xml" if which == "model" else "big.xml")
    with big.open("ab") as handle:
        handle.write(b"<mujoco>")
        handle.truncate(MAX_MJCF_BYTES + 1)
    code, output, seconds = _check(scene)
    lines = [line for line in output.splitlines() if line.strip()]
    assert code == 1 and len(lines) == 1 and lines[0].startswith("error: "), output
    if which == "model":  # MjcfRobot's own check, before the reader
        assert f"m.xml: {MAX_MJCF_BYTES + 1} bytes, over {MAX_MJCF_BYTES}" in lines[0], lines[0]
    else:  # the reader's bounded read (meshtool/files/safeopen.py rounds both sizes to MiB)
        assert "<include file='big.xml'>: cannot read" in lines[0] and "over the 64 MiB limit" in lines[0], lines[0]
    assert seconds < benign_seconds + SLACK_S, (seconds, benign_seconds)


def test_cli_names_the_readers_variable() -> None:
    from simrun.cli.main import ALLOW_ROOTS_ENV as CLI_NAME  # the CLI module imports no MuJoCo

    assert CLI_NAME == ALLOW_ROOTS_ENV


# -- what is opened ----------------------------------------------------------------------------------------------

_OPENED: list[str] = []
_RECORD = [False]


def _hook(event: str, args: tuple[object, ...]) -> None:
    if _RECORD[0] and event == "open" and args and isinstance(args[0], (str, bytes, os.PathLike)):
        _OPENED.append(os.fsdecode(args[0]))


sys.addaudithook(_hook)

#: The cases whose model names something that must never be opened: outside files, /proc, /dev, a FIFO.
_OPEN_CASES = [c for c in CASES if c[0].split("_")[0] in ("meshdir", "assetdir", "mesh", "include", "fifo", "zero")]


def _forbidden(tmp_path: Path) -> tuple[set[str], set[str]]:
    """Absolute paths and the names (an ``openat`` beside a folder descriptor shows the name alone)."""
    paths = {
        str(tmp_path / "outside" / "secret.obj"),
        "/proc/self/environ",
        "/dev/zero",
        str(tmp_path / "scene" / "pipe"),
    }
    return paths, {"secret.obj", "environ", "zero", "pipe"}


@pytest.mark.parametrize(("text", "args"), [c[1:3] for c in _OPEN_CASES], ids=[c[0] for c in _OPEN_CASES])
def test_audit_hook_sees_no_open_outside_the_root(tmp_path: Path, text: Callable[[Path], str], args: list[str]) -> None:
    """In-process: Python opens nothing outside the root and no FIFO while the hostile model is refused."""
    if "pipe" in text(tmp_path) and not FIFO:
        pytest.skip("no FIFOs on this system")
    scene = _layout(tmp_path, text(tmp_path / "outside"))
    paths, names = _forbidden(tmp_path)
    env = {ALLOW_ROOTS_ENV: args[1]} if args else {}
    saved = os.environ.get(ALLOW_ROOTS_ENV)
    os.environ.update(env)
    _OPENED.clear()
    _RECORD[0] = True
    try:
        with pytest.raises(EntityError):
            load_scene(scene).compile()
    finally:
        _RECORD[0] = False
        if env:
            os.environ.pop(ALLOW_ROOTS_ENV) if saved is None else os.environ.update({ALLOW_ROOTS_ENV: saved})
    assert any(p.endswith("m.xml") for p in _OPENED)  # the hook does see the reader's opens
    bad = [p for p in _OPENED if p in paths or os.path.basename(p) in names or p.startswith("/proc/")]
    assert not bad, bad


def _strace(tmp_path: Path, scene: Path, *args: str, calls: str = "open,openat,openat2") -> tuple[int, list[str]]:
    log = tmp_path / "strace.log"
    command = [STRACE or "strace", "-f", "-qq", "-e", f"trace={calls}", "-o", str(log)]
    done = subprocess.run(
        [*command, str(SIMRUN), "check", str(scene), *args],
        capture_output=True,
        text=True,
        timeout=600,
        env={**os.environ, "MUJOCO_GL": "egl"},
        stdin=subprocess.DEVNULL,
        check=False,
    )
    return done.returncode, log.read_text(encoding="utf-8", errors="replace").splitlines()


_CALL = re.compile(r'open(?:at2?)?\((?:(AT_FDCWD|\d+), )?"((?:[^"\\]|\\.)*)", ([A-Z_|]+)')


def _opens(lines: list[str]) -> list[tuple[str, str, str]]:
    """(folder descriptor, path, flags) of every open call strace logged."""
    return [(m[1] or "AT_FDCWD", m[2], m[3]) for m in map(_CALL.search, lines) if m]


@pytest.mark.skipif(STRACE is None, reason="strace is not installed (scripts/install_test_tools.sh installs it)")
@pytest.mark.parametrize(("text", "args"), [c[1:3] for c in _OPEN_CASES], ids=[c[0] for c in _OPEN_CASES])
def test_strace_sees_no_open_outside_the_root(tmp_path: Path, text: Callable[[Path], str], args: list[str]) -> None:
    """The whole command, MuJoCo's C code included, opens nothing outside the root and no FIFO."""
    if "pipe" in text(tmp_path) and not FIFO:
        pytest.skip("no FIFOs on this system")
    scene = _layout(tmp_path, text(tmp_path / "outside"))
    code, lines = _strace(tmp_path, scene, *args)
    assert code == 1
    opens = _opens(lines)
    assert any(path.endswith("m.xml") for _, path, _ in opens), lines[:20]  # strace did see the opens
    paths, names = _forbidden(tmp_path)
    bad = [o for o in opens if o[1] in paths or os.path.basename(o[1]) in names]
    assert not bad, bad


@pytest.mark.skipif(STRACE is None, reason="strace is not installed (scripts/install_test_tools.sh installs it)")
def test_strace_mujoco_opens_no_model_file(tmp_path: Path) -> None:
    """A benign model with includes, a mesh and a texture: every one of its files is opened by the reader only.

    All file system calls are traced (``%file``: opens, ``stat`` and the rest).
    The reader opens an included file or asset beside a folder descriptor with ``O_NOFOLLOW`` (``openat`` from
    the root); the main MJCF, named by the scene, with ``O_NONBLOCK``. MuJoCo's own ``fopen`` would show as an
    ``O_RDONLY`` open by path: there is none.
    """
    shutil.copytree(ROOT / "fixtures" / "mjcf" / "included", tmp_path / "arm")
    code, lines = _strace(tmp_path, tmp_path / "arm" / "swing.toml", calls="%file")
    assert code == 0, lines[-5:]
    looked_up = [line for line in lines if re.search(r'"(mjcf_arm_|options_|wheels_)\d', line)]
    assert not looked_up, looked_up  # MuJoCo looks no in-memory name up on disk either
    opens = _opens(lines)
    for name in ("assets.xml", "defaults.xml", "link.xml", "paddle.obj", "grid.png"):
        mine = [o for o in opens if os.path.basename(o[1]) == name]
        assert mine, name
        assert all(fd != "AT_FDCWD" and "O_NOFOLLOW" in flags for fd, _, flags in mine), mine
    main = [o for o in opens if o[1].endswith("robot.xml")]
    assert main and all("O_NONBLOCK" in flags for _, _, flags in main), main
