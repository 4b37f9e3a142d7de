"""Penetration depths of the footprint in walls and boxes (the collision judge)."""

import math

import pytest
from rover_sim.geometry import box_overlap_depth, penetration_depths, rover_corners

from rover_sim import Box, WorldConfig


@pytest.mark.parametrize(
    ("pose", "box", "depth"),
    [
        ((50.0, 50.0, 0.0), Box(60.0, 50.0, 4.0, 4.0), 0.0),  # touching: front at 58
        ((50.0, 50.0, 0.0), Box(59.0, 50.0, 4.0, 4.0), 1.0),
        ((50.0, 50.0, math.pi / 2), Box(59.0, 50.0, 4.0, 4.0), 0.0),  # turned: front at 56
        ((50.0, 50.0, math.pi / 2), Box(57.0, 50.0, 4.0, 4.0), 1.0),
        ((50.0, 50.0, 0.0), Box(50.0, 50.0, 2.0, 2.0), 7.0),  # inside: out along y, 6 + 1
    ],
)
def test_box_overlap_depth(pose, box, depth):
    assert box_overlap_depth(pose, 16.0, 12.0, box) == pytest.approx(depth, abs=1e-9)


def test_diagonal_box_corner_overlap_matches_corner_geometry():
    pose = (50.0, 50.0, math.radians(45))
    corners = rover_corners(pose, 16.0, 12.0)
    xmax = corners[:, 0].max()
    box = Box(xmax + 2.0 - 0.5, 50.0, 4.0, 40.0)  # west face 0.5 left of the corner
    assert box_overlap_depth(pose, 16.0, 12.0, box) == pytest.approx(0.5)


def test_wall_depths_per_wall():
    cfg = WorldConfig.preset("exp1")
    assert penetration_depths((50.0, 50.0, 0.3), cfg) == (0.0, 0.0, 0.0, 0.0)
    d = penetration_depths((7.0, 95.0, 0.0), cfg)  # half-length 8, half-width 6
    assert d == pytest.approx((1.0, 0.0, 0.0, 1.0))
    d3 = penetration_depths((58.0, 50.0, 0.0), WorldConfig.preset("exp3"))
    assert len(d3) == 5 and d3[4] == pytest.approx(9.0)  # rover x 50..66, obstacle 51..59
