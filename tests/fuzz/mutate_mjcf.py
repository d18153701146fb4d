"""Mutators for MJCF models (MuJoCo's XML), built on :func:`mutate_xml.mutated_xml`.

An MJCF is changed as a tree (attributes set to extremes, elements duplicated, dropped or moved) and by the
operations of :func:`mjcf_operation`, which aim at what the project's MJCF reader (``simrun/robots/mjcf_read.py``)
must bound before MuJoCo sees the model: ``<include>`` and asset files that are devices, FIFOs, ``/proc``
files, symbolic links or paths outside the model's root (``@OUTSIDE@`` stands for an absolute folder outside
it; the target writes it in), ``<compiler>`` folders, self-includes, ``<replicate>``/``<composite>``/
``<flexcomp>`` counts, ``<size>`` values, height-field and texture sizes, deep body chains and many bodies,
free joints and mocap bodies away from the top, keyframes of the wrong length and NaN or infinite numbers.
"""

from __future__ import annotations

import copy
from typing import Any

from hypothesis import strategies as st
from mutate_xml import XML_NUMBERS, XML_TOKENS, mutated_xml

#: Where the target puts hostile files: ``pipe`` (a FIFO) and ``link.obj`` (a link to ``@OUTSIDE@/secret.obj``)
#: beside the model; ``@OUTSIDE@`` (replaced by the target) holds ``secret.obj``, outside the model's root.
MJCF_PATHS = [
    "/dev/zero", "/dev/stdin", "/dev/null", "/proc/self/environ", "/proc/self/mem", "/etc/passwd", "pipe",
    "link.obj", "../outside/secret.obj", "../../outside/secret.obj", "../../../outside/secret.obj",
    "@OUTSIDE@/secret.obj", "@OUTSIDE@", "/", ".", "..", "", " ", "x" * 300, "missing.stl", "meshes/",
    "a\\b.obj", "file:///etc/passwd", "\u00e9.obj", "m.xml",
]  # fmt: skip
MJCF_DIRS = ["/", "..", "../outside", "@OUTSIDE@", "/dev", "/proc/self", "pipe", "", ".", "meshes", "x" * 300]
MJCF_VECTORS = ["nan 0 0", "inf inf inf", "1e999 0 0", "1e308 1e308 1e308", "1 2", "1 2 3 4 5", "", "a b c",
                "0 0 0 0", "-1 -1 -1", "1e-320 0 0", "0 0 0"]  # fmt: skip
MJCF_COUNTS = ["-1", "0", "1", "3", "1000", "100000", "2147483647", "4294967296", "99999999999999999999", "1e3",
               "x", "", "100000 100000 1", "2000 2000 2000"]  # fmt: skip
_VECTOR_KEYS = (
    "pos euler axis xyaxes zaxis fromto gravity scale rgba quat axisangle size range ctrlrange forcerange friction "
    "solref solimp gear diaginertia fullinertia wind magnetic qpos qvel ctrl mpos mquat act vertex face user"
).split()
_COUNT_KEYS = (
    "count nrow ncol width height nkey nuserdata nuser_body nuser_geom nconmax njmax nstack maxhullvert condim "
    "group priority contype conaffinity"
).split()
MJCF_ATTRIBUTES: dict[str, list[str]] = {
    **dict.fromkeys(_VECTOR_KEYS, MJCF_VECTORS),
    **dict.fromkeys(_COUNT_KEYS, MJCF_COUNTS),
    "memory": ["-1", "0", "1K", "1M", "100G", "1T", "99999999999999E", "x", ""],
    "file": MJCF_PATHS,
    "meshdir": MJCF_DIRS,
    "texturedir": MJCF_DIRS,
    "assetdir": MJCF_DIRS,
    "type": [*"mesh hfield sdf plane box cube skybox 2d free ball hinge slide grid direct x".split(), ""],
    "angle": ["degree", "radian", "x", ""],
    "eulerseq": ["xyz", "XYZ", "zzz", "abc", "xy", ""],
    "builtin": ["checker", "gradient", "flat", "none", "x"],
    "mass": ["-1", "0", "nan", "inf", "1e308", "1e-320", "x"],
    "density": ["-1", "0", "nan", "1e308", "x"],
    "timestep": ["0", "-0.001", "1e-300", "1e300", "nan", "x"],
    "integrator": ["Euler", "RK4", "implicit", "implicitfast", "x"],
    "class": ["main", "missing", "", "a/b"],
    "childclass": ["main", "missing", ""],
    "name": ["", "world", "a/b", "/", "x" * 300, "\u00e9", "dup"],
    "mesh": ["missing", "", "dup"],
    "material": ["missing", ""],
    "texture": ["missing", ""],
    "joint": ["missing", "", "dup"],
    "body": ["world", "missing", ""],
    "mocap": ["true", "false", "x"],
    "inertiafromgeom": ["true", "false", "auto", "x"],
    "autolimits": ["true", "false", "x"],
    "strippath": ["true", "false", "x"],
    "limited": ["true", "false", "auto", "x"],
}
MJCF_TOKENS = [
    *XML_TOKENS, b"<include file='/dev/zero'/>", b"<include file='pipe'/>", b"<include file='m.xml'/>",
    b"<body>", b"</body>", b"<freejoint/>", b"<geom size='1'/>", b"<replicate count='100000'>", b"</replicate>",
    b"nan", b"inf", b"1e999", b"<compiler meshdir='/'/>",
]  # fmt: skip

_ASSETS = [
    ("mesh", "file"), ("texture", "file"), ("hfield", "file"), ("skin", "file"), ("texture", "fileright"),
    ("texture", "fileup"),
]  # fmt: skip


def mjcf_special(model_name: str) -> Any:
    """The MJCF operations for a model named ``model_name`` (its own file name: a self-include)."""
    return lambda draw, root: mjcf_operation(draw, root, model_name)


def _child(root: Any, tag: str) -> Any:
    import xml.etree.ElementTree as ET

    found = root.find(tag)
    return found if found is not None else ET.SubElement(root, tag)


def mjcf_operation(draw: Any, root: Any, model_name: str) -> None:
    """One MJCF-specific change of ``root`` (a ``<mujoco>`` element tree)."""
    import xml.etree.ElementTree as ET

    elements = list(root.iter())
    bodies = [e for e in elements if e.tag == "body"]
    worldbody = _child(root, "worldbody")
    op = draw(
        st.sampled_from(
            ["include", "asset", "asset", "compiler", "count", "size", "image", "chain", "many", "free", "mocap",
             "key", "file", "numbers", "dup_name", "option"]
        )
    )  # fmt: skip
    if op == "include":  # anywhere: a device, a FIFO, /proc, outside, itself
        target = draw(st.sampled_from(elements))
        name = draw(st.sampled_from([*MJCF_PATHS, model_name, model_name]))
        target.insert(draw(st.integers(0, len(target))), ET.Element("include", file=name))
    elif op == "asset":  # a new asset naming a hostile file, used by a geom
        tag, attr = draw(st.sampled_from(_ASSETS))
        asset = ET.SubElement(_child(root, "asset"), tag, name="fuzz_asset")
        asset.set(attr, draw(st.sampled_from(MJCF_PATHS)))
        if tag == "hfield":
            asset.set("size", "1 1 0.1 0.1")
        if tag == "texture":
            asset.set("type", draw(st.sampled_from(["2d", "cube", "skybox"])))
        body = ET.SubElement(worldbody, "body", name="fuzz_body")
        if tag in ("mesh", "hfield"):
            ET.SubElement(body if tag == "mesh" else worldbody, "geom", type=tag, **{tag: "fuzz_asset"})
        ET.SubElement(body, "geom", size="0.1")
    elif op == "compiler":
        compiler = _child(root, "compiler")
        key = draw(st.sampled_from(["meshdir", "texturedir", "assetdir", "angle", "strippath", "inertiafromgeom"]))
        compiler.set(key, draw(st.sampled_from(MJCF_ATTRIBUTES[key])))
    elif op == "count":  # what multiplies bodies and geoms
        tag = draw(st.sampled_from(["replicate", "composite", "flexcomp"]))
        count = draw(st.sampled_from(MJCF_COUNTS))
        parent = draw(st.sampled_from([worldbody, *bodies]))
        made = ET.SubElement(parent, tag, count=count)
        if tag == "replicate":
            made.set("offset", "0.1 0 0")
            ET.SubElement(ET.SubElement(made, "body"), "geom", size="0.05")
        elif tag == "composite":
            made.set("type", draw(st.sampled_from(["particle", "grid", "cable", "rope", "x"])))
            made.set("spacing", "0.05")
            ET.SubElement(made, "geom", size="0.01")
        else:
            made.set("type", draw(st.sampled_from(["grid", "box", "cylinder", "mesh", "direct", "x"])))
            made.set("name", "fuzz_flex")
            made.set("spacing", "0.05 0.05 0.05")
            if draw(st.booleans()):
                made.set("file", draw(st.sampled_from(MJCF_PATHS)))
    elif op == "size":
        size = _child(root, "size")
        key = draw(st.sampled_from(["nkey", "nuser_body", "nuser_geom", "nuserdata", "njmax", "nconmax", "memory"]))
        size.set(key, draw(st.sampled_from(MJCF_ATTRIBUTES[key])))
    elif op == "image":  # an element asking MuJoCo for a large buffer by its attributes alone
        asset = _child(root, "asset")
        big = draw(st.sampled_from(["100000", "65536", "20000", "-1", "0", "4294967296"]))
        if draw(st.booleans()):
            ET.SubElement(asset, "hfield", name="fuzz_h", nrow=big, ncol=big, size="1 1 0.1 0.1")
            ET.SubElement(worldbody, "geom", type="hfield", hfield="fuzz_h")
        else:
            kind = draw(st.sampled_from(["2d", "cube", "skybox"]))
            ET.SubElement(asset, "texture", name="fuzz_t", type=kind, builtin="checker", width=big, height=big)
            ET.SubElement(asset, "material", name="fuzz_m", texture="fuzz_t")
            ET.SubElement(worldbody, "geom", size="0.1", material="fuzz_m")
    elif op == "chain":  # bodies nested deep, around the reader's depth limit
        parent = draw(st.sampled_from([worldbody, *bodies]))
        for _ in range(draw(st.sampled_from([10, 200, 470, 600]))):
            parent = ET.SubElement(parent, "body", pos="0 0 0.01")
            ET.SubElement(parent, "geom", size="0.01")
    elif op == "many" and bodies:  # one body repeated, around the body limit
        body = draw(st.sampled_from(bodies))
        parent = next((e for e in elements if body in list(e)), worldbody)
        size = sum(1 for _ in body.iter())
        for _ in range(min(draw(st.sampled_from([2, 30, 600])), max(2, 60_000 // size))):  # a few MB at most
            parent.append(copy.deepcopy(body))
    elif op == "free" and bodies:  # a free joint below the top (MuJoCo refuses it) or on a welded model
        body = draw(st.sampled_from(bodies))
        ET.SubElement(body, draw(st.sampled_from(["freejoint", "joint"])), type="free")
    elif op == "mocap" and bodies:
        draw(st.sampled_from(bodies)).set("mocap", "true")
    elif op == "key":
        key = ET.SubElement(_child(root, "keyframe"), "key", name=draw(st.sampled_from(["", "home", "a/b"])))
        attr = draw(st.sampled_from(["qpos", "qvel", "ctrl", "act", "mpos", "mquat", "time"]))
        key.set(attr, draw(st.sampled_from([*MJCF_VECTORS, " ".join(["0"] * 500), "0", "nan"])))
    elif op == "file":  # an existing file attribute (or an include's) pointed somewhere hostile
        named = [(e, a) for e in elements for a in e.attrib if a.startswith("file") or a.endswith("dir")]
        if named:
            element, attr = draw(st.sampled_from(named))
            element.set(attr, draw(st.sampled_from(MJCF_DIRS if attr.endswith("dir") else MJCF_PATHS)))
    elif op == "numbers":  # a number attribute set to a NaN, an infinity or an overflow
        numeric = [(e, a) for e in elements for a in e.attrib if a in MJCF_ATTRIBUTES and a not in ("file", "name")]
        if numeric:
            element, attr = draw(st.sampled_from(numeric))
            element.set(attr, draw(st.sampled_from(["nan", "-nan", "inf", "-inf", "1e999", "NaN 0 0", "0 inf 0"])))
    elif op == "dup_name":  # two elements of a kind with one name
        named = [e for e in elements if e.get("name")]
        if len(named) > 1:
            a, b = draw(st.sampled_from(named)), draw(st.sampled_from(named))
            b.set("name", a.get("name", ""))
    elif op == "option":
        option = _child(root, "option")
        key = draw(st.sampled_from(["timestep", "gravity", "integrator", "wind", "magnetic"]))
        option.set(key, draw(st.sampled_from(MJCF_ATTRIBUTES.get(key, XML_NUMBERS))))


@st.composite
def mutated_mjcf(draw: Any, seed: bytes, model_name: str) -> bytes:
    """An MJCF document changed as a tree (with :func:`mjcf_operation`) or, 1 in 5, as bytes."""
    return bytes(draw(mutated_xml(seed, MJCF_ATTRIBUTES, mjcf_special(model_name), MJCF_TOKENS, special_weight=7)))
