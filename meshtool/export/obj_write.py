"""OBJ writer for :class:`meshtool.repair.mesh.TriMesh`: deterministic text, one ``usemtl`` run per material."""

from __future__ import annotations

import numpy as np

from meshtool.repair.mesh import TriMesh


def format_obj(mesh: TriMesh, material_names: list[str], mtl_file: str | None, header: str) -> str:
    """Write a mesh as OBJ text.

    Numbers use the shortest text that reads back to the same float64 (``repr``), so writing, reading and
    writing again gives identical text. Triangles are written in mesh order; a ``usemtl`` starts each
    material run and ``g`` each part run (omitted when the only part is ``default``).

    Args:
        mesh: The mesh, already in output units and axes.
        material_names: Output name of each material index.
        mtl_file: File name for ``mtllib``, or ``None`` to write no materials.
        header: Text of the first comment line.

    Returns:
        OBJ text with LF line endings and a final newline.
    """
    out = [f"# {header}"]
    if mtl_file is not None:
        out.append(f"mtllib {mtl_file}")
    positions = mesh.positions + 0.0  # no negative zeros
    if mesh.colors is not None:
        rows = np.concatenate([positions, mesh.colors + 0.0], axis=1).tolist()
        out.extend("v %r %r %r %r %r %r" % tuple(r) for r in rows)
    else:
        out.extend("v %r %r %r" % tuple(r) for r in positions.tolist())
    out.extend("vt %r %r" % tuple(r) for r in (mesh.texcoords + 0.0).tolist())
    out.extend("vn %r %r %r" % tuple(r) for r in (mesh.normals + 0.0).tolist())

    m = mesh.faces.shape[0]
    text = np.empty(m, dtype=object)
    v = mesh.faces + 1
    t = mesh.face_uv + 1
    n = mesh.face_normal + 1
    has_t = mesh.face_uv[:, 0] >= 0 if m else np.zeros(0, dtype=bool)
    has_n = mesh.face_normal[:, 0] >= 0 if m else np.zeros(0, dtype=bool)
    forms = (
        (~has_t & ~has_n, "f %d %d %d", [v]),
        (has_t & ~has_n, "f %d/%d %d/%d %d/%d", [v, t]),
        (~has_t & has_n, "f %d//%d %d//%d %d//%d", [v, n]),
        (has_t & has_n, "f %d/%d/%d %d/%d/%d %d/%d/%d", [v, t, n]),
    )
    for mask, template, arrays in forms:
        idx = np.flatnonzero(mask)
        if idx.size:
            rows = np.stack([a[idx] for a in arrays], axis=2).reshape(idx.size, -1).tolist()
            text[idx] = [template % tuple(r) for r in rows]

    show_parts = len(set(mesh.face_part.tolist())) > 1 or any(
        mesh.part_names[p] != "default" for p in set(mesh.face_part.tolist())
    )
    current_material, current_part = -1, -1
    materials = mesh.face_material.tolist()
    parts = mesh.face_part.tolist()
    for k in range(m):
        if materials[k] != current_material:
            current_material, current_part = materials[k], -1
            if mtl_file is not None:
                out.append(f"usemtl {material_names[current_material]}")
        if parts[k] != current_part:
            current_part = parts[k]
            if show_parts:
                out.append(f"g {mesh.part_names[current_part]}")
        out.append(text[k])
    return "\n".join(out) + "\n"
