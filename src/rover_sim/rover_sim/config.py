"""World configuration: units, actions, the frozen `WorldConfig` and the task presets.

Units: the world length unit ``u`` is 1/16 m (`UNIT_M`). The room is 100 x 100 u, the
rover 16 x 12 u, the goal radius 5 u. Angles are radians in code, degrees in fault
parameters (as the paper). Speeds are given per second of sim time.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass
from enum import IntEnum
from typing import Any

import numpy as np

from rover_sim.errors import RoverSimError

UNIT_M: float = 0.0625
"""Metres per world unit ``u`` (a power of two: u <-> m conversion is exact)."""

TASKS: tuple[str, ...] = ("exp1", "exp3")
POST_COLLISION_RULES: tuple[str, ...] = ("replace", "undo", "stay", "back_off")
COMMAND_RESPONSES: tuple[str, ...] = ("dynamic", "immediate")
FAULT_NAMES: tuple[str, ...] = (
    "goal_sensor_rotation_deg",
    "left_wheel_gain",
    "goal_sensor_noise_std",
    "range_sensor_noise_std",
)


class Action(IntEnum):
    """The four behaviours' actions of the paper (one action repeated per behaviour)."""

    FORWARD = 0
    BACKWARD = 1
    CLOCKWISE = 2
    COUNTER_CLOCKWISE = 3


@dataclass(frozen=True)
class Box:
    """An axis-aligned box obstacle: centre (cx, cy) and full sizes (sx, sy), in u."""

    cx: float
    cy: float
    sx: float
    sy: float

    def __post_init__(self) -> None:
        for name in ("cx", "cy", "sx", "sy"):
            object.__setattr__(self, name, _finite(f"Box.{name}", getattr(self, name)))
        if self.sx <= 0 or self.sy <= 0:
            raise RoverSimError(f"Box sizes must be positive, got sx={self.sx!r}, sy={self.sy!r}")

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(xmin, ymin, xmax, ymax) in u."""
        return (
            self.cx - self.sx / 2,
            self.cy - self.sy / 2,
            self.cx + self.sx / 2,
            self.cy + self.sy / 2,
        )


def _finite(name: str, value: Any) -> float:
    # float() would take YAML's true as 1.0 and a quoted "20" as 20.0: neither is a number here
    if isinstance(value, bool | np.bool_) or not isinstance(value, numbers.Real):
        raise RoverSimError(f"{name} must be a number, got {value!r}")
    f = float(value)
    if not math.isfinite(f):
        raise RoverSimError(f"{name} must be finite, got {value!r}")
    return f


def _positive(name: str, value: Any) -> float:
    f = _finite(name, value)
    if f <= 0:
        raise RoverSimError(f"{name} must be positive, got {value!r}")
    return f


def _nonnegative(name: str, value: Any) -> float:
    f = _finite(name, value)
    if f < 0:
        raise RoverSimError(f"{name} must be >= 0, got {value!r}")
    return f


def _boxes(value: Any) -> tuple[Box, ...]:
    """Obstacles given as Box instances or [cx, cy, sx, sy] lists (YAML, JSON); None: none."""
    if value is None:
        return ()
    if isinstance(value, str | bytes | Mapping) or not isinstance(value, tuple | list):
        raise RoverSimError(f"obstacles must be a list of boxes, got {value!r}")
    boxes = []
    for i, b in enumerate(value):
        if not isinstance(b, Box) and (not isinstance(b, tuple | list) or len(b) != 4):
            raise RoverSimError(f"obstacles[{i}] must be [cx, cy, sx, sy] in u, got {b!r}")
        boxes.append(b if isinstance(b, Box) else Box(*b))
    return tuple(boxes)


def validate_fault(name: str, value: Any) -> float:
    """Check one fault value and return it as float; raise RoverSimError naming it."""
    if name not in FAULT_NAMES:
        raise RoverSimError(f"unknown fault {name!r}; known: {', '.join(FAULT_NAMES)}")
    f = _finite(name, value)
    if name == "left_wheel_gain" and not 0.0 < f <= 2.0:
        raise RoverSimError(f"left_wheel_gain must be in (0, 2], got {value!r}")
    if name.endswith("_noise_std") and f < 0:
        raise RoverSimError(f"{name} must be >= 0, got {value!r}")
    return f


@dataclass(frozen=True)
class WorldConfig:
    """Everything that defines a rover world. Lengths in u, times in s of sim time.

    Build one with `WorldConfig.preset("exp1", **overrides)`; every field is validated on
    construction and a bad value raises `RoverSimError` naming it.
    """

    task: str = "exp1"
    """Task name, one of `TASKS` (decides the defaults of the preset)."""
    room_size: float = 100.0
    """Side of the square room (interior), u. The room spans [0, room_size]^2."""
    rover_length: float = 16.0
    """Rover footprint along its x axis (forward), u."""
    rover_width: float = 12.0
    """Rover footprint along its y axis (left), u."""
    goal_radius: float = 5.0
    """Goal arrival when the rover centre is within this distance of the goal centre, u."""
    goal_region: float = 72.0
    """Random goals are drawn uniformly in the central goal_region x goal_region square."""
    goal: tuple[float, float] | None = None
    """Fixed goal (x, y) in u; None = a random goal each trial."""
    obstacles: tuple[Box, ...] = ()
    """Box obstacles (axis-aligned)."""
    range_sensor: bool = False
    """Append the six sector ranges to the observation (8-D input)."""
    tick_seconds: float = 0.1
    """Sim time of one control tick, s."""
    physics_substeps: int = 4
    """pybullet steps per control tick (4: 25 ms; with 1 the body hops when a command
    changes)."""
    solver_iterations: int = 20
    """pybullet constraint-solver iterations per physics step."""
    forward_speed: float = 20.0
    """Speed of the forward/backward actions, u/s (2 u per 0.1 s tick)."""
    rotation_speed_deg: float = 50.0
    """Turn rate of the rotation actions, deg/s (5 deg per 0.1 s tick)."""
    max_rotation_deg: float = 90.0
    """One continuous rotation beyond this angle is penalised (-1)."""
    command_response: str = "immediate"
    """How the rover takes a new command: "dynamic" (the wheel motors accelerate the body
    through the contacts: after a rotation the heading runs on about 4.5 deg into the next
    behaviour), "immediate" (at each change of the commanded body velocity, the body and
    wheel velocities are set to the new command, as an ideal differential drive; give it
    physics_substeps >= 2, else the coarse step makes the body hop). The paper gives no
    dynamics (section 7.1); its rover turns and drives as commanded."""
    post_collision: str = "replace"
    """After a collision: "replace" (new random pose), "undo" (back to the pose where the
    current motion began, i.e. the colliding behaviour is undone), "stay" (the wall stops
    the rover: the tick's motion is undone), "back_off" (as "stay", then moved
    back_off_distance away from the wall)."""
    back_off_distance: float = 4.0
    """Distance the "back_off" rule moves the rover back from the contact, u."""
    rays_per_sector: int = 7
    """Rays cast per 60-degree sector (both edges included; neighbours share edges)."""
    max_range: float = 150.0
    """Range reading when a sector sees nothing (cannot happen in a closed room), u."""
    goal_sensor_rotation_deg: float = 0.0
    """Initial fault: the goal sensor's reading is rotated by this angle (ccw), deg."""
    left_wheel_gain: float = 1.0
    """Initial fault: the left wheel turns at this fraction of its command (0, 2]."""
    goal_sensor_noise_std: float = 0.0
    """Initial fault: Gaussian noise on each goal coordinate, u."""
    range_sensor_noise_std: float = 0.0
    """Initial fault: Gaussian noise on each range reading, u."""
    start_clear_of_goal: bool = True
    """Start and re-placement poses keep the whole footprint off the goal circle (the
    paper: "the rover is set at an arbitrary position outside of the goal"); False: only
    the centre outside the goal radius."""
    start_margin: float = 0.0
    """Random start poses keep the whole rover this far inside walls and obstacles, u."""

    def __post_init__(self) -> None:
        if self.task not in TASKS:
            raise RoverSimError(f"unknown task {self.task!r}; known: {', '.join(TASKS)}")
        for name in (
            "room_size",
            "rover_length",
            "rover_width",
            "goal_radius",
            "goal_region",
            "tick_seconds",
            "forward_speed",
            "rotation_speed_deg",
            "max_rotation_deg",
            "max_range",
        ):
            object.__setattr__(self, name, _positive(name, getattr(self, name)))
        for name in ("back_off_distance", "start_margin"):
            object.__setattr__(self, name, _nonnegative(name, getattr(self, name)))
        for name in ("physics_substeps", "solver_iterations", "rays_per_sector"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise RoverSimError(f"{name} must be an integer >= 1, got {value!r}")
        if self.rays_per_sector < 2:
            raise RoverSimError(f"rays_per_sector must be >= 2, got {self.rays_per_sector!r}")
        if self.goal_region > self.room_size:
            raise RoverSimError(
                f"goal_region must fit in the room ({self.room_size}), got {self.goal_region!r}"
            )
        if max(self.rover_length, self.rover_width) >= self.room_size / 2:
            raise RoverSimError(
                f"the rover ({self.rover_length} x {self.rover_width}) does not fit "
                f"the room {self.room_size!r}"
            )
        if self.command_response not in COMMAND_RESPONSES:
            raise RoverSimError(
                f"unknown command_response {self.command_response!r}; "
                f"known: {', '.join(COMMAND_RESPONSES)}"
            )
        if self.post_collision not in POST_COLLISION_RULES:
            raise RoverSimError(
                f"unknown post_collision rule {self.post_collision!r}; "
                f"known: {', '.join(POST_COLLISION_RULES)}"
            )
        if self.goal is not None:
            if not isinstance(self.goal, tuple | list | np.ndarray) or len(self.goal) != 2:
                raise RoverSimError(f"goal must be (x, y), got {self.goal!r}")
            gx, gy = self.goal
            gx, gy = _finite("goal x", gx), _finite("goal y", gy)
            if not (0 < gx < self.room_size and 0 < gy < self.room_size):
                raise RoverSimError(f"goal must lie inside the room, got {self.goal!r}")
            object.__setattr__(self, "goal", (gx, gy))
        obstacles = tuple(self.obstacles)
        for box in obstacles:
            if not isinstance(box, Box):
                raise RoverSimError(f"obstacles must be Box instances, got {box!r}")
        object.__setattr__(self, "obstacles", obstacles)
        for name in ("range_sensor", "start_clear_of_goal"):
            value = getattr(self, name)
            if not isinstance(value, bool | np.bool_):
                raise RoverSimError(f"{name} must be true or false, got {value!r}")
            object.__setattr__(self, name, bool(value))
        for name in FAULT_NAMES:
            object.__setattr__(self, name, validate_fault(name, getattr(self, name)))

    # ----------------------------------------------------------------- derived values
    @property
    def observation_dim(self) -> int:
        """2 (goal x, y) or 8 (goal x, y + six sector ranges)."""
        return 8 if self.range_sensor else 2

    @property
    def faults(self) -> dict[str, float]:
        """The initial fault values of this config."""
        return {name: getattr(self, name) for name in FAULT_NAMES}

    @property
    def step_length(self) -> float:
        """Distance of one forward/backward tick, u."""
        return self.forward_speed * self.tick_seconds

    @property
    def step_angle_deg(self) -> float:
        """Angle of one rotation tick, deg."""
        return self.rotation_speed_deg * self.tick_seconds

    def replace(self, **changes: Any) -> WorldConfig:
        """A copy with some fields changed (validated again)."""
        unknown = sorted(set(changes) - {f.name for f in dataclasses.fields(self)})
        if unknown:
            raise RoverSimError(f"unknown WorldConfig field(s): {', '.join(unknown)}")
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict[str, Any]:
        """Plain data (obstacles as lists of [cx, cy, sx, sy])."""
        d = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        d["obstacles"] = [[b.cx, b.cy, b.sx, b.sy] for b in self.obstacles]
        d["goal"] = None if self.goal is None else list(self.goal)
        return d

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> WorldConfig:
        """Inverse of `to_dict`; obstacles may be Box or [cx, cy, sx, sy]."""
        d = dict(data)
        if "obstacles" in d:
            d["obstacles"] = _boxes(d["obstacles"])
        if isinstance(d.get("goal"), list):
            d["goal"] = tuple(d["goal"])
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(d) - names)
        if unknown:
            raise RoverSimError(f"unknown WorldConfig field(s): {', '.join(unknown)}")
        return cls(**d)

    @classmethod
    def preset(cls, name: str, **overrides: Any) -> WorldConfig:
        """The config of a task of the paper, with optional field overrides.

        - ``exp1``: no obstacle, random goal in the central 72 x 72 each trial, 2-D input.
        - ``exp3``: one obstacle, fixed goal, 8-D input (layout in the package README).
        """
        if name not in PRESETS:
            raise RoverSimError(f"unknown task {name!r}; known: {', '.join(PRESETS)}")
        base = dict(PRESETS[name])
        base.update(overrides)
        return cls.from_dict(base)


EXP3_GOAL: tuple[float, float] = (80.0, 50.0)
"""Exp. 3 goal: on the east-west centre line, 20 u from the east wall."""
EXP3_OBSTACLE: Box = Box(55.0, 50.0, 8.0, 24.0)
"""Exp. 3 obstacle: an 8 x 24 block (x 51..59, y 38..62) 21 u west of the goal, hiding it
from the middle of the room (sized so that a random policy arrives at the paper's rate)."""

PRESETS: dict[str, dict[str, Any]] = {
    "exp1": {"task": "exp1"},
    "exp3": {
        "task": "exp3",
        "goal": EXP3_GOAL,
        "obstacles": (EXP3_OBSTACLE,),
        "range_sensor": True,
    },
}
