"""``rover-sim-bench``: control ticks per second and random-policy behaviour steps per
second, headless, single process.

    rover-sim-bench --task exp1 --ticks 20000 --steps 10000
"""

from __future__ import annotations

import argparse
import platform
import time
from collections.abc import Sequence

import numpy as np

from rover_sim.config import TASKS, WorldConfig
from rover_sim.world import RoverWorld


def bench_ticks(config: WorldConfig, ticks: int, seed: int = 0) -> float:
    """Control ticks per second for a cycle of actions changed every 10 ticks."""
    with RoverWorld(config, seed=seed) as world:
        world.reset()
        t0 = time.perf_counter()
        for i in range(ticks):
            _, _, terminated, _, _ = world.step((i // 10) % 4)
            if terminated:
                world.reset()
        return ticks / (time.perf_counter() - t0)


def bench_behaviours(config: WorldConfig, steps: int, seed: int = 0) -> tuple[float, int, int]:
    """(seconds, behaviour steps, ticks) of a random behaviour policy run."""
    policy = np.random.default_rng([seed, 1])
    done = ticks = 0
    with RoverWorld(config, seed=seed) as world:
        world.reset()
        t0 = time.perf_counter()
        while done < steps:
            out = world.run_behaviour(int(policy.integers(4)))
            done += 1
            ticks += out.ticks
            if out.terminated:
                done += 1
                world.reset()
        return time.perf_counter() - t0, done, ticks


def main(args: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="rover-sim-bench",
        description="Headless single-process speed of the rover world.",
    )
    parser.add_argument("--task", choices=(*TASKS, "all"), default="all")
    parser.add_argument("--ticks", type=int, default=20000, help="ticks for the tick rate")
    parser.add_argument("--steps", type=int, default=10000, help="random-policy behaviour steps")
    parser.add_argument("--seed", type=int, default=0)
    ns = parser.parse_args(args)
    if ns.ticks < 1 or ns.steps < 1:
        parser.error(f"--ticks and --steps must be >= 1, got {ns.ticks} and {ns.steps}")
    print(f"python {platform.python_version()} on {platform.machine()}, one process")
    tasks = TASKS if ns.task == "all" else (ns.task,)
    for task in tasks:
        config = WorldConfig.preset(task)
        tps = bench_ticks(config, ns.ticks, ns.seed)
        secs, steps, ticks = bench_behaviours(config, ns.steps, ns.seed)
        print(
            f"{task}: {tps:8.0f} control ticks/s ({ns.ticks} ticks); random policy: "
            f"{steps} behaviour steps in {secs:.1f} s = {steps / secs:.0f} steps/s "
            f"({ticks / steps:.1f} ticks/step, {ticks / secs:.0f} ticks/s)",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
