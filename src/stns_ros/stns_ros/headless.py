"""The same run config without ROS: the tick loop of docs/INTERFACES.md in one process.

The reference for the lockstep ROS run (same seeds, same decisions) and for its speed
(``stns_bringup --config FILE --headless``). Faults of the scenario are applied between
ticks as soon as they are due (the ROS injector applies them a few ticks later, through
the simulator's parameter service).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from stns_ros.conversion import m_to_u
from stns_ros.driver import make_agent
from stns_ros.faults import ScenarioClock, parse_scenario, ramp_points
from stns_ros.params import FAULT_NEUTRAL


def _set(world, values: dict[str, float]) -> None:
    for name, v in values.items():
        world.set_fault(name[:-2], m_to_u(v)) if name.endswith("_std_m") else world.set_fault(name, v)


def run_headless(cfg: dict[str, Any]) -> dict[str, Any]:
    from rover_sim import RoverWorld, WorldConfig
    from stns_core import StnsConfig

    world_cfg, learner = cfg["world"], cfg["learner"]
    world = RoverWorld(WorldConfig.preset(world_cfg["preset"], **world_cfg["overrides"]),
                       seed=world_cfg["seed"])
    lc = StnsConfig.preset(learner["preset"], **{**learner["overrides"], "seed": learner["seed"]})
    agent = make_agent(lc.to_dict(), world.observation_dim, learner["state_in"])
    _set(world, world_cfg["faults"])
    clock = ScenarioClock(parse_scenario(cfg["faults"]))
    values = dict(FAULT_NEUTRAL, **world_cfg["faults"])
    ramps: list[tuple[float, dict[str, float]]] = []
    steps = agent.behaviour_steps + cfg["run"]["steps"]  # a saved learner starts with some
    start = agent.behaviour_steps
    records = []
    ticks = 0
    t0 = time.perf_counter()
    obs, _ = world.reset()
    reward, term = 0.0, False
    while agent.behaviour_steps < steps:
        a = agent.step(obs, reward, term)
        records.extend(agent.pop_records())
        if clock.scenario.faults or ramps:
            now = world.sim_time
            for e in clock.due(agent.behaviour_steps - start, now):
                if e.kind == "ramp":
                    ramps.extend(ramp_points(values, e, now))
                else:
                    _set(world, e.values)
                values.update(e.values)
            for p in [p for p in ramps if p[0] <= now]:
                _set(world, p[1])
                ramps.remove(p)
        if a is None:
            obs, _ = world.reset()
            reward, term = 0.0, False
            continue
        obs, reward, term, trunc, _ = world.step(int(a))
        ticks += 1
        if trunc and not term:
            obs, _ = world.reset()
            reward, term = 0.0, False
    records.extend(agent.pop_records())
    wall = time.perf_counter() - t0
    world.close()
    return {
        "records": records,
        "ticks": ticks,
        "behaviour_steps": agent.behaviour_steps - start,
        "wall_seconds": round(wall, 3),
        "ticks_per_second": round(ticks / wall, 1),
        "behaviour_steps_per_second": round((agent.behaviour_steps - start) / wall, 1),
        "obs_sample": np.asarray(obs).tolist(),
    }
