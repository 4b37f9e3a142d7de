"""``rover-sim-calibrate``: arrivals per 100 behaviour steps of a uniformly random policy.

A behaviour is one action repeated tick by tick until a tick's reward is non-zero (goal
+10, collision -1, over-rotation -1): the paper's stopping rule without a learner (no
target situation, no stop on a change of classified situation). A goal arrival counts as
one more behaviour step (paper footnote 8). The paper's figures: 2.04 (Exp. 1), 1.34
(Exp. 3).

    rover-sim-calibrate --task exp1 --seeds 20 --steps 2000 --post-collision replace
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from rover_sim.config import POST_COLLISION_RULES, TASKS, WorldConfig
from rover_sim.errors import RoverSimError
from rover_sim.world import RoverWorld

PAPER_RATES: dict[str, float] = {"exp1": 2.04, "exp3": 1.34}
"""Random-policy goal arrivals per 100 behaviour steps reported by the paper."""


@dataclass(frozen=True)
class RandomPolicyResult:
    """One seed's random-policy run."""

    seed: int
    steps: int
    """Behaviour steps (behaviours + goal arrivals)."""
    arrivals: int
    ticks: int
    collisions: int
    over_rotations: int

    @property
    def rate(self) -> float:
        """Goal arrivals per 100 behaviour steps."""
        return 100.0 * self.arrivals / self.steps if self.steps else 0.0


def random_policy_run(
    config: WorldConfig, seed: int, steps: int, max_ticks: int = 500
) -> RandomPolicyResult:
    """Run a uniformly random behaviour policy for `steps` behaviour steps.

    The world uses `seed`; the policy draws from its own Generator seeded by (seed, 1).
    """
    policy = np.random.default_rng([seed, 1])
    n_actions = 4
    done = arrivals = ticks = collisions = over_rotations = 0
    with RoverWorld(config, seed=seed) as world:
        world.reset()
        while done < steps:
            out = world.run_behaviour(int(policy.integers(n_actions)), max_ticks=max_ticks)
            done += 1
            ticks += out.ticks
            collisions += out.events.count("collision")
            over_rotations += out.events.count("over_rotation")
            if out.terminated:
                arrivals += 1
                done += 1
                world.reset()
    return RandomPolicyResult(seed, done, arrivals, ticks, collisions, over_rotations)


def _parse_override(item: str, parser: argparse.ArgumentParser) -> tuple[str, object]:
    key, sep, text = item.partition("=")
    if not sep or not key:
        parser.error(f"--set needs FIELD=VALUE, got {item!r}")
    value: object
    if text.lower() in ("true", "false"):
        return key.strip(), text.lower() == "true"
    try:
        value = int(text)
    except ValueError:
        try:
            value = float(text)
        except ValueError:
            value = text
    return key.strip(), value


def main(args: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="rover-sim-calibrate",
        description="Goal arrivals per 100 behaviour steps of a random behaviour policy.",
    )
    parser.add_argument("--task", choices=(*TASKS, "all"), default="all")
    parser.add_argument("--seeds", type=int, default=20, help="number of seeds (0..N-1)")
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--steps", type=int, default=2000, help="behaviour steps per seed")
    parser.add_argument(
        "--post-collision",
        choices=(*POST_COLLISION_RULES, "all"),
        default=None,
        help="post-collision rule (default: the preset's)",
    )
    parser.add_argument("--max-ticks", type=int, default=500, help="tick cap per behaviour")
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="FIELD=VALUE",
        help="override a WorldConfig field (number or word), e.g. --set forward_speed=30",
    )
    ns = parser.parse_args(args)
    extra = dict(_parse_override(item, parser) for item in ns.set)
    if ns.seeds < 1 or ns.steps < 1:
        parser.error(f"--seeds and --steps must be >= 1, got {ns.seeds} and {ns.steps}")
    if ns.max_ticks < 1:
        parser.error(f"--max-ticks must be >= 1, got {ns.max_ticks}")
    if not 0 <= ns.first_seed <= 2**32 - ns.seeds:
        parser.error(f"--first-seed must be in [0, 2**32 - seeds], got {ns.first_seed}")
    tasks = TASKS if ns.task == "all" else (ns.task,)
    if ns.post_collision == "all":
        rules: tuple[str | None, ...] = POST_COLLISION_RULES
    else:
        rules = (ns.post_collision,)
    print(
        f"{'task':5} {'rule':9} {'seeds':>5} {'steps':>7} {'arrivals':>8} "
        f"{'rate/100':>8} {'sd':>5} {'paper':>5} {'ratio':>5} {'ticks/beh':>9} {'sec':>6}"
    )
    for task in tasks:
        for rule in rules:
            overrides = dict(extra)
            if rule is not None:
                overrides["post_collision"] = rule
            try:
                config = WorldConfig.preset(task, **overrides)
            except RoverSimError as exc:
                parser.error(str(exc))
            t0 = time.perf_counter()
            results = [
                random_policy_run(config, seed, ns.steps, ns.max_ticks)
                for seed in range(ns.first_seed, ns.first_seed + ns.seeds)
            ]
            wall = time.perf_counter() - t0
            steps = sum(r.steps for r in results)
            arrivals = sum(r.arrivals for r in results)
            rate = 100.0 * arrivals / steps
            sd = statistics.stdev(r.rate for r in results) if len(results) > 1 else 0.0
            ticks = sum(r.ticks for r in results) / (steps - arrivals)
            paper = PAPER_RATES[task]
            print(
                f"{task:5} {config.post_collision:9} {len(results):5d} {steps:7d} {arrivals:8d} "
                f"{rate:8.2f} {sd:5.2f} {paper:5.2f} {rate / paper:5.2f} {ticks:9.1f} {wall:6.1f}",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
