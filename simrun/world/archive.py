"""``.mjz`` archives: a world's MJCF with its in-memory assets, plus the compiled model for exact replay.

The zip holds what ``MjSpec.to_zip`` writes (the XML and the PNG textures) and ``model.mjb``, the compiled
binary model. :func:`load_mjz` loads the binary model, so a reloaded world steps bit-identically.
"""

from __future__ import annotations

import io
import zipfile
from pathlib import Path

import mujoco
import numpy as np

from simrun.errors import SimrunError
from simrun.outfile import write_bytes
from simrun.world.world import World

MJB = "model.mjb"


def mjz_bytes(world: World) -> bytes:
    """The archive of a world (compiled if needed)."""
    model, spec = world.model, world.spec
    buffer = io.BytesIO()
    mujoco.MjSpec.to_zip(spec, buffer)
    binary = np.zeros(mujoco.mj_sizeModel(model), dtype=np.uint8)
    mujoco.mj_saveModel(model, None, binary)
    with zipfile.ZipFile(buffer, "a", compression=zipfile.ZIP_DEFLATED) as archive:
        info = zipfile.ZipInfo(MJB, date_time=(1980, 1, 1, 0, 0, 0))
        archive.writestr(info, binary.tobytes())
    return buffer.getvalue()


def save_mjz(world: World, path: Path) -> None:
    """Write :func:`mjz_bytes` atomically."""
    write_bytes(path, mjz_bytes(world), world=world)


def load_mjz(path: Path) -> mujoco.MjModel:
    """The compiled model stored in an ``.mjz``.

    Raises:
        SimrunError: Not a zip, or no ``model.mjb`` in it.
    """
    try:
        with zipfile.ZipFile(path) as archive:
            binary = archive.read(MJB)
    except (OSError, zipfile.BadZipFile, KeyError) as exc:
        raise SimrunError(f"{path}: not an .mjz with {MJB} ({exc})") from None
    return mujoco.MjModel.from_binary_path(MJB, {MJB: binary})
