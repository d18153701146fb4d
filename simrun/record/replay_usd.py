"""Animated USD of a recording: the static USD export with time samples on each moving body's transform.

The stage is :mod:`simrun.export.usd`'s, physics schemas and all, decorated through the project's one USD
writer (:meth:`~meshtool.export.usd_write.UsdBuilder.timeline` and
:meth:`~meshtool.export.usd_write.UsdBuilder.sample_pose`).

Each body prim's ``xformOp:translate`` (double3, metres) and ``xformOp:orient`` (quatd, w x y z) get one
time sample per keyframe (:func:`simrun.record.replay_tracks.animation_keys`); the stage's
``timeCodesPerSecond`` and ``framesPerSecond`` are the recording's frame rate (1 / frame period), so time
code ``c`` is ``c / timeCodesPerSecond`` seconds of the recording, and ``startTimeCode``/``endTimeCode``
span it. USD interpolates translations linearly and orientations spherically, as the keyframe bound
assumes. Static bodies keep the static export's default pose, or, when the recording holds them
elsewhere, one time sample at the start with that pose. The default (untimed) values stay the bodies'
poses at ``qpos0``, the frame the joints are defined in. Z-up, metres.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import numpy.typing as npt

from meshtool.export.usd_write import UsdBuilder
from simrun.export.usd import export_world_usd
from simrun.record.replay_tracks import I64, STILL, Tracks, rotation_error
from simrun.world.world import World


def time_codes_per_second(frame_period: float) -> float:
    """The recording's frame rate (a whole number when it is one to 1e-9)."""
    rate = 1.0 / frame_period
    return float(round(rate)) if abs(rate - round(rate)) < 1e-9 else rate


def time_code(seconds: float, per_second: float) -> float:
    """The time code of a recording time (rounded to 1e-6, so frame k of a 50 Hz run is code k exactly)."""
    return round(seconds * per_second, 6)


def export_recording_usd(
    world: World, tracks: Tracks, keys: dict[int, I64], out: Path, alive: npt.NDArray[np.bool_] | None = None
) -> None:
    """Write the animated stage (see the module) to ``out`` (``.usd``, ``.usda`` or ``.usdc``).

    Args:
        world: The compiled world the recording was replayed in.
        tracks: Every body's pose per frame (:func:`simrun.record.replay_tracks.read_tracks`).
        keys: Keyframe indices per moving body.
        out: The output file.
        alive: (frames, bodies) whether each body exists at each frame (an edited recording's,
            :mod:`simrun.record.replay_edits`): a body that does not exist throughout gets ``visibility``
            time samples, ``invisible`` outside its lifetime and ``inherited`` inside (held, not interpolated).

    Raises:
        SimrunError: An unsupported extension or a failed write.
    """

    def decorate(usd: UsdBuilder, paths: dict[int, str]) -> None:
        from pxr import UsdGeom

        rate = time_codes_per_second(tracks.frame_period)
        usd.timeline(rate, time_code(float(tracks.times[0]), rate), time_code(float(tracks.times[-1]), rate))
        for b, path in sorted(paths.items()):
            if b == 0:
                continue
            prim = usd.stage.GetPrimAtPath(path)
            if alive is not None and not alive[:, b].all():
                life = alive[:, b]
                visibility = UsdGeom.Imageable(prim).CreateVisibilityAttr()
                for k in [0, *(np.flatnonzero(life[1:] != life[:-1]) + 1).tolist()]:
                    shown = UsdGeom.Tokens.inherited if life[k] else UsdGeom.Tokens.invisible
                    visibility.Set(shown, time_code(float(tracks.times[k]), rate))
            frames = keys.get(b)
            if frames is None:
                translate, orient = UsdGeom.Xformable(prim).GetOrderedXformOps()[:2]
                held = orient.Get()
                here = np.array([held.GetReal(), *held.GetImaginary()], dtype=np.float64)
                moved = np.linalg.norm(np.array(translate.Get()) - tracks.positions[0, b]) > STILL
                if not moved and rotation_error(here, tracks.quats[0, b]) <= 1e-6:
                    continue
                frames = np.array([0], dtype=np.int64)
            for k in frames.tolist():
                code = time_code(float(tracks.times[k]), rate)
                usd.sample_pose(prim, code, tracks.positions[k, b], tracks.quats[k, b])

    export_world_usd(world, out, decorate)
