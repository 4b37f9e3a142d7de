"""``stns-core-bench``: cost per control tick and per behaviour step, and a learning check.

Timing: a learner is built with 20 situations on synthetic data (20 Gaussian regions
chained towards two goal regions: behaviour ``b_k`` from region ``k`` reaches its parent
region with probability 0.85), for 2-D / history 1000 (Exp. 1 parameters) and 8-D /
history 10000 (Exp. 3 parameters). Then it measures

* per tick: ``StnsAgent.step`` while a behaviour runs on (validation, classification of the
  input, stop test), on inputs drawn from the regions (so the nearest-neighbour test runs);
* per behaviour step: storing the record and all of categorical learning
  (``Learner.add_record``, the adjust-interval operations amortised) plus planning for the
  next behaviour.

``--learn`` runs the kinematic Exp. 1 sketch (``stns_core.toyworld``) and prints behaviours
per goal arrival by 1000-step block.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time

import numpy as np

from .agent import StnsAgent, _Running
from .categorical import GOAL
from .config import StnsConfig
from .errors import StnsError
from .situation import R_KIND, T_KIND

N_SITUATIONS = 20


class _Regions:
    """Synthetic record generator: 20 regions, two R regions, the rest chained T regions."""

    def __init__(self, dim: int, n_behaviours: int, rng: np.random.Generator) -> None:
        self.dim = dim
        self.rng = rng
        self.n_behaviours = n_behaviours
        means: list[np.ndarray] = []
        while len(means) < N_SITUATIONS:  # well separated regions
            m = rng.uniform(-100.0, 100.0, dim)
            if all(np.linalg.norm(m - o) > 30.0 for o in means):
                means.append(m)
        self.means = np.array(means)
        self.std = 4.0
        self.behaviour = np.zeros(N_SITUATIONS, dtype=np.int64)
        self.parent = np.full(N_SITUATIONS, -1, dtype=np.int64)
        self.behaviour[1] = 1
        used: set[tuple[int, int]] = set()
        for k in range(2, N_SITUATIONS):  # unique (behaviour, parent) attributes
            while True:
                pair = (int(rng.integers(n_behaviours)), int(rng.integers(k)))
                if pair not in used:
                    used.add(pair)
                    break
            self.behaviour[k], self.parent[k] = pair

    def sample(self, k: int) -> np.ndarray:
        return self.means[k] + self.rng.normal(0.0, self.std, self.dim)

    def margin(self) -> np.ndarray:
        """A point of the margin space: at least 30 from every region's centre."""
        while True:
            x = self.rng.uniform(-150.0, 150.0, self.dim)
            if np.min(np.linalg.norm(self.means - x, axis=1)) > 30.0:
                return x

    def record(self):
        """(x, b, reward, x_next, terminal): one behaviour step of a mostly-good policy.

        From region k the policy takes ``b_k`` with probability 0.85, which reaches the
        parent region (or the goal) with probability 0.9; other outcomes end in the margin.
        One record in ten starts in the margin.
        """
        rng = self.rng
        if rng.random() < 0.1:
            return self.margin(), int(rng.integers(self.n_behaviours)), 0.0, self.margin(), False
        k = int(rng.integers(N_SITUATIONS))
        x = self.sample(k)
        b = int(self.behaviour[k]) if rng.random() < 0.85 else int(rng.integers(self.n_behaviours))
        if b == self.behaviour[k] and rng.random() < 0.9:
            if self.parent[k] < 0:
                return x, b, 10.0, x, True
            return x, b, 0.0, self.sample(int(self.parent[k])), False
        return x, b, 0.0, self.margin(), False


def build_agent(preset: str, dim: int, seed: int = 0) -> tuple[StnsAgent, _Regions]:
    """An agent whose learner holds a full history and the 20 situations of the regions."""
    cfg = StnsConfig.preset(preset, seed=seed)
    agent = StnsAgent(cfg, obs_dim=dim, n_behaviours=4)
    learner = agent.learner
    regions = _Regions(dim, 4, np.random.default_rng(seed))
    h = learner.hist
    for _ in range(h.capacity):
        x, b, r, xn, term = regions.record()
        h.append(x, 0, b, r, xn, 0, term)
    # extract the chain top-down, as extraction would (R first, each T after its parent)
    ids: dict[int, int] = {}
    for k in range(N_SITUATIONS):
        learner.relabel()
        if regions.parent[k] < 0:
            learner._new_situation(R_KIND, int(regions.behaviour[k]), 0, 10.0, 0)
        else:
            learner._new_situation(T_KIND, int(regions.behaviour[k]),
                                   ids[int(regions.parent[k])], 0.0, 0)
        ids[k] = learner.order[-1].id
    return agent, regions


def _behaviour_step(agent: StnsAgent, regions: _Regions) -> None:
    learner = agent.learner
    x, b, r, xn, term = regions.record()
    learner.add_record(x, learner.classify(x), b, r, xn, learner.classify(xn), term)
    learner.plan(learner.classify(xn))


def measure(preset: str, dim: int, ticks: int, steps: int, seed: int = 0) -> dict:
    agent, regions = build_agent(preset, dim, seed)
    for _ in range(agent.config.adjust_interval):  # warm-up: one adjust interval
        _behaviour_step(agent, regions)
    n_sit = len(agent.learner.order)
    # per behaviour step
    times = []
    for _ in range(steps):
        t0 = time.perf_counter()
        _behaviour_step(agent, regions)
        times.append(time.perf_counter() - t0)
    # per tick: a running behaviour that never stops (target = the goal, zero reward)
    xs = [regions.sample(int(regions.rng.integers(N_SITUATIONS))) for _ in range(ticks)]
    agent._run = _Running(x0=xs[0], s0=0, b=0, target=GOAL, planned=True)
    t0 = time.perf_counter()
    for x in xs:
        agent.step(x, 0.0, False)
    tick = (time.perf_counter() - t0) / ticks
    return {
        "config": f"{dim}-D / history {agent.config.history_size}",
        "situations": n_sit,
        "situations_end": len(agent.learner.order),
        "tick_us": tick * 1e6,
        "step_ms_mean": statistics.fmean(times) * 1e3,
        "step_ms_median": statistics.median(times) * 1e3,
        "step_ms_p95": float(np.percentile(times, 95)) * 1e3,
    }


TARGETS = {2: (100.0, 2.0), 8: (300.0, 10.0)}


def run_bench(quick: bool = False) -> list[dict]:
    out = []
    for preset, dim in (("exp1", 2), ("exp3", 8)):
        res = measure(preset, dim, ticks=2000 if quick else 20000, steps=200 if quick else 1000)
        tick_t, step_t = TARGETS[dim]
        res["tick_target_us"], res["step_target_ms"] = tick_t, step_t
        out.append(res)
    return out


def run_learn(steps: int, seeds: list[int], lookahead: int = 0,
              overrides: dict | None = None) -> list[list[float]]:
    from .toyworld import behaviours_per_arrival, run_learning

    curves = []
    for seed in seeds:
        cfg = StnsConfig.preset("exp1", seed=seed, target_lookahead_ticks=lookahead,
                                **(overrides or {}))
        agent = StnsAgent(cfg, 2, 4)
        recs = run_learning(agent, steps, seed=seed)
        curves.append([behaviours_per_arrival(recs[k:k + 1000], 1000)
                       for k in range(0, steps, 1000)])
    return curves


def main(args=None) -> int:
    parser = argparse.ArgumentParser(prog="stns-core-bench", description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="fewer repetitions")
    parser.add_argument("--learn", action="store_true",
                        help="learning check on the kinematic Exp. 1 sketch instead of timing")
    parser.add_argument("--steps", type=int, default=5000, help="behaviour steps (--learn)")
    parser.add_argument("--seeds", type=int, default=3, help="seeds 0..N-1 (--learn)")
    parser.add_argument("--lookahead", type=int, default=0, help="target_lookahead_ticks (--learn)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="config override for --learn, e.g. --set random_stop=reward")
    ns = parser.parse_args(args)
    out = sys.stdout
    if ns.learn:
        for name, value, lowest in (("--steps", ns.steps, 1), ("--seeds", ns.seeds, 1),
                                    ("--lookahead", ns.lookahead, 0)):
            if value < lowest:
                parser.error(f"{name} must be >= {lowest}, got {value}")
        overrides = {}
        for item in ns.set:
            key, eq, value = item.partition("=")
            if not eq:
                parser.error(f"--set takes KEY=VALUE, got {item!r}")
            # run_learn sets these two itself, from the options
            if key == "seed":
                parser.error("--set seed: the seeds are 0..N-1 of --seeds; give --seeds")
            if key == "target_lookahead_ticks":
                parser.error(f"--set target_lookahead_ticks: give --lookahead {value} instead")
            default = getattr(StnsConfig(), key, None)
            try:
                if isinstance(default, bool):  # a typo must not read as False
                    words = {"1": True, "true": True, "yes": True,
                             "0": False, "false": False, "no": False}
                    if value.lower() not in words:
                        parser.error(f"--set {key}: {value!r} is not true or false")
                    overrides[key] = words[value.lower()]
                elif default is not None:
                    overrides[key] = type(default)(value)
                else:
                    overrides[key] = value
            except ValueError:
                kind = {"int": "an integer", "float": "a number"}.get(type(default).__name__,
                                                                      type(default).__name__)
                parser.error(f"--set {key}: {value!r} is not {kind}")
        try:
            StnsConfig.preset("exp1", **overrides)
        except (StnsError, TypeError) as e:
            parser.error(f"--set: {e}")
        curves = run_learn(ns.steps, list(range(ns.seeds)), ns.lookahead, overrides)
        out.write("behaviours per goal arrival by 1000-step block (kinematic Exp. 1 sketch)\n")
        for seed, curve in enumerate(curves):
            out.write(f"seed {seed}: " + " ".join(f"{v:5.2f}" for v in curve) + "\n")
        last = [c[-1] for c in curves]
        out.write(f"last block mean over {len(last)} seeds: {statistics.fmean(last):.2f}\n")
        return 0
    for res in run_bench(ns.quick):
        ok_tick = res["tick_us"] < res["tick_target_us"]
        ok_step = res["step_ms_mean"] < res["step_target_ms"]
        out.write(
            f"{res['config']}, {res['situations']} situations "
            f"({res['situations_end']} at the end):\n"
            f"  per control tick (classification): {res['tick_us']:7.1f} us "
            f"(target < {res['tick_target_us']:.0f} us) {'OK' if ok_tick else 'OVER'}\n"
            f"  per behaviour step (learning + planning): mean {res['step_ms_mean']:.3f} ms, "
            f"median {res['step_ms_median']:.3f} ms, p95 {res['step_ms_p95']:.3f} ms "
            f"(target < {res['step_target_ms']:.0f} ms) {'OK' if ok_step else 'OVER'}\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
