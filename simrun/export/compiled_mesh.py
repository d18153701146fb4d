"""Mesh data of a compiled MuJoCo model, as arrays (shared by the USD and GLB exporters)."""

from __future__ import annotations

import mujoco
import numpy as np
import numpy.typing as npt


def compiled_mesh(model: mujoco.MjModel, mesh_id: int) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.int64]]:
    """Vertices ((n, 3) metres, in the mesh frame MuJoCo centred and aligned) and triangles ((k, 3))."""
    v0, nv = int(model.mesh_vertadr[mesh_id]), int(model.mesh_vertnum[mesh_id])
    f0, nf = int(model.mesh_faceadr[mesh_id]), int(model.mesh_facenum[mesh_id])
    vertices = np.asarray(model.mesh_vert[v0 : v0 + nv], dtype=np.float64)
    faces = np.asarray(model.mesh_face[f0 : f0 + nf], dtype=np.int64)
    return vertices, faces
