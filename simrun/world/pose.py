"""Poses: position in metres and orientation as a unit quaternion (w, x, y, z), MuJoCo's order."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from simrun.errors import PoseError


@dataclass(frozen=True, slots=True)
class Pose:
    """A rigid transform relative to the parent (the world for top-level entities).

    Attributes:
        position: (x, y, z) metres.
        orientation: Unit quaternion (w, x, y, z).
    """

    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    orientation: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        position, orientation = self.position, self.orientation
        if len(position) != 3 or len(orientation) != 4:
            raise PoseError("a pose needs a 3-vector position and a 4-vector (w, x, y, z) orientation")
        # one float() per value (worlds of thousands of entities builds thousands of poses)
        px, py, pz = float(position[0]), float(position[1]), float(position[2])
        w, x, y, z = float(orientation[0]), float(orientation[1]), float(orientation[2]), float(orientation[3])
        # v - v is 0.0 for every finite v and NaN for inf/NaN: the sum is 0.0 exactly when all seven are finite
        if px - px + py - py + pz - pz + w - w + x - x + y - y + z - z != 0.0:
            raise PoseError("pose values must be finite numbers")
        norm = math.sqrt(w * w + x * x + y * y + z * z)
        if abs(norm - 1.0) > 1e-6:
            raise PoseError(f"orientation must be a unit quaternion (norm {norm:.6g})")
        object.__setattr__(self, "position", (px, py, pz))
        object.__setattr__(self, "orientation", (w, x, y, z))

    @classmethod
    def look_at(cls, eye: tuple[float, float, float], target: tuple[float, float, float]) -> Pose:
        """A camera pose at ``eye`` looking at ``target`` with +Z up (MuJoCo cameras look along -Z)."""
        e, t = np.asarray(eye, float), np.asarray(target, float)
        forward = t - e
        if np.linalg.norm(forward) == 0:
            raise PoseError("eye and target coincide")
        z = -forward / np.linalg.norm(forward)
        x = np.cross([0.0, 0.0, 1.0], z)
        if np.linalg.norm(x) < 1e-9:
            x = np.array([1.0, 0.0, 0.0])
        x /= np.linalg.norm(x)
        y = np.cross(z, x)
        position = (float(e[0]), float(e[1]), float(e[2]))
        return cls(position, _quat_from_matrix(np.stack([x, y, z], axis=1)))


def _quat_from_matrix(r: np.ndarray) -> tuple[float, float, float, float]:
    w = math.sqrt(max(0.0, 1 + r[0, 0] + r[1, 1] + r[2, 2])) / 2
    x = math.copysign(math.sqrt(max(0.0, 1 + r[0, 0] - r[1, 1] - r[2, 2])) / 2, r[2, 1] - r[1, 2])
    y = math.copysign(math.sqrt(max(0.0, 1 - r[0, 0] + r[1, 1] - r[2, 2])) / 2, r[0, 2] - r[2, 0])
    z = math.copysign(math.sqrt(max(0.0, 1 - r[0, 0] - r[1, 1] + r[2, 2])) / 2, r[1, 0] - r[0, 1])
    n = math.sqrt(w * w + x * x + y * y + z * z)
    return (w / n, x / n, y / n, z / n)
