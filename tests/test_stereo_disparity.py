"""The stereo rig against the pinhole model: disparity = f B / Z, from the seed's numbers, not the rig's.

The seed's stereo camera: two 320 x 240 images, 30 degrees across the width, 0.10 m baseline. A matte plate
faces the rig at 0.5, 1 and 2 m; its image centre (the coverage-weighted column of its pixels, anti-aliased
edges included) is found in each eye, and the difference must equal f B / Z within 0.2 pixel with
f = (320 / 2) / tan(30 / 2 degrees).
"""

import math

import numpy as np
import pytest
from conftest import needs_gl

from simrun import Box, EntityError, Pose, World
from simrun.sensors.cameras import StereoCamera, StereoRig

SEED_WIDTH, SEED_HEIGHT, SEED_FOV, SEED_BASELINE = 320, 240, 30.0, 0.10


def test_stereo_rig_defaults_are_the_seeds_and_the_field_of_view_spans_the_width():
    rig = StereoRig(name="eyes")
    assert (rig.resolution, rig.fov, rig.fov_axis, rig.baseline) == ((320, 240), 30.0, "horizontal", 0.10)
    world = World()
    world.insert(rig)
    model = world.model
    fovy = model.camera("eyes/left").fovy[0]
    # 30 degrees across 320 pixels -> the vertical angle across 240 pixels of the same focal length
    assert math.tan(math.radians(fovy) / 2) * SEED_WIDTH / SEED_HEIGHT == pytest.approx(
        math.tan(math.radians(SEED_FOV) / 2), rel=1e-12
    )
    vertical = World()
    vertical.insert(StereoRig(name="eyes", fov=30.0, fov_axis="vertical"))
    assert vertical.model.camera("eyes/left").fovy[0] == pytest.approx(30.0)
    for bad, match in (({"fov_axis": "diagonal"}, "fov_axis"), ({"fov": 180.0}, "fov"), ({"fov": -1.0}, "fov")):
        broken = World()
        broken.insert(StereoRig(name="x", **bad))
        with pytest.raises(EntityError, match=match):
            broken.compile()


def _plate_centre(rgb):
    """Column of the red plate's centre, pixels from the image's left edge (coverage-weighted)."""
    red = rgb[..., 0].astype(float) - rgb[..., 2].astype(float)  # the plate is red, the sky is not
    inside = np.median(red[red > 0.8 * red.max()])
    coverage = np.clip(red / inside, 0.0, 1.0)
    coverage[coverage < 0.02] = 0.0
    columns = np.arange(rgb.shape[1]) + 0.5
    return float((coverage * columns).sum() / coverage.sum())


@needs_gl
@pytest.mark.parametrize("depth", [0.5, 1.0, 2.0])
def test_disparity_of_a_plate_matches_f_b_over_z(depth):
    world = World()
    world.insert(StereoRig(name="eyes", pose=Pose((0.0, 0.0, 1.0))))
    size = 0.06 * depth  # about 20 % of the view at every depth
    plate = Box(name="plate", dimensions=(0.002, size, size), color=(1.0, 0.0, 0.0, 1.0))
    plate.pose = Pose((depth + 0.001, 0.0, 1.0))  # its front face at `depth` from the eyes
    world.insert(plate)
    stereo = StereoCamera(world, "eyes", rate=0)
    world.step(1)
    frame = stereo.reading
    assert frame.left.rgb.shape == (SEED_HEIGHT, SEED_WIDTH, 3)
    disparity = _plate_centre(frame.left.rgb) - _plate_centre(frame.right.rgb)
    focal = (SEED_WIDTH / 2) / math.tan(math.radians(SEED_FOV) / 2)
    assert disparity == pytest.approx(focal * SEED_BASELINE / depth, abs=0.2)
