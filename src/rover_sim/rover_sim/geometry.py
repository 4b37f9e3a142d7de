"""Plane geometry of the world in u: the rover rectangle, penetration depths, poses."""

from __future__ import annotations

import math

import numpy as np

from rover_sim.config import Box, WorldConfig
from rover_sim.errors import RoverSimError

Pose = tuple[float, float, float]
"""(x, y, theta): centre in u, heading in radians (ccw from the room's x axis)."""

_CORNER_SIGNS = np.array([[1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]])


def wrap_angle(a: float) -> float:
    """Angle wrapped into [-pi, pi)."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def rover_corners(pose: Pose, length: float, width: float) -> np.ndarray:
    """The four corners (4 x 2, u) of the rover footprint at `pose`."""
    x, y, th = pose
    c, s = math.cos(th), math.sin(th)
    local = _CORNER_SIGNS * (length / 2.0, width / 2.0)
    rot = np.array([[c, -s], [s, c]])
    return local @ rot.T + (x, y)


def box_overlap_depth(pose: Pose, length: float, width: float, box: Box) -> float:
    """Separating-axis overlap of the rover footprint at `pose` and an axis-aligned box, u.

    0 when they do not overlap, else the smallest overlap over the four axes (how far
    the rover would have to move to get clear). Pure Python: it runs every tick.
    """
    x, y, th = pose
    c, s = math.cos(th), math.sin(th)
    hl, hw = length / 2.0, width / 2.0
    # rover extents along the room axes, box extents along the rover axes
    ex = abs(c) * hl + abs(s) * hw
    ey = abs(s) * hl + abs(c) * hw
    bx, by = box.sx / 2.0, box.sy / 2.0
    dx, dy = box.cx - x, box.cy - y
    fx = ex + bx - abs(dx)
    fy = ey + by - abs(dy)
    fu = hl + abs(c) * bx + abs(s) * by - abs(c * dx + s * dy)
    fv = hw + abs(s) * bx + abs(c) * by - abs(-s * dx + c * dy)
    m = min(fx, fy, fu, fv)
    return m if m > 0.0 else 0.0


def penetration_depths(pose: Pose, config: WorldConfig) -> tuple[float, ...]:
    """How deep the rover footprint is in each wall (W, E, S, N) and each obstacle, u."""
    x, y, th = pose
    c, s = abs(math.cos(th)), abs(math.sin(th))
    hl, hw = config.rover_length / 2.0, config.rover_width / 2.0
    ex = c * hl + s * hw
    ey = s * hl + c * hw
    size = config.room_size
    walls = (
        max(0.0, ex - x),
        max(0.0, x + ex - size),
        max(0.0, ey - y),
        max(0.0, y + ey - size),
    )
    if not config.obstacles:
        return walls
    return walls + tuple(
        box_overlap_depth(pose, config.rover_length, config.rover_width, b)
        for b in config.obstacles
    )


def deeper(after: tuple[float, ...], before: tuple[float, ...], eps: float = 1e-9) -> bool:
    """True when any depth in `after` exceeds its counterpart in `before` by more than eps."""
    return any(a > b + eps for a, b in zip(after, before, strict=True))


def pose_is_free(pose: Pose, config: WorldConfig, margin: float = 0.0) -> bool:
    """True when the whole rover lies at least `margin` inside walls and off obstacles."""
    corners = rover_corners(pose, config.rover_length, config.rover_width)
    if corners.min() < margin or corners.max() > config.room_size - margin:
        return False
    for box in config.obstacles:
        grown = Box(box.cx, box.cy, box.sx + 2 * margin, box.sy + 2 * margin)
        if box_overlap_depth(pose, config.rover_length, config.rover_width, grown) > 0.0:
            return False
    return True


def footprint_distance(
    pose: Pose, point: tuple[float, float], length: float, width: float
) -> float:
    """Distance from `point` to the rover footprint at `pose` (0 when inside), u."""
    x, y, th = pose
    dx, dy = point[0] - x, point[1] - y
    c, s = math.cos(th), math.sin(th)
    lx, ly = c * dx + s * dy, -s * dx + c * dy
    ox = max(abs(lx) - length / 2.0, 0.0)
    oy = max(abs(ly) - width / 2.0, 0.0)
    return math.hypot(ox, oy)


def sample_goal(rng: np.random.Generator, config: WorldConfig) -> tuple[float, float]:
    """The trial's goal: the fixed one, else uniform in the central goal_region square."""
    if config.goal is not None:
        return config.goal
    lo = (config.room_size - config.goal_region) / 2.0
    gx, gy = rng.uniform(lo, lo + config.goal_region, size=2)
    return float(gx), float(gy)


def sample_pose(
    rng: np.random.Generator,
    config: WorldConfig,
    goal: tuple[float, float],
    max_tries: int = 10000,
) -> Pose:
    """A uniformly random free pose (whole rover in the room, off obstacles) outside the
    goal, with a uniformly random heading. "Outside the goal" means the whole footprint
    is off the goal circle when `WorldConfig.start_clear_of_goal`, else only the centre."""
    half = min(config.rover_length, config.rover_width) / 2.0
    for _ in range(max_tries):
        x, y = rng.uniform(half, config.room_size - half, size=2)
        th = float(rng.uniform(-math.pi, math.pi))
        pose = (float(x), float(y), th)
        if math.hypot(x - goal[0], y - goal[1]) <= config.goal_radius:
            continue
        if config.start_clear_of_goal and (
            footprint_distance(pose, goal, config.rover_length, config.rover_width)
            <= config.goal_radius
        ):
            continue
        if pose_is_free(pose, config, config.start_margin):
            return pose
    raise RoverSimError(f"no free start pose found in {max_tries} draws for config {config!r}")
