"""``rover-sim-bench``: control ticks per second and random-policy behaviour steps per
second, headless, single process.

    rover-sim-bench --task exp1 --ticks 20000 --steps 10000
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from collections.abc import Sequence

import numpy as np

from rover_sim.config import TASKS, WorldConfig
from rover_sim.world import RoverWorld


def bench_ticks(config: WorldConfig, ticks: int, seed: int = 0) -> tuple[float, float]:
    """(wall s, CPU s) of `ticks` control ticks, actions cycled every 10 ticks."""
    with RoverWorld(config, seed=seed) as world:
        world.reset()
        t0, c0 = time.perf_counter(), time.process_time()
        for i in range(ticks):
            _, _, terminated, _, _ = world.step((i // 10) % 4)
            if terminated:
                world.reset()
        return time.perf_counter() - t0, time.process_time() - c0


def bench_behaviours(
    config: WorldConfig, steps: int, seed: int = 0
) -> tuple[float, float, int, int]:
    """(wall s, CPU s, behaviour steps, ticks) of a random behaviour policy run."""
    policy = np.random.default_rng([seed, 1])
    done = ticks = 0
    with RoverWorld(config, seed=seed) as world:
        world.reset()
        t0, c0 = time.perf_counter(), time.process_time()
        while done < steps:
            out = world.run_behaviour(int(policy.integers(4)))
            done += 1
            ticks += out.ticks
            if out.terminated:
                done += 1
                world.reset()
        return time.perf_counter() - t0, time.process_time() - c0, done, ticks


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
    if ns.seed < 0:
        parser.error(f"--seed must be a non-negative integer, got {ns.seed}")
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(
        f"python {platform.python_version()} on {platform.machine()}, one process, "
        f"{os.cpu_count()} cores, load average {load:.1f}; "
        "rates per wall-clock second (per CPU second of this process)"
    )
    tasks = TASKS if ns.task == "all" else (ns.task,)
    for task in tasks:
        config = WorldConfig.preset(task)
        wall, cpu = bench_ticks(config, ns.ticks, ns.seed)
        print(
            f"{task}: control ticks: {ns.ticks} in {wall:.1f} s = {ns.ticks / wall:.0f} ticks/s "
            f"({ns.ticks / cpu:.0f} per CPU s)",
            flush=True,
        )
        wall, cpu, steps, ticks = bench_behaviours(config, ns.steps, ns.seed)
        print(
            f"{task}: random policy: {steps} behaviour steps in {wall:.1f} s "
            f"(CPU {cpu:.1f} s) = {steps / wall:.0f} steps/s ({steps / cpu:.0f} per CPU s), "
            f"{ticks / steps:.1f} ticks/step",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
