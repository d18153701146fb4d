"""Body poses of a recording, frame by frame, and the keyframes an animation needs to stay within an error bound.

:func:`read_tracks` replays a ``.simlog`` kinematically (each recorded state through ``mj_forward``) and
keeps every body's world pose (MuJoCo's ``xpos``, metres, and ``xquat``, w x y z, Z-up world frame). Memory:
56 bytes per body per frame (a 40 s run at 50 frames/s with 10 bodies: 1.1 MB).

:func:`keyframes` picks the frames an animation keeps. Without a rate, every recorded frame. With one
(``fps``), the frames nearest a grid of that rate, plus every frame needed so that linear interpolation
between kept frames (positions) and spherical linear interpolation (orientations, the shorter way, as glTF
and USD interpolate) stays within ``max_metres`` and ``max_radians`` of the recorded pose at every recorded
frame: a segment whose worst frame exceeds either bound is split at that frame until none does.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from simrun.errors import SimrunError
from simrun.record.simlog import Simlog, replay_states
from simrun.world.world import World

F64 = npt.NDArray[np.float64]
I64 = npt.NDArray[np.int64]

#: A body whose pose never moves further than this from its first frame (metres, radians) is static:
#: below the resolution of the float32 numbers glTF stores.
STILL = 1e-7


@dataclass(frozen=True)
class Tracks:
    """Every body's pose at every recorded frame.

    Attributes:
        times: (n,) frame times, seconds, increasing.
        positions: (n, nbody, 3) body origins in the world, metres (Z up).
        quats: (n, nbody, 4) body orientations, w x y z, each body's sign chosen so consecutive frames
            have a non-negative dot product (interpolation then takes the shorter way).
        frame_period: The recording's frame period, seconds.
    """

    times: F64
    positions: F64
    quats: F64
    frame_period: float

    def moving(self) -> list[int]:
        """Bodies whose pose changes during the recording (by more than :data:`STILL`)."""
        shift = np.linalg.norm(self.positions - self.positions[:1], axis=2).max(axis=0)
        turn = rotation_error(self.quats, np.broadcast_to(self.quats[:1], self.quats.shape)).max(axis=0)
        return [b for b in range(self.positions.shape[1]) if shift[b] > STILL or turn[b] > STILL]


def read_tracks(world: World, log: Simlog) -> Tracks:
    """Replay ``log`` in ``world`` (compiled from the recorded scene) and keep every body's pose per frame.

    Raises:
        SimrunError: The recording holds no frame (or is malformed: :class:`simrun.record.simlog.SimlogError`).
    """
    data = world.data
    times, positions, quats = [], [], []
    for t in replay_states(world, log):
        times.append(t)
        positions.append(np.array(data.xpos, dtype=np.float64))
        quats.append(np.array(data.xquat, dtype=np.float64))
    if not times:
        raise SimrunError(f"{log.path}: the recording holds no frame")
    q = np.array(quats)
    q /= np.linalg.norm(q, axis=2, keepdims=True)
    flips = np.cumsum(np.sum(q[1:] * q[:-1], axis=2) < 0, axis=0) % 2  # make consecutive frames agree in sign
    q[1:] *= np.where(flips[..., None] == 1, -1.0, 1.0)
    return Tracks(np.array(times), np.array(positions), q, log.frame_period)


def rotation_error(a: F64, b: F64) -> F64:
    """Angles (radians) between unit quaternions ``a`` and ``b`` (..., 4), either sign.

    ``4 atan2(|a - b|, |a + b|)`` with the signs aligned: well conditioned for small angles, where
    ``2 acos(a . b)`` loses half the digits.
    """
    sign = np.where(np.sum(a * b, axis=-1) < 0, -1.0, 1.0)[..., None]
    near, far = np.linalg.norm(a - sign * b, axis=-1), np.linalg.norm(a + sign * b, axis=-1)
    return np.asarray(4.0 * np.arctan2(near, far), dtype=np.float64)


def slerp(qa: F64, qb: F64, s: F64) -> F64:
    """Spherical linear interpolation from ``qa`` to ``qb`` (4,) at fractions ``s`` (m,), the shorter way."""
    d = float(np.dot(qa, qb))
    if d < 0:
        qb, d = -qb, -d
    theta = math.acos(min(d, 1.0))
    if theta < 1e-9:
        out = qa[None, :] + s[:, None] * (qb - qa)[None, :]
    else:
        sin = math.sin(theta)
        out = (np.sin((1 - s) * theta) / sin)[:, None] * qa + (np.sin(s * theta) / sin)[:, None] * qb
    return np.asarray(out / np.linalg.norm(out, axis=1, keepdims=True), dtype=np.float64)


def interpolation_error(times: F64, positions: F64, quats: F64, a: int, b: int) -> tuple[F64, F64]:
    """Position (metres) and orientation (radians) errors at frames a+1..b-1 when only a and b are kept."""
    s = (times[a + 1 : b] - times[a]) / (times[b] - times[a])
    lerp = positions[a] + s[:, None] * (positions[b] - positions[a])
    metres = np.linalg.norm(lerp - positions[a + 1 : b], axis=1)
    radians = rotation_error(slerp(quats[a], quats[b], s), quats[a + 1 : b])
    return np.asarray(metres, dtype=np.float64), radians


def keyframes(times: F64, positions: F64, quats: F64, fps: float | None, max_metres: float, max_radians: float) -> I64:
    """Indices of the frames to keep for one body (see the module); always the first and last frame.

    Args:
        times: (n,) frame times, seconds.
        positions: (n, 3) positions, metres.
        quats: (n, 4) orientations, w x y z, sign-continuous.
        fps: Target keyframe rate, per second; ``None`` keeps every frame.
        max_metres: Largest position error allowed between keyframes, metres (> 0).
        max_radians: Largest orientation error allowed between keyframes, radians (> 0).
    """
    n = len(times)
    if fps is None or n <= 2:
        return np.arange(n, dtype=np.int64)
    slot = np.floor((times - times[0]) * fps + 1e-6).astype(np.int64)
    keep = {0, n - 1, *np.flatnonzero(np.diff(slot) > 0) + 1}
    ordered = sorted(keep)
    pending = list(itertools.pairwise(ordered))
    while pending:
        a, b = pending.pop()
        if b - a < 2:
            continue
        metres, radians = interpolation_error(times, positions, quats, a, b)
        worst = np.maximum(metres / max_metres, radians / max_radians)
        k = int(np.argmax(worst))
        if worst[k] > 1.0:
            m = a + 1 + k
            keep.add(m)
            pending += [(a, m), (m, b)]
    return np.array(sorted(keep), dtype=np.int64)


def animation_keys(
    tracks: Tracks, fps: float | None = None, max_metres: float = 1e-3, max_radians: float = 1e-3
) -> dict[int, I64]:
    """The keyframe indices of every moving body (see :func:`keyframes`), by body id.

    Raises:
        SimrunError: A bound that is not a positive finite number, or a rate that is not positive.
    """
    for label, value in (("position error bound", max_metres), ("rotation error bound", max_radians)):
        if not (math.isfinite(value) and value > 0):
            raise SimrunError(f"the {label} must be a positive number, got {value}")
    if fps is not None and not (math.isfinite(fps) and fps > 0):
        raise SimrunError(f"the keyframe rate must be a positive number of frames per second, got {fps}")
    return {
        b: keyframes(tracks.times, tracks.positions[:, b], tracks.quats[:, b], fps, max_metres, max_radians)
        for b in tracks.moving()
    }
