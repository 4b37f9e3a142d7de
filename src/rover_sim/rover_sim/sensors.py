"""Sensors: the goal sensor (analytic, from the base pose) and the six-sector range sensor
(pybullet ray casts).

Sectors (angles ccw from the rover's forward x axis, each 60 degrees wide):

====  ===========  ================
 k    name         angles (deg)
====  ===========  ================
 0    front        -30 .. +30
 1    front-left   +30 .. +90
 2    rear-left    +90 .. +150
 3    rear         +150 .. +210
 4    rear-right   -150 .. -90
 5    front-right  -90 .. -30
====  ===========  ================

A sector's reading is the distance from the rover centre to the nearest wall or obstacle
point hit by any of its rays (``rays_per_sector`` rays evenly spread over the sector, both
edges included), in u, rounded to float32.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from rover_sim.config import UNIT_M

SECTOR_NAMES: tuple[str, ...] = (
    "front",
    "front-left",
    "rear-left",
    "rear",
    "rear-right",
    "front-right",
)
N_SECTORS: int = 6
SECTOR_WIDTH: float = 2.0 * math.pi / N_SECTORS


def sector_bounds(k: int) -> tuple[float, float]:
    """(start, end) angles of sector k in radians, rover frame, ccw from forward."""
    centre = k * SECTOR_WIDTH
    return centre - SECTOR_WIDTH / 2.0, centre + SECTOR_WIDTH / 2.0


def sector_of_angle(angle: float) -> int:
    """The sector holding a rover-frame bearing (radians); edges go to the ccw sector."""
    a = (angle + SECTOR_WIDTH / 2.0) % (2.0 * math.pi)
    return int(a // SECTOR_WIDTH) % N_SECTORS


def goal_sensor(
    pose: tuple[float, float, float],
    goal: tuple[float, float],
    rotation_deg: float = 0.0,
) -> tuple[float, float]:
    """Goal (x, y) in the rover frame (x forward, y left), u; the heading fault rotates the
    reading by `rotation_deg` counter-clockwise."""
    dx, dy = goal[0] - pose[0], goal[1] - pose[1]
    a = -pose[2] + math.radians(rotation_deg)
    c, s = math.cos(a), math.sin(a)
    return c * dx - s * dy, s * dx + c * dy


class RangeSensor:
    """Six-sector obstacle range sensor cast with one ``rayTestBatch`` per reading."""

    def __init__(
        self,
        client: Any,
        rays_per_sector: int,
        max_range: float,
        height_m: float,
    ) -> None:
        self._client = client
        self._max_range = float(max_range)
        self._height = float(height_m)
        per = rays_per_sector - 1
        n = N_SECTORS * per
        self._angles = -SECTOR_WIDTH / 2.0 + np.arange(n) * (SECTOR_WIDTH / per)
        # sector k uses rays k*per .. k*per+per (the last one shared with sector k+1)
        self._index = (np.arange(N_SECTORS)[:, None] * per + np.arange(per + 1)) % n

    @property
    def ray_angles(self) -> np.ndarray:
        """Rover-frame bearings of all rays, radians."""
        return self._angles.copy()

    def read(self, pose: tuple[float, float, float]) -> np.ndarray:
        """Six ranges in u (float64 holding float32 values), sector order as SECTOR_NAMES."""
        x, y, th = pose
        a = self._angles + th
        reach = self._max_range * UNIT_M
        ox, oy, z = x * UNIT_M, y * UNIT_M, self._height
        ends = np.empty((len(a), 3))
        ends[:, 0] = ox + np.cos(a) * reach
        ends[:, 1] = oy + np.sin(a) * reach
        ends[:, 2] = z
        hits = self._client.rayTestBatch([(ox, oy, z)] * len(a), ends.tolist())
        # a miss reports fraction 1.0, i.e. max_range
        frac = np.fromiter((h[2] for h in hits), dtype=np.float64, count=len(a))
        ranges = (frac * self._max_range)[self._index].min(axis=1)
        return ranges.astype(np.float32).astype(np.float64)
