"""A tiny kinematic version of the paper's Exp. 1 world, for tests and the benchmark only.

Not the project's simulator (that is ``rover_sim``): a dependency-free sketch after
STNS-NOTES section 9 (1 unit and 3 degrees per tick, rover re-placed at a random pose after a
wall collision) so that stns_core can check its own learning without other packages.
Actions: 0 forward, 1 backward, 2 clockwise, 3 counter-clockwise.
"""

from __future__ import annotations

import math

import numpy as np

ROOM = 100.0
HALF_L, HALF_W = 8.0, 6.0  # rover 16 x 12
GOAL_RADIUS = 5.0
STEP_U = 1.0
STEP_RAD = math.radians(3.0)
CORNERS = np.array([[HALF_L, HALF_W], [HALF_L, -HALF_W], [-HALF_L, HALF_W], [-HALF_L, -HALF_W]])


class KinematicRover:
    """Gymnasium-shaped: ``reset() -> obs``; ``step(a) -> (obs, reward, terminated)``."""

    def __init__(self, seed: int = 0) -> None:
        self.rng = np.random.default_rng(seed)
        self.goal = np.zeros(2)
        self.pose = np.zeros(3)
        self._rot_ticks = 0
        self._rot_dir = 0

    def _inside(self, x: float, y: float, th: float) -> bool:
        c, s = math.cos(th), math.sin(th)
        px = x + CORNERS[:, 0] * c - CORNERS[:, 1] * s
        py = y + CORNERS[:, 0] * s + CORNERS[:, 1] * c
        return bool(np.all((px >= 0) & (px <= ROOM) & (py >= 0) & (py <= ROOM)))

    def _place(self) -> None:
        while True:
            x, y = self.rng.uniform(0.0, ROOM, 2)
            th = self.rng.uniform(-math.pi, math.pi)
            if self._inside(x, y, th) and math.hypot(x - self.goal[0], y - self.goal[1]) > GOAL_RADIUS:
                self.pose = np.array([x, y, th])
                self._rot_ticks = 0
                return

    def reset(self) -> np.ndarray:
        self.goal = self.rng.uniform(14.0, 86.0, 2)
        self._place()
        return self.obs()

    def obs(self) -> np.ndarray:
        x, y, th = self.pose
        dx, dy = self.goal[0] - x, self.goal[1] - y
        c, s = math.cos(th), math.sin(th)
        return np.array([c * dx + s * dy, -s * dx + c * dy])

    def step(self, action: int) -> tuple[np.ndarray, float, bool]:
        x, y, th = self.pose
        reward = 0.0
        if action in (0, 1):
            self._rot_ticks = 0
            sign = 1.0 if action == 0 else -1.0
            nx, ny = x + sign * STEP_U * math.cos(th), y + sign * STEP_U * math.sin(th)
            if self._inside(nx, ny, th):
                self.pose = np.array([nx, ny, th])
            else:
                reward = -1.0
                self._place()
        else:
            direction = -1 if action == 2 else 1
            if direction != self._rot_dir:
                self._rot_ticks = 0
                self._rot_dir = direction
            th = (th + direction * STEP_RAD + math.pi) % (2 * math.pi) - math.pi
            self.pose = np.array([x, y, th])
            self._rot_ticks += 1
            if self._rot_ticks * 3 > 90:
                reward = -1.0
                self._rot_ticks = 0
        if math.hypot(self.pose[0] - self.goal[0], self.pose[1] - self.goal[1]) <= GOAL_RADIUS:
            return self.obs(), reward + 10.0, True
        return self.obs(), reward, False


def run_learning(agent, steps: int, seed: int = 0, max_ticks: int = 10_000_000) -> list:
    """Drive ``agent`` on the kinematic world for ``steps`` behaviour steps; all StepRecords."""
    world = KinematicRover(seed)
    obs, reward, terminated = world.reset(), 0.0, False
    records = []
    ticks = 0
    while agent.behaviour_steps < steps and ticks < max_ticks:
        action = agent.step(obs, reward, terminated)
        ticks += 1
        if action is None:
            obs, reward, terminated = world.reset(), 0.0, False
            continue
        obs, reward, terminated = world.step(action)
    records.extend(agent.pop_records())
    return records


def behaviours_per_arrival(records, last: int = 1000) -> float:
    """Behaviour steps per goal arrival over the last ``last`` records (arrivals included)."""
    window = records[-last:]
    arrivals = sum(1 for r in window if r.arrival)
    behaviours = sum(1 for r in window if not r.arrival)
    return behaviours / arrivals if arrivals else float("inf")
