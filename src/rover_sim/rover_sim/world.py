"""`RoverWorld`: the pybullet rover world with a Gymnasium-shaped API.

One control tick = `WorldConfig.tick_seconds` of sim time: the command's body velocity
is turned into two wheel velocities (left wheel scaled by the ``left_wheel_gain`` fault),
the wheel motors are set and pybullet steps ``physics_substeps`` times. Then the world
computes the tick's events from the new base pose:

- ``"collision"`` (-1): a tick that commands translation (v != 0) and pushes the rover
  footprint further into a wall or obstacle than it was before the tick. The
  ``post_collision`` rule then places the rover (see `WorldConfig.post_collision`).
  Pure rotation (v == 0) is never checked for collision, and walls exert no contact
  force on the rover (rover-wall collision pairs are switched off in pybullet), so a
  rotation next to a wall is never stopped;
  a translation out of such an overlap is allowed, one further into it collides.
- ``"over_rotation"`` (-1): pure rotation ticks in one direction accumulate the measured
  heading change; when it passes ``max_rotation_deg`` the penalty is given and the
  accumulator restarts. Any other command (another direction, translation, stop) resets
  the accumulator.
- ``"goal"`` (+10, terminated): the rover centre is within ``goal_radius`` of the goal.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pybullet

from rover_sim import bodies
from rover_sim.client import DirectClient
from rover_sim.config import (
    FAULT_NAMES,
    UNIT_M,
    Action,
    WorldConfig,
    _finite,
    validate_fault,
)
from rover_sim.errors import RoverSimError
from rover_sim.geometry import (
    Pose,
    deeper,
    penetration_depths,
    sample_goal,
    sample_pose,
    wrap_angle,
)
from rover_sim.sensors import RangeSensor, goal_sensor

GOAL_REWARD = 10.0
COLLISION_REWARD = -1.0
OVER_ROTATION_REWARD = -1.0
_DEPTH_EPS = 1e-9
_RESET_OPTIONS = ("goal", "pose")


@dataclass(frozen=True)
class BehaviourOutcome:
    """What `RoverWorld.run_behaviour` did."""

    action: Action
    ticks: int
    """Control ticks the behaviour ran."""
    reward: float
    """Sum of the ticks' rewards."""
    events: tuple[str, ...]
    """Events of all its ticks, in order."""
    terminated: bool
    """The goal was reached (call `reset` next)."""
    stopped_by: str
    """"reward", "stop" (the predicate) or "max_ticks"."""
    obs: np.ndarray
    """Observation after the last tick."""
    info: dict[str, Any]
    """Info of the last tick."""
    poses: tuple[Pose, ...] = field(default=())
    """Pose after each tick (only with ``record=True``)."""


class RoverWorld:
    """The rover world of the paper. Owns one pybullet client (DIRECT, headless).

    >>> world = RoverWorld("exp1", seed=7)
    >>> obs, info = world.reset()
    >>> obs, reward, terminated, truncated, info = world.step(Action.FORWARD)
    """

    def __init__(self, config: WorldConfig | str = "exp1", seed: int | None = None) -> None:
        if isinstance(config, str):
            config = WorldConfig.preset(config)
        if not isinstance(config, WorldConfig):
            raise RoverSimError(f"config must be a WorldConfig or a task name, got {config!r}")
        self._config = config
        self._rng = _generator(seed)
        self._faults = config.faults
        self._client: DirectClient | None = DirectClient()
        self._scene = bodies.build_scene(self._client, config)
        self._ranges = (
            RangeSensor(
                self._client,
                config.rays_per_sector,
                config.max_range,
                bodies.RAY_HEIGHT_M,
            )
            if config.range_sensor
            else None
        )
        self._goal: tuple[float, float] = config.goal or (config.room_size / 2,) * 2
        self._tick = 0
        self._trial = -1
        self._done = False
        self._motor_cmd: tuple[float, float] | None = None
        self._segment_cmd: tuple[float, float] | None = None
        self._segment_base: Any = None
        self._rot_sign = 0
        self._rot_acc = 0.0
        self._place((config.room_size / 2, config.room_size / 2, 0.0))

    # ------------------------------------------------------------------ properties
    @property
    def config(self) -> WorldConfig:
        """The world's (frozen) config."""
        return self._config

    @property
    def pose(self) -> Pose:
        """Ground-truth rover pose (x, y in u, theta in rad)."""
        return self._pose

    @property
    def goal(self) -> tuple[float, float]:
        """Goal centre of the current trial, u."""
        return self._goal

    @property
    def faults(self) -> dict[str, float]:
        """Current fault values (a copy)."""
        return dict(self._faults)

    @property
    def observation_dim(self) -> int:
        """2 (exp1) or 8 (exp3)."""
        return self._config.observation_dim

    @property
    def tick(self) -> int:
        """Control ticks since construction."""
        return self._tick

    @property
    def sim_time(self) -> float:
        """Sim time since construction, s."""
        return self._tick * self._config.tick_seconds

    @property
    def trial(self) -> int:
        """Index of the current trial (0 after the first reset)."""
        return self._trial

    @property
    def rng(self) -> np.random.Generator:
        """The world's one random Generator."""
        return self._rng

    # ------------------------------------------------------------------ API
    def reset(
        self, *, seed: int | None = None, options: Mapping[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start a new trial: goal and start pose from the world's Generator.

        `seed` re-seeds the Generator. `options` may fix ``"goal": (x, y)`` and/or
        ``"pose": (x, y, theta)`` (u, rad) instead of drawing them.
        """
        self._check_open()
        if seed is not None:
            self._rng = _generator(seed)
        options = dict(options or {})
        unknown = sorted(set(options) - set(_RESET_OPTIONS))
        if unknown:
            raise RoverSimError(
                f"unknown reset option(s) {unknown!r}; known: {', '.join(_RESET_OPTIONS)}"
            )
        if options.get("goal") is not None:
            goal = _finite_tuple("goal", options["goal"], 2)
        else:
            goal = sample_goal(self._rng, self._config)
        self._goal = (goal[0], goal[1])
        if options.get("pose") is not None:
            pose = _finite_tuple("pose", options["pose"], 3)
        else:
            pose = sample_pose(self._rng, self._config, self._goal)
        self._place((pose[0], pose[1], pose[2]))
        self._trial += 1
        self._done = False
        self._reset_rotation()
        return self._observe(), self._info([])

    def action_velocity(self, action: Action | int) -> tuple[float, float]:
        """Body velocity (v in u/s, w in rad/s, ccw positive) of a discrete action."""
        a = _as_action(action)
        v = self._config.forward_speed
        w = math.radians(self._config.rotation_speed_deg)
        return {
            Action.FORWARD: (v, 0.0),
            Action.BACKWARD: (-v, 0.0),
            Action.CLOCKWISE: (0.0, -w),
            Action.COUNTER_CLOCKWISE: (0.0, w),
        }[a]

    def step(self, action: Action | int) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """One control tick of a discrete action: exactly
        ``step_velocity(*action_velocity(action))``."""
        return self.step_velocity(*self.action_velocity(action))

    def step_velocity(
        self, v: float, w: float
    ) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """One control tick at body velocity `v` (u/s, forward) and `w` (rad/s, ccw).

        Returns (obs, reward, terminated, truncated, info); `truncated` is always False.
        """
        self._check_open()
        v = _finite("v", v)
        w = _finite("w", w)
        if self._trial < 0:
            raise RoverSimError("step before reset(): call reset() to start a trial")
        if self._done:
            raise RoverSimError(
                f"trial {self._trial} ended at the goal; call reset() before stepping again"
            )
        cfg = self._config
        before_pose = self._pose
        before_base = self._base_state
        before_depth = self._depths

        if self._segment_cmd != (v, w):
            # a new motion segment (a behaviour, seen from the world) starts here
            self._segment_cmd, self._segment_base = (v, w), before_base
        self._drive(v, w)
        c = self._client
        for _ in range(cfg.physics_substeps):
            c.stepSimulation()
        self._read_pose()
        self._tick += 1

        events: list[str] = []
        reward = 0.0
        if v != 0.0:
            self._depths = penetration_depths(self._pose, cfg)
            if deeper(self._depths, before_depth, _DEPTH_EPS):
                events.append("collision")
                reward += COLLISION_REWARD
                self._after_collision(before_pose, before_base, v)
        if v == 0.0 and w != 0.0:
            sign = 1 if w > 0 else -1
            if sign != self._rot_sign:
                self._rot_sign, self._rot_acc = sign, 0.0
            self._rot_acc += sign * wrap_angle(self._pose[2] - before_pose[2])
            if self._rot_acc > math.radians(cfg.max_rotation_deg):
                events.append("over_rotation")
                reward += OVER_ROTATION_REWARD
                self._rot_acc = 0.0
        else:
            self._reset_rotation()
        if v == 0.0:
            self._depths = penetration_depths(self._pose, cfg)
        x, y, _ = self._pose
        terminated = math.hypot(x - self._goal[0], y - self._goal[1]) <= cfg.goal_radius
        if terminated:
            events.append("goal")
            reward += GOAL_REWARD
            self._done = True
        if reward != 0.0:
            self._segment_cmd = None
        return self._observe(), reward, terminated, False, self._info(events)

    def run_behaviour(
        self,
        action: Action | int,
        stop: Callable[[np.ndarray], bool] | None = None,
        max_ticks: int = 500,
        *,
        record: bool = False,
    ) -> BehaviourOutcome:
        """Repeat `action` tick by tick until a tick's reward is non-zero (or the goal is
        reached), `stop(obs)` is true after a tick, or `max_ticks` ticks ran."""
        a = _as_action(action)
        if isinstance(max_ticks, bool) or not isinstance(max_ticks, int) or max_ticks < 1:
            raise RoverSimError(f"max_ticks must be an integer >= 1, got {max_ticks!r}")
        v, w = self.action_velocity(a)
        total = 0.0
        events: list[str] = []
        poses: list[Pose] = []
        stopped_by = "max_ticks"
        ticks = 0
        obs, terminated, info = self._observe(), False, self._info([])
        while ticks < max_ticks:
            obs, reward, terminated, _, info = self.step_velocity(v, w)
            ticks += 1
            total += reward
            events.extend(info["events"])
            if record:
                poses.append(self._pose)
            if reward != 0.0 or terminated:
                stopped_by = "reward"
                break
            if stop is not None and stop(obs):
                stopped_by = "stop"
                break
        return BehaviourOutcome(
            action=a,
            ticks=ticks,
            reward=total,
            events=tuple(events),
            terminated=terminated,
            stopped_by=stopped_by,
            obs=obs,
            info=info,
            poses=tuple(poses),
        )

    def set_fault(self, name: str, value: float) -> None:
        """Change a fault at any time: ``goal_sensor_rotation_deg`` (deg, ccw),
        ``left_wheel_gain`` in (0, 2], ``goal_sensor_noise_std`` / ``range_sensor_noise_std``
        (u, >= 0)."""
        self._faults[name] = validate_fault(name, value)
        if name == "left_wheel_gain":
            self._motor_cmd = None

    def clear_faults(self) -> None:
        """Back to a healthy rover (all faults at their neutral values)."""
        for name in FAULT_NAMES:
            self._faults[name] = 1.0 if name == "left_wheel_gain" else 0.0
        self._motor_cmd = None

    def range_readings(self) -> np.ndarray:
        """The six sector ranges (u) at the current pose, noise-free (any task)."""
        self._check_open()
        sensor = self._ranges or RangeSensor(
            self._client,
            self._config.rays_per_sector,
            self._config.max_range,
            bodies.RAY_HEIGHT_M,
        )
        return sensor.read(self._pose)

    def close(self) -> None:
        """Disconnect the pybullet client; safe to call twice."""
        if self._client is not None:
            client, self._client = self._client, None
            client.close()

    def __enter__(self) -> RoverWorld:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __del__(self) -> None:
        if getattr(self, "_client", None) is not None:
            self.close()

    # ------------------------------------------------------------------ internals
    def _check_open(self) -> None:
        if self._client is None:
            raise RoverSimError("the world is closed")

    def _drive(self, v: float, w: float) -> None:
        half_track = bodies.TRACK_M / 2.0
        v_m = v * UNIT_M
        left = (v_m - w * half_track) / bodies.WHEEL_RADIUS_M * self._faults["left_wheel_gain"]
        right = (v_m + w * half_track) / bodies.WHEEL_RADIUS_M
        if self._motor_cmd != (left, right):
            if self._config.command_response == "immediate":
                self._take_command(left, right)
            self._client.setJointMotorControlArray(
                self._scene.rover,
                [bodies.LEFT_WHEEL, bodies.RIGHT_WHEEL],
                pybullet.VELOCITY_CONTROL,
                targetVelocities=[left, right],
                forces=[bodies.MOTOR_FORCE, bodies.MOTOR_FORCE],
            )
            self._motor_cmd = (left, right)

    def _take_command(self, left: float, right: float) -> None:
        """command_response="immediate": body and wheels move at the new wheel speeds (the
        left-wheel fault included) at once, as an ideal differential drive."""
        c, rover = self._client, self._scene.rover
        r = bodies.WHEEL_RADIUS_M
        v_m = (left + right) * r / 2.0
        w = (right - left) * r / bodies.TRACK_M
        th = self._pose[2]
        c.resetBaseVelocity(rover, [v_m * math.cos(th), v_m * math.sin(th), 0.0], [0.0, 0.0, w])
        for joint, speed in ((bodies.LEFT_WHEEL, left), (bodies.RIGHT_WHEEL, right)):
            c.resetJointState(rover, joint, c.getJointState(rover, joint)[0], speed)

    def _read_pose(self) -> None:
        pos, quat = self._client.getBasePositionAndOrientation(self._scene.rover)
        self._base_state = (pos, quat)
        self._pose = (pos[0] / UNIT_M, pos[1] / UNIT_M, bodies.yaw_from_quat(quat))

    def _set_base(self, pos: Any, quat: Any) -> None:
        c, rover = self._client, self._scene.rover
        c.resetBasePositionAndOrientation(rover, pos, quat)
        c.resetBaseVelocity(rover, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0])
        for joint in (bodies.LEFT_WHEEL, bodies.RIGHT_WHEEL):
            c.resetJointState(rover, joint, 0.0, 0.0)
        self._read_pose()
        self._depths = penetration_depths(self._pose, self._config)
        self._segment_cmd = None
        self._motor_cmd = None  # the wheels stand still now: the next command is new

    def _place(self, pose: Pose) -> None:
        x, y, th = pose
        self._set_base([x * UNIT_M, y * UNIT_M, bodies.WHEEL_RADIUS_M], bodies.quat_from_yaw(th))

    def _after_collision(self, before_pose: Pose, before_base: Any, v: float) -> None:
        rule = self._config.post_collision
        if rule == "replace":
            self._place(sample_pose(self._rng, self._config, self._goal))
            return
        if rule == "undo":
            self._set_base(*self._segment_base)
            return
        self._set_base(*before_base)
        if rule == "back_off":
            x, y, th = before_pose
            d = -math.copysign(self._config.back_off_distance, v)
            moved = (x + d * math.cos(th), y + d * math.sin(th), th)
            if not deeper(penetration_depths(moved, self._config), self._depths, _DEPTH_EPS):
                self._place(moved)

    def _reset_rotation(self) -> None:
        self._rot_sign, self._rot_acc = 0, 0.0

    def _observe(self) -> np.ndarray:
        gx, gy = goal_sensor(self._pose, self._goal, self._faults["goal_sensor_rotation_deg"])
        std = self._faults["goal_sensor_noise_std"]
        if std > 0.0:
            nx, ny = self._rng.normal(0.0, std, size=2)
            gx, gy = gx + nx, gy + ny
        if self._ranges is None:
            return np.array([gx, gy], dtype=np.float64)
        ranges = self._ranges.read(self._pose)
        std = self._faults["range_sensor_noise_std"]
        if std > 0.0:
            ranges = np.maximum(ranges + self._rng.normal(0.0, std, size=ranges.shape), 0.0)
            ranges = ranges.astype(np.float32).astype(np.float64)
        return np.concatenate(([gx, gy], ranges))

    def _info(self, events: list[str]) -> dict[str, Any]:
        return {
            "events": events,
            "pose": self._pose,
            "goal": self._goal,
            "trial": self._trial,
            "tick": self._tick,
            "sim_time": self.sim_time,
        }


def _generator(seed: Any) -> np.random.Generator:
    """The world's Generator from `seed`; numpy's own errors for a bad one ("expected
    non-negative integer") name neither the seed nor its value."""
    if seed is None or isinstance(seed, (np.random.SeedSequence, np.random.Generator)):
        return np.random.default_rng(seed)
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or seed < 0:
        raise RoverSimError(f"seed must be a non-negative integer, got {seed!r}")
    return np.random.default_rng(int(seed))


def _as_action(action: Any) -> Action:
    if isinstance(action, bool):
        raise RoverSimError(f"unknown action {action!r}; actions are 0..{len(Action) - 1}")
    try:
        return Action(action)
    except (ValueError, TypeError):
        raise RoverSimError(
            f"unknown action {action!r}; actions are 0..{len(Action) - 1}"
        ) from None


def _finite_tuple(name: str, value: Any, n: int) -> tuple[float, ...]:
    try:
        items = tuple(value)
    except TypeError:
        raise RoverSimError(f"{name} must be a sequence of {n} numbers, got {value!r}") from None
    if len(items) != n:
        raise RoverSimError(f"{name} must have {n} numbers, got {value!r}")
    return tuple(_finite(name, x) for x in items)


__all__ = ["BehaviourOutcome", "RoverWorld"]
