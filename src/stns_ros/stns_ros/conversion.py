"""Unit and message conversions at the ROS boundary (no rclpy node code here).

World units ``u`` are 1/16 m: a power of two, so ``m = u * UNIT_M`` and ``u = m / UNIT_M``
are exact in floating point and the ROS run sees bit-identical numbers to the headless run.
Sim time is an integer number of nanoseconds: frame ``k`` is stamped ``k * tick_ns``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from stns_ros.errors import StnsRosError

UNIT_M: float = 0.0625
"""Metres per world unit (must equal rover_sim.UNIT_M; a test pins it)."""
NS_PER_S = 1_000_000_000


def u_to_m(value: float) -> float:
    return float(value) * UNIT_M


def m_to_u(value: float) -> float:
    return float(value) / UNIT_M


def tick_ns(tick_seconds: float) -> int:
    """Integer nanoseconds of one control tick; refuses ticks that are not whole nanoseconds."""
    ns = round(float(tick_seconds) * NS_PER_S)
    if ns <= 0 or not math.isclose(ns / NS_PER_S, tick_seconds, rel_tol=0, abs_tol=1e-12):
        raise StnsRosError(f"tick_seconds must be a positive whole number of ns, got {tick_seconds!r}")
    return ns


def set_stamp(stamp, t_ns: int) -> None:
    """Write integer ns into a builtin_interfaces/Time in place."""
    stamp.sec, stamp.nanosec = divmod(int(t_ns), NS_PER_S)


def stamp_ns(stamp) -> int:
    return int(stamp.sec) * NS_PER_S + int(stamp.nanosec)


def yaw_quaternion(theta: float) -> tuple[float, float, float, float]:
    """(x, y, z, w) of a rotation by `theta` about z."""
    return (0.0, 0.0, math.sin(theta / 2.0), math.cos(theta / 2.0))


def quaternion_yaw(x: float, y: float, z: float, w: float) -> float:
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def observation_from_messages(goal_xy_m: Sequence[float], ranges_m: Sequence[float] | None) -> list[float]:
    """The agent's observation in u: [goal_x, goal_y] (+ six sector ranges)."""
    obs = [m_to_u(goal_xy_m[0]), m_to_u(goal_xy_m[1])]
    if ranges_m is not None:
        if len(ranges_m) != 6:
            raise StnsRosError(f"expected 6 sector ranges, got {len(ranges_m)}")
        obs.extend(m_to_u(r) for r in ranges_m)
    return obs


# /rover/reward is a geometry_msgs/Vector3Stamped: vector.x = reward of the tick,
# vector.y = 1.0 at goal arrival (terminated) else 0.0, vector.z = trial index.
REWARD_FIELDS = ("reward", "terminated", "trial")
