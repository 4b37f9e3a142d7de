"""The agent side of the tick protocol, free of rclpy: shared by the agent node and
``stns_replay --verify`` so that both feed `StnsAgent.step` exactly as the headless loop does.

Per frame (observation, reward of the tick, terminated): ``agent.step`` gives an action,
or None at a goal arrival; the answer is the action's body velocity in SI units
(v in m/s = v_u * UNIT_M, w in rad/s), or zero for None (the world then starts a new trial).
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from stns_ros.conversion import u_to_m
from stns_ros.errors import StnsRosError

N_BEHAVIOURS = 4


def action_velocities(world_preset: str, world_overrides: Mapping[str, Any] | None = None
                      ) -> list[tuple[float, float]]:
    """(v u/s, w rad/s) of each discrete action, as `RoverWorld.action_velocity` gives them
    (a unit test pins the two against each other), without starting pybullet."""
    from rover_sim import WorldConfig

    cfg = WorldConfig.preset(world_preset, **dict(world_overrides or {}))
    v = cfg.forward_speed
    w = math.radians(cfg.rotation_speed_deg)
    return [(v, 0.0), (-v, 0.0), (0.0, -w), (0.0, w)]


def observation_dim(world_preset: str, world_overrides: Mapping[str, Any] | None = None) -> int:
    from rover_sim import WorldConfig

    return WorldConfig.preset(world_preset, **dict(world_overrides or {})).observation_dim


def seeds_from_run_seed(seed: int) -> tuple[int, int]:
    """(world_seed, agent_seed) of trial set 0 of ``stns-experiment ... --seed seed``:
    SeedSequence([seed, 0]).spawn(1)[0].generate_state(3)[:2] (stns_experiments.runner)."""
    child = np.random.SeedSequence([int(seed), 0]).spawn(1)[0]
    w, a, _ = (int(v) for v in child.generate_state(3, dtype=np.uint32))
    return w, a


def record_to_dict(record: Any) -> dict[str, Any]:
    """A StepRecord as JSON-safe plain data."""
    d = dataclasses.asdict(record) if dataclasses.is_dataclass(record) else dict(record)
    return {k: _plain(v) for k, v in d.items()}


def _plain(v: Any) -> Any:
    if isinstance(v, np.ndarray):
        return [_plain(x) for x in v.tolist()]
    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, list | tuple):
        return [_plain(x) for x in v]
    if isinstance(v, dict):
        return {str(k): _plain(x) for k, x in v.items()}
    return v


def dumps(d: Any) -> str:
    return json.dumps(_plain(d), sort_keys=True, separators=(",", ":"))


class AgentDriver:
    """One StnsAgent fed frame by frame."""

    def __init__(self, agent: Any, velocities: list[tuple[float, float]]) -> None:
        self.agent = agent
        self.velocities_si = [(u_to_m(v), float(w)) for v, w in velocities]
        self._steps = agent.behaviour_steps

    def on_frame(self, obs: np.ndarray, reward: float, terminated: bool
                 ) -> tuple[int | None, tuple[float, float], list[Any]]:
        """(action or None, (v m/s, w rad/s), StepRecords finished by this tick)."""
        action = self.agent.step(obs, float(reward), bool(terminated))
        records: list[Any] = []
        if self.agent.behaviour_steps != self._steps:
            self._steps = self.agent.behaviour_steps
            records = self.agent.pop_records()
        if action is None:
            return None, (0.0, 0.0), records
        return int(action), self.velocities_si[int(action)], records

    @property
    def behaviour_steps(self) -> int:
        return self.agent.behaviour_steps


def make_agent(learner_config: Mapping[str, Any], obs_dim: int, state_in: str = "") -> Any:
    """A fresh StnsAgent from a full StnsConfig dict, or the saved one at `state_in`, which
    must take `obs_dim`-D observations and the four behaviours (else `StnsRosError`)."""
    from stns_core import StnsAgent, StnsConfig

    if state_in:
        agent = StnsAgent.load(state_in)
        if (agent.obs_dim, agent.n_behaviours) != (obs_dim, N_BEHAVIOURS):
            raise StnsRosError(
                f"saved learner {state_in!r} takes {agent.obs_dim}-D observations and "
                f"{agent.n_behaviours} behaviours; this world gives {obs_dim}-D observations "
                f"and {N_BEHAVIOURS} behaviours")
        return agent
    return StnsAgent(StnsConfig.from_dict(dict(learner_config)), obs_dim=obs_dim,
                     n_behaviours=N_BEHAVIOURS)

