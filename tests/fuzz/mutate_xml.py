"""Mutators for XML mesh and robot formats (COLLADA, URDF, MJCF), built on the generic machinery of :mod:`mutate`.

COLLADA, URDF and MJCF are parsed as XML trees (attributes and number lists set to extremes, elements duplicated,
dropped or moved, ``instance_node`` cycles, deep chains, missing links, mimic cycles, ``package://`` variants;
MJCF's own operations: :mod:`mutate_mjcf`).
"""

from __future__ import annotations

import sys
from typing import Any

from hypothesis import strategies as st
from mutate import mutated_bytes

# -- XML (COLLADA, URDF): parsed, changed as a tree, written back -----------------------------------------------

XML_NUMBERS = ["-1", "-2147483648", "2147483647", "4294967296", "99999999999999999999", "nan", "inf", "-inf", "1e308",
               "0", "1.5", "", "x", "0x10"]  # fmt: skip
XML_TOKENS = [b"<!DOCTYPE x [<!ENTITY a 'aaaa'>]>", b"&a;", b"<![CDATA[", b"]]>", b"</", b"/>", b"<p>", b"</p>",
              b'count="-1"', b'url="#"', b"<node>", b"</node>"]  # fmt: skip


def local_name(tag: Any) -> str:
    """An element's tag without its ``{namespace}``."""
    return str(tag).rsplit("}", 1)[-1]


@st.composite
def mutated_xml(
    draw: Any,
    seed: bytes,
    attributes: dict[str, list[str]],
    special: Any = None,
    tokens: list[bytes] | None = None,
    special_weight: int = 1,
) -> bytes:
    """An XML document changed as a tree (attributes, number lists, elements duplicated, dropped or moved, and
    ``special(draw, root)`` format operations, ``special_weight`` in 7 + ``special_weight`` of the changes), or
    as bytes (1 in 5: token inserts from ``tokens``, default :data:`XML_TOKENS`, truncation).
    """
    import xml.etree.ElementTree as ET

    try:
        root = ET.fromstring(seed)
    except ET.ParseError:
        root = None
    if root is None or draw(st.integers(0, 4)) == 0:
        return bytes(draw(mutated_bytes(seed, tokens or XML_TOKENS)))
    if root.tag.startswith("{"):  # plain tags and an xmlns attribute: written back as the file had them
        namespace = root.tag[1:].split("}")[0]
        for element in root.iter():
            element.tag = local_name(element.tag)
        root.set("xmlns", namespace)
    limit = sys.getrecursionlimit()
    sys.setrecursionlimit(max(limit, 20000))  # deep chains are copied and written (recursively) here
    try:
        return _mutated_tree(draw, root, attributes, special, special_weight)
    finally:
        sys.setrecursionlimit(limit)


def _mutated_tree(draw: Any, root: Any, attributes: dict[str, list[str]], special: Any, weight: int = 1) -> bytes:
    import copy
    import xml.etree.ElementTree as ET

    for _ in range(draw(st.integers(1, 4))):
        elements = list(root.iter())
        parents = {child: parent for parent in elements for child in parent}
        element = draw(st.sampled_from(elements))
        ops = ["attribute", "attribute", "text", "text", "duplicate", "drop", "move"] + ["special"] * weight
        op = draw(st.sampled_from(ops))
        if op == "attribute" and element.attrib:
            name = draw(st.sampled_from(sorted(element.attrib)))
            ids = sorted({"#" + e.get("id", "") for e in elements if e.get("id")})
            pool = attributes.get(name, XML_NUMBERS) + (ids if name in ("url", "source", "target") else [])
            element.set(name, draw(st.sampled_from(pool)))
        elif op == "text" and (element.text or "").split():
            words = element.text.split() if element.text else []
            choice = draw(st.integers(0, 3))
            if choice == 0:
                words[draw(st.integers(0, len(words) - 1))] = draw(st.sampled_from(XML_NUMBERS))
            elif choice == 1:
                del words[draw(st.integers(0, len(words) - 1)) :]
            elif choice == 2:
                words *= draw(st.sampled_from([2, 100]))
            else:
                words = [draw(st.sampled_from(XML_NUMBERS))] * len(words)
            element.text = " ".join(words)
        elif op == "duplicate" and element in parents:
            parent = parents[element]
            parent.insert(list(parent).index(element), copy.deepcopy(element))
        elif op == "drop" and element in parents:
            parents[element].remove(element)
        elif op == "move" and element in parents:
            inside = set(element.iter())
            target = draw(st.sampled_from([e for e in elements if e not in inside]))
            parents[element].remove(element)
            target.append(element)
        elif op == "special" and special is not None:
            special(draw, root)
    return bytes(ET.tostring(root, encoding="utf-8", xml_declaration=True))


COLLADA_ATTRIBUTES: dict[str, list[str]] = {
    "count": ["-1", "0", "1", "2", "3", "4294967295", "99999999999", "x", ""],
    "stride": ["-1", "0", "1", "2", "4", "100", "4294967296", "x"],
    "offset": ["-1", "0", "1", "2", "3", "99", "x"],
    "set": ["-1", "0", "1", "99", "x"],
    "meter": ["0", "-1", "nan", "inf", "1e-300", "1e300", "x", ""],
    "url": ["#", "", "#missing", "missing.dae#x", "file:///etc/passwd"],
    "source": ["#", "", "#missing"],
    "target": ["#", "", "#missing"],
    "semantic": ["VERTEX", "POSITION", "NORMAL", "TEXCOORD", "COLOR", "TEXBINORMAL", "X", ""],
    "texture": ["", "missing", "paint-img"],
}


def collada_special(draw: Any, root: Any) -> None:
    """A node instanced inside itself or a descendant (a cycle), a negative index list, or an up axis."""
    import xml.etree.ElementTree as ET

    nodes = [e for e in root.iter() if local_name(e.tag) == "node"]
    op = draw(st.integers(0, 3))
    if op == 0 and nodes:  # <instance_node url="#n"/> inside n or under it: endless recursion if followed
        node = draw(st.sampled_from(nodes))
        if not node.get("id"):
            node.set("id", "fuzz-node")
        inside = [e for e in node.iter() if local_name(e.tag) == "node"]
        ET.SubElement(draw(st.sampled_from(inside)), "instance_node", url="#" + node.get("id", ""))
    elif op == 1:  # negative and out-of-range indices in a <p>
        lists = [e for e in root.iter() if local_name(e.tag) in ("p", "vcount", "v")]
        if lists:
            element = draw(st.sampled_from(lists))
            words = (element.text or "").split() or ["0"]
            words[draw(st.integers(0, len(words) - 1))] = draw(st.sampled_from(["-1", "-3", "65536", "2147483648"]))
            element.text = " ".join(words)
    elif op == 2:
        for e in root.iter():
            if local_name(e.tag) == "up_axis":
                e.text = draw(st.sampled_from(["X_UP", "Y_UP", "Z_UP", "W_UP", ""]))
    elif nodes:  # a deep chain of nested nodes
        parent = draw(st.sampled_from(nodes))
        for _ in range(draw(st.sampled_from([50, 1100]))):
            parent = ET.SubElement(parent, "node")
            ET.SubElement(parent, "matrix").text = "1 0 0 0 0 1 0 0 0 0 1 0.001 0 0 0 1"


URDF_NUMBERS = ["-1", "0", "nan", "-nan", "inf", "-inf", "1e308", "-1e308", "1e-320", "x", "", "1 2"]
URDF_VECTORS = ["nan 0 0", "inf inf inf", "1 2", "1 2 3 4", "", "1e308 1e308 1e308", "0 0 0", "-1 -1 -1", "a b c"]
URDF_ATTRIBUTES: dict[str, list[str]] = {
    "value": URDF_NUMBERS,
    "xyz": URDF_VECTORS,
    "rpy": URDF_VECTORS,
    "scale": [*URDF_VECTORS, "-1 1 1", "0.5 -0.5 0.5", "1e-300 1e-300 1e-300"],
    "type": ["revolute", "continuous", "prismatic", "fixed", "floating", "planar", "spherical", "", "x"],
    "name": ["", "world", "a b", "base_link", "x" * 300, "\u00e9", "shoulder"],
    "link": ["", "world", "nope", "base_link", "upper", "tool", "base", "arm"],
    "joint": ["", "nope", "shoulder", "elbow", "left_slide", "right_slide", "turn"],
    "multiplier": URDF_NUMBERS,
    "offset": URDF_NUMBERS,
    "rgba": ["nan 0 0 1", "1 1 1", "2 2 2 2", "", "-1 0 0 1"],
}
for _key in ("lower", "upper", "effort", "velocity", "damping", "friction", "radius", "length"):
    URDF_ATTRIBUTES[_key] = URDF_NUMBERS
for _key in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz"):
    URDF_ATTRIBUTES[_key] = URDF_NUMBERS
URDF_ATTRIBUTES["size"] = URDF_VECTORS


def urdf_mesh_names(package: str) -> list[str]:
    """``filename`` values for a package's meshes: ``package://`` forms, escapes, devices, odd schemes."""
    return [
        f"package://{package}/meshes/base.obj", "package:///meshes/base.obj", "package://unknown_pkg/meshes/x.stl",
        f"package://{package}/../secret.stl", f"package://{package}/meshes/", f"package://{package}",
        "package://", "package:///", "package:///../secret.stl", "../secret.stl", "../../secret.stl",
        "file:///etc/passwd", "file:///dev/zero", "/dev/zero", "/etc/passwd", "meshes/../../../../etc/passwd",
        f"package://{package}/meshes/upper%20arm.stl", f"package://{package}/meshes/fin.stl",
        f"package://{package}/meshes/painted.dae", f"package://{package}/meshes/knob.obj",
        f"package://{package}/meshes/link.obj", "http://example.com/x.stl", "x.off", "", "\x00",
        f"package://{package}/package.xml", f"package://{package}/urdf/" + "x" * 300 + ".stl",
    ]  # fmt: skip


def urdf_special(package: str) -> Any:
    """The URDF operations for a robot in ``package``: see :func:`urdf_operation`."""
    return lambda draw, root: urdf_operation(draw, root, package)


def urdf_operation(draw: Any, root: Any, package: str) -> None:
    """A deep chain, a joint naming a missing link or closing a loop, a mimic (cycle), a mass, a mesh path."""
    import xml.etree.ElementTree as ET

    links = [e for e in root if e.tag == "link"]
    joints = [e for e in root if e.tag == "joint"]
    names = [e.get("name", "") for e in links]
    op = draw(st.sampled_from(["chain", "missing", "loop", "mimic", "mimic_cycle", "mass", "mesh", "inertia"]))
    if op == "chain" and links:
        parent = draw(st.sampled_from(names))
        for k in range(draw(st.sampled_from([20, 200, 1100]))):
            ET.SubElement(root, "link", name=f"deep{k}")
            joint = ET.SubElement(root, "joint", name=f"deep_j{k}", type=draw(st.sampled_from(["revolute", "fixed"])))
            ET.SubElement(joint, "parent", link=parent)
            ET.SubElement(joint, "child", link=f"deep{k}")
            ET.SubElement(joint, "axis", xyz="0 0 1")
            ET.SubElement(joint, "limit", lower="-1", upper="1", effort="1", velocity="1")
            parent = f"deep{k}"
    elif op == "missing" and joints:
        joint = draw(st.sampled_from(joints))
        end = joint.find(draw(st.sampled_from(["parent", "child"])))
        if end is not None:
            end.set("link", draw(st.sampled_from(["nope", "", *names])))
        elif names:
            ET.SubElement(joint, "child", link=draw(st.sampled_from(names)))
    elif op == "loop" and joints and names:  # a joint back from the last child to the first parent
        child, parent = joints[-1].find("child"), joints[0].find("parent")
        loop = ET.SubElement(root, "joint", name="fuzz_loop", type="fixed")
        ET.SubElement(loop, "parent", link=names[-1] if child is None else child.get("link", ""))
        ET.SubElement(loop, "child", link=names[0] if parent is None else parent.get("link", ""))
    elif op in ("mimic", "mimic_cycle") and joints:
        a, b = draw(st.sampled_from(joints)), draw(st.sampled_from(joints))
        multiplier = draw(st.sampled_from(["1", "-1", "0", "nan", "inf", "1e308", "x"]))
        target = draw(st.sampled_from([b.get("name", ""), a.get("name", ""), "nope", ""]))
        ET.SubElement(a, "mimic", joint=target, multiplier=multiplier, offset=draw(st.sampled_from(URDF_NUMBERS)))
        if op == "mimic_cycle":
            ET.SubElement(b, "mimic", joint=a.get("name", ""))
    elif op in ("mass", "inertia") and links:
        link = draw(st.sampled_from(links))
        inertial = link.find("inertial")
        if inertial is None:
            inertial = ET.SubElement(link, "inertial")
        if op == "mass":
            mass = inertial.find("mass")
            if mass is None:
                mass = ET.SubElement(inertial, "mass")
            mass.set("value", draw(st.sampled_from(["-1", "0", "nan", "-nan", "inf", "-inf", "1e308", "1e-320", ""])))
        else:
            inertia = inertial.find("inertia")
            if inertia is None:
                inertia = ET.SubElement(inertial, "inertia")
            for key in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz"):
                inertia.set(key, draw(st.sampled_from(["0", "-1", "1", "nan", "1e308", "1e-320"])))
    elif op == "mesh":
        meshes = list(root.iter("mesh"))
        if meshes:
            draw(st.sampled_from(meshes)).set("filename", draw(st.sampled_from(urdf_mesh_names(package))))
