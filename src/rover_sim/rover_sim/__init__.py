"""The pybullet differential-drive rover world of the STNS paper: room, goal, obstacle, sensors, behaviours, rewards, faults.

>>> from rover_sim import RoverWorld, Action
>>> world = RoverWorld("exp1", seed=7)
>>> obs, info = world.reset()
>>> obs, reward, terminated, truncated, info = world.step(Action.FORWARD)
"""

from rover_sim.config import (
    FAULT_NAMES,
    POST_COLLISION_RULES,
    TASKS,
    UNIT_M,
    Action,
    Box,
    WorldConfig,
)
from rover_sim.errors import RoverSimError
from rover_sim.sensors import SECTOR_NAMES
from rover_sim.world import BehaviourOutcome, RoverWorld

__all__ = [
    "FAULT_NAMES",
    "POST_COLLISION_RULES",
    "SECTOR_NAMES",
    "TASKS",
    "UNIT_M",
    "Action",
    "BehaviourOutcome",
    "Box",
    "RoverSimError",
    "RoverWorld",
    "WorldConfig",
]
