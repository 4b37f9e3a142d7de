"""Shared helpers: synthetic StepRecord-like records with known answers."""

from __future__ import annotations

import json

import numpy as np
from stns_experiments.agents import Record


def make_trials(lengths, kinds=None, success=None, planned=True, dim=2):
    """Records of consecutive trials: trial k has lengths[k] behaviours then an arrival.

    kinds[k][j] / success[k][j] give the situation kind and the outcome of behaviour j of
    trial k (default "0" and None).
    """
    recs = []
    for t, n in enumerate(lengths, start=1):
        for j in range(n):
            kind = kinds[t - 1][j] if kinds else "0"
            succ = success[t - 1][j] if success else None
            recs.append(Record(index=len(recs) + 1, x=np.zeros(dim), situation=1 if kind != "0" else 0,
                               kind=kind, behaviour=0, target=None, planned=planned,
                               reward=0.0, next_situation=0, success=succ, ticks=3,
                               arrival=False, trial=t))
        recs.append(Record(index=len(recs) + 1, x=np.zeros(dim), situation=-1, kind="0",
                           behaviour=None, target=None, planned=False, reward=0.0,
                           next_situation=None, success=None, ticks=0, arrival=True, trial=t))
    return recs


# the params of a small synthetic Exp. 1 run (config.json "params")
PARAMS = {"experiment": "exp1", "steps": 400, "block_size": 100, "final_window": 200,
          "convergence_tol": 0.1, "trailing_window": 200, "random_steps": 60,
          "max_ticks_per_step": 2000, "world": {"preset": "exp1", "overrides": {}},
          "agent": {"preset": "exp1", "overrides": {}}, "save_states": True,
          "figures": False, "config_source": None}


def synthetic_set(key, behaviours, arrivals, final_window_blocks=2, **extra):
    """One trial-set result (sets/KEY.json) with the given block counts; the final window
    is the last ``final_window_blocks`` blocks."""
    fb, fa = sum(behaviours[-final_window_blocks:]), sum(arrivals[-final_window_blocks:])
    return {"key": key, "block_behaviours": behaviours, "block_arrivals": arrivals,
            "final_behaviours": fb, "final_arrivals": fa, "success_r": [9, 10],
            "success_t": [1, 2], "within_two": [3, 4], "situations_final": 6,
            "wall_seconds": 1.0, "steps_per_second": 400.0, "cpu_seconds": 1.0, **extra}


def synthetic_run(folder, seed, sets, params=None, commit="abc1234", agent_config=None,
                  random=None, base_sets=None):
    """A run folder with config.json, summary.json and the trial-set results (and Exp. 2
    pre-training sets in base/), as stns-experiment writes them."""
    p = dict(PARAMS if params is None else params, seed=seed, trial_sets=len(sets))
    (folder / "sets").mkdir(parents=True)
    cfg = {"params": p, "seeds": {}, "command": "stns-experiment ...",
           "world_config": {"seed": seed, "tick_s": 0.1},
           "agent_config": agent_config or {"seed": 0, "p_min": 0.1}}
    (folder / "config.json").write_text(json.dumps(cfg))
    summ = {"experiment": p["experiment"], "seed": seed, "trial_sets": len(sets), "paper": {},
            "code_version": {"commit": commit, "uncommitted": []}}
    (folder / "summary.json").write_text(json.dumps(summ))
    for s in sets:
        (folder / "sets" / f"{s['key']}.json").write_text(json.dumps(s))
    if random is not None:
        (folder / "sets" / "random.json").write_text(json.dumps(random))
    if base_sets is not None:
        (folder / "base" / "sets").mkdir(parents=True)
        for s in base_sets:
            (folder / "base" / "sets" / f"{s['key']}.json").write_text(json.dumps(s))
    return folder
