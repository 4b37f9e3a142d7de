"""The experiments: trial-set tasks (run in worker processes) and their summaries.

Output folder of every experiment::

    summary.json            figures of merit (keys of DESIGN.md + experiment-specific ones)
    config.json             the resolved parameters and the seeds of every trial set
    records/<task>.csv.gz   per-step records of each trial set (records.py columns)
    states/<task>.json      learner state after the trial set (StnsAgent.save)
    sets/<task>.json        small per-task result (block counts, window counts, ...)
    figures/*.png           plots (plots.py)
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from stns_experiments import metrics as M
from stns_experiments import records as R
from stns_experiments.agents import GridAgent, RandomAgent
from stns_experiments.config import ExperimentError
from stns_experiments.runner import run_loop, write_json

PAPER = {
    "exp1": {"convergence_step": 1200, "final_behaviours_to_goal": 2.2,
             "success_rate_r": 0.943, "success_rate_t": 0.921,
             "within_two_behaviours": 0.87, "random_arrivals_per_100": 2.04},
    "exp3": {"final_behaviours_to_goal": 6.85, "success_rate_r": 0.698,
             "success_rate_t2": 0.708, "success_rate_t3": 0.620,
             "random_arrivals_per_100": 1.34, "first_situation_behaviours": 1034.8},
    "offline": {"ratio": 12.1},
    "grid": {"states_8d_polar": 78732, "states_8d_orthogonal": 321489},
}


# ------------------------------------------------------------------ library access
def _libs():
    try:
        import rover_sim
        import stns_core
    except ImportError as e:  # pragma: no cover - depends on the workspace build
        raise ExperimentError(
            f"cannot import the simulator or the learner ({e}); run `make setup` and "
            f"`source env.sh`") from None
    return rover_sim, stns_core


def world_config(params: dict):
    """The run's ``WorldConfig`` (no pybullet world is made)."""
    rover_sim, _ = _libs()
    w = params["world"]
    try:
        return rover_sim.WorldConfig.preset(w["preset"], **w["overrides"])
    except (rover_sim.RoverSimError, TypeError) as e:
        raise ExperimentError(f"world: {e}") from None


def make_world(params: dict, seed: int):
    rover_sim, _ = _libs()
    try:
        return rover_sim.RoverWorld(world_config(params), seed=int(seed))
    except rover_sim.RoverSimError as e:
        raise ExperimentError(f"world: {e}") from None


def make_agent_config(params: dict, seed: int):
    _, stns_core = _libs()
    a = params["agent"]
    try:
        return stns_core.StnsConfig.preset(a["preset"], **{**a["overrides"], "seed": int(seed)})
    except stns_core.StnsError as e:
        raise ExperimentError(f"agent: {e}") from None


def make_agent(params: dict, seed: int, obs_dim: int):
    _, stns_core = _libs()
    cfg = make_agent_config(params, seed)
    return stns_core.StnsAgent(cfg, obs_dim=obs_dim, n_behaviours=4)


def check_params(params: dict) -> None:
    """Build one world config and one agent config to validate presets and overrides."""
    w = params["world"]
    cfg = world_config(params)
    if params.get("range_edges") and cfg.observation_dim != 8:
        raise ExperimentError(
            f"range_edges {params['range_edges']!r} grid the range sensor's sectors, but world "
            f"preset {w['preset']!r} has no range sensor (observation dimension "
            f"{cfg.observation_dim}); use the exp3 world")
    make_agent_config(params, 0)


def load_agent(path: Path):
    _, stns_core = _libs()
    try:
        return stns_core.StnsAgent.load(path)
    except (OSError, stns_core.StnsError) as e:
        raise ExperimentError(f"cannot load learner state {str(path)!r}: {e}") from None


# ------------------------------------------------------------------ explain() digest
def situations_of(agent) -> list[dict[str, Any]]:
    """Situations of an StnsAgent as plain dicts: id, kind, behaviour, parent, positives."""
    info = agent.explain()
    out = []
    for s in info.get("situations", []):
        out.append({
            "id": int(s.get("id", s.get("index", -1))),
            "kind": str(s.get("kind", "?")),
            "behaviour": s.get("behaviour"),
            "parent": s.get("parent"),
            "positives": int(s.get("n_positive", s.get("positives", 0)) or 0),
            "negatives": int(s.get("n_negative", s.get("negatives", 0)) or 0),
            "utility": s.get("utility"),
        })
    return out


def events_of(agent) -> list[dict[str, Any]]:
    return list(agent.explain().get("events", []))


def count_events(events: list[dict], name: str) -> int:
    """Events of the learner's log (explain()["events"]) whose "event" is ``name``."""
    return sum(1 for e in events if e.get("event") == name)


def depth_of(situations: list[dict]) -> dict[int, int]:
    """Behaviour steps from the goal: R = 1, a T-situation = its parent's + 1."""
    by_id = {s["id"]: s for s in situations}
    depth: dict[int, int] = {}

    def d(i: int, seen: frozenset = frozenset()) -> int:
        if i in depth:
            return depth[i]
        s = by_id.get(i)
        if s is None or i in seen:
            return 0
        if s["kind"] == "R":
            depth[i] = 1
        else:
            p = s.get("parent")
            pd = 0 if p is None else d(int(p), seen | {i})
            depth[i] = pd + 1 if pd else 0
        return depth[i]

    for i in by_id:
        d(i)
    return depth


# ------------------------------------------------------------------ per-set result
def window_result(table: dict, n_steps: int, params: dict, situations=None) -> dict:
    """Counts over the final window of one trial set (pooled later over sets)."""
    fw = params["final_window"]
    start = max(0, n_steps - fw)
    b, a = M.span_counts(table, start, n_steps)
    sr = M.success_counts(table, "R", start, n_steps)
    st = M.success_counts(table, "T", start, n_steps)
    w2 = M.within_counts(table, start, n_steps, 2)
    out = {"final_behaviours": b, "final_arrivals": a, "success_r": sr, "success_t": st,
           "within_two": w2, "final_ticks": M.span_ticks(table, start, n_steps),
           "run_ticks": M.span_ticks(table, 0, n_steps),
           "run_arrivals": M.span_counts(table, 0, n_steps)[1]}
    if situations is not None:
        depth = depth_of(situations)
        for k in (2, 3):
            ids = [i for i, d in depth.items() if d == k]
            out[f"success_t{k}"] = M.success_counts(table, "T", start, n_steps, ids)
        out["success_t4plus"] = M.success_counts(
            table, "T", start, n_steps, [i for i, d in depth.items() if d >= 4])
    return out


def _set_paths(out: Path, key: str) -> dict[str, Path]:
    for d in ("records", "states", "sets"):
        (out / d).mkdir(parents=True, exist_ok=True)
    return {"records": out / "records" / f"{key}.csv.gz", "state": out / "states" / f"{key}.npz",
            "result": out / "sets" / f"{key}.json"}


def _finish(task: dict, table: dict, n_steps: int, extra: dict, agent=None,
            t0: float = 0.0) -> dict:
    params, out = task["params"], Path(task["out"])
    paths = _set_paths(out, task["key"])
    R.write_csv(table, paths["records"])
    situations = None
    if agent is not None and hasattr(agent, "explain"):
        situations = situations_of(agent)
        if params["save_states"]:
            agent.save(paths["state"])
    wall = time.monotonic() - t0
    cpu = time.process_time() - task.get("_cpu0", 0.0)
    bs, ar = M.block_counts(table, params["block_size"], n_steps)
    res = {
        "key": task["key"], "index": task["index"], "seeds": task["seeds"], "steps": n_steps,
        "block_behaviours": bs.tolist(), "block_arrivals": ar.tolist(),
        "wall_seconds": wall, "steps_per_second": n_steps / wall if wall > 0 else None,
        "cpu_seconds": cpu, "steps_per_cpu_second": n_steps / cpu if cpu > 0 else None,
        "situations_final": None if situations is None else len(situations),
        "situations": situations,
        **window_result(table, n_steps, params, situations), **extra,
    }
    write_json(paths["result"], res)
    return res


# ------------------------------------------------------------------ tasks
def task_stns(task: dict, progress) -> dict:
    """One STNS trial set from scratch (Exp. 1, Exp. 3, the pre-training of Exp. 2)."""
    t0 = time.monotonic()
    params, seeds = task["params"], task["seeds"]
    world = make_world(params, seeds["world_seed"])
    try:
        for name, value in task.get("faults", {}).items():
            world.set_fault(name, value)
        agent = make_agent(params, seeds["agent_seed"], world.observation_dim)
        steps = task["steps"]
        watch = FirstExtraction(agent, progress)
        recs, _ = run_loop(world, agent, steps, watch, params["max_ticks_per_step"])
    finally:
        world.close()
    table = R.head(R.to_table(recs), steps)
    extra = {"first_situation_step": first_situation_step(table),
             "first_extraction_step": watch.step,
             "first_extraction_behaviours": behaviours_up_to(table, watch.step)}
    return _finish(task, table, steps, extra, agent, t0)


class FirstExtraction:
    """A progress callback that notes the first behaviour step after which the learner
    holds a situation (§7.3 counts the behaviours "needed for extracting the first
    situation"), passing each call on to ``progress``."""

    def __init__(self, agent, progress) -> None:
        self.agent, self.progress = agent, progress
        self.step: int | None = None

    def __call__(self, steps: int) -> None:
        if self.step is None and self.agent.learner.by_id:
            # the record count at creation: a goal arrival's record follows the behaviour
            # that extracted an R-situation within the same call
            self.step = min(int(s.created) for s in self.agent.learner.by_id.values())
        if self.progress is not None:
            self.progress(steps)


def first_situation_step(table: dict) -> int | None:
    """Step of the first record classified into a situation (not 0): its first use."""
    idx = np.nonzero((table["situation"] > 0) & ~table["arrival"])[0]
    return int(table["step"][idx[0]]) if len(idx) else None


def behaviours_up_to(table: dict, step: int | None) -> int | None:
    """Behaviours (records that are not goal arrivals) among steps 1..``step``."""
    if step is None:
        return None
    return int(((table["step"] <= step) & ~table["arrival"]).sum())


def task_random(task: dict, progress) -> dict:
    """The random policy on the same world: goal arrivals per 100 behaviour steps."""
    t0 = time.monotonic()
    params, seeds = task["params"], task["seeds"]
    world = make_world(params, seeds["world_seed"])
    try:
        agent = RandomAgent(np.random.default_rng(seeds["agent_seed"]), params["max_ticks_per_step"])
        recs, _ = run_loop(world, agent, task["steps"], progress, params["max_ticks_per_step"] + 1)
    finally:
        world.close()
    table = R.head(R.to_table(recs), task["steps"])
    res = {"key": task["key"], "steps": task["steps"], "arrivals": int(table["arrival"].sum()),
           "behaviours": int((~table["arrival"]).sum()), "wall_seconds": time.monotonic() - t0,
           "arrivals_per_100": M.arrivals_per_100(table)}
    write_json(_set_paths(Path(task["out"]), task["key"])["result"], res)
    return res


def task_grid(task: dict, progress) -> dict:
    """One trial set of a tabular grid learner (§7.5)."""
    t0 = time.monotonic()
    params, seeds = task["params"], task["seeds"]
    world = make_world(params, seeds["world_seed"])
    try:
        agent = GridAgent(task["grid"], task["learner"], np.random.default_rng(seeds["agent_seed"]),
                          gamma=params["gamma"], initial_value=params["initial_value"],
                          alpha=params["alpha"], epsilon=params["epsilon"],
                          sweeps=params["sweeps"], max_ticks=params["max_ticks_per_step"],
                          range_edges=tuple(params["range_edges"]))
        recs, _ = run_loop(world, agent, task["steps"], progress, params["max_ticks_per_step"] + 1)
    finally:
        world.close()
    table = R.head(R.to_table(recs), task["steps"])
    extra = {"grid": task["grid"], "learner": task["learner"],
             "cells_visited": int((agent.n.sum(axis=1) > 0).sum()), "cells": agent.n_cells}
    return _finish(task, table, task["steps"], extra, None, t0)


def task_exp2(task: dict, progress) -> dict:
    """Exp. 2: a learner trained without the fault continues with it, or one from scratch."""
    t0 = time.monotonic()
    params, seeds = task["params"], task["seeds"]
    world = make_world(params, seeds["world_seed"])
    try:
        world.set_fault(task["fault_name"], task["fault_value"])
        steps = task["steps"]
        extra: dict[str, Any] = {"mode": task["mode"], "level": task["level"],
                                 "fault": {task["fault_name"]: task["fault_value"]}}
        if task["mode"] == "relearn":
            agent = load_agent(Path(task["base_state"]))
            before = situations_of(agent)
            base = agent.behaviour_steps
            # the agent's event log is a bounded deque: collect it every 250 steps
            seen: dict[str, dict] = {}
            recs, state = [], None
            prog = progress_offset(progress, base)
            for target in range(base + 250, base + steps + 250, 250):
                part, state = run_loop(world, agent, min(target, base + steps), prog,
                                       params["max_ticks_per_step"], state)
                recs += part
                for e in events_of(agent):
                    if int(e.get("step", 0)) > base:
                        seen[json.dumps(e, sort_keys=True, default=str)] = e
            new_events = sorted(seen.values(), key=lambda e: int(e.get("step", 0)))
            after_ids = {s["id"] for s in situations_of(agent)}
            extra.update({
                "base_steps": base,
                "situations_before": len(before),
                "original_situations_gone": sum(1 for s in before if s["id"] not in after_ids),
                "eliminated_after_fault": count_events(new_events, "eliminated"),
                "redefined_after_fault": count_events(new_events, "redefined"),
                "extracted_after_fault": count_events(new_events, "extracted"),
                "eliminations": [
                    {k: e.get(k) for k in ("step", "situation", "kind", "behaviour", "reason")}
                    for e in new_events if e.get("event") == "eliminated"],
            })
        else:
            agent = make_agent(params, seeds["agent_seed"], world.observation_dim)
            recs, _ = run_loop(world, agent, steps, progress, params["max_ticks_per_step"])
    finally:
        world.close()
    table = R.head(R.to_table(recs), steps)
    return _finish(task, table, steps, extra, agent, t0)


def progress_offset(progress, base: int):
    if progress is None:
        return None
    return lambda steps: progress(steps - base)


def task_offline(task: dict, progress) -> dict:
    """§7.4: STNS on-line for ``steps``, then random behaviours until every situation has as
    many positive instances as the on-line learner had (situations frozen)."""
    t0 = time.monotonic()
    params, seeds = task["params"], task["seeds"]
    world = make_world(params, seeds["world_seed"])
    try:
        agent = make_agent(params, seeds["agent_seed"], world.observation_dim)
        recs, _ = run_loop(world, agent, task["steps"], progress, params["max_ticks_per_step"])
        table = R.head(R.to_table(recs), task["steps"])
        online_behaviours = int((~table["arrival"]).sum())
        sits = [s for s in situations_of(agent) if s["kind"] in ("R", "T")]
        r_min = float(agent.config.r_min_r) if hasattr(agent, "config") else 5.0
        rng = np.random.default_rng(seeds["rng_seed"])
        rand = offline_random(world, agent, sits, rng, params["max_random_behaviours"],
                              params["max_ticks_per_step"], r_min)
    finally:
        world.close()
    extra = {"online_behaviours": online_behaviours, "online_steps": task["steps"],
             "targets": {str(s["id"]): s["positives"] for s in sits},
             "target_kinds": {str(s["id"]): s["kind"] for s in sits}, **rand}
    return _finish(task, table, task["steps"], extra, agent, t0)


def offline_random(world, agent, sits: list[dict], rng, max_behaviours: int, max_ticks: int,
                   r_min: float) -> dict:
    """Random behaviours with the frozen segmentation: a behaviour stops on a reward or when
    the classified situation changes. A behaviour is a positive instance of every situation
    whose condition behaviour it was and whose result it met (op. 1 of §5.3). Runs until
    every situation has its on-line count (``collected_at``); ``totals_collected_at`` is the
    behaviour by which the R and the T positives, each summed over the situations of that
    kind, had reached their on-line sums (None if never, within ``max_behaviours``)."""
    need = {s["id"]: s["positives"] for s in sits}
    have = dict.fromkeys(need, 0)
    done_at: dict[int, int | None] = dict.fromkeys(need, None)
    kind = {s["id"]: s["kind"] for s in sits}
    # §7.4's figures are totals over all R- (T-) situations (its 225.5 R positives are below
    # its 232 arrivals in 1200 steps), so also note when the totals of each kind are reached.
    need_total = {k: sum(v for i, v in need.items() if kind[i] == k) for k in ("R", "T")}
    have_total = dict.fromkeys(need_total, 0)
    totals_at: int | None = 0 if all(v <= 0 for v in need_total.values()) else None
    behaviours = arrivals = 0
    by_b: dict[int, list[dict]] = {}
    for s in sits:
        if s["behaviour"] is not None:
            by_b.setdefault(int(s["behaviour"]), []).append(s)
    obs, _ = world.reset()
    remaining = {i for i in need if need[i] > 0}
    for i in need:
        if need[i] <= 0:
            done_at[i] = 0
    while remaining and behaviours < max_behaviours:
        b = int(rng.integers(4))
        s0 = agent.classify(obs)
        reward, ticks, term = 0.0, 0, False
        while True:
            obs, r, term, trunc, _ = world.step(b)
            ticks += 1
            reward += r
            if term or r != 0.0 or ticks >= max_ticks:
                break
            if agent.classify(obs) != s0:
                break
        behaviours += 1
        s1 = None if term else agent.classify(obs)
        for s in by_b.get(b, []):
            met = (reward >= r_min) if s["kind"] == "R" else (s1 is not None and s1 == s["parent"])
            if met:
                have[s["id"]] += 1
                have_total[s["kind"]] += 1
                if s["id"] in remaining and have[s["id"]] >= need[s["id"]]:
                    remaining.discard(s["id"])
                    done_at[s["id"]] = behaviours
        if totals_at is None and all(have_total[k] >= need_total[k] for k in need_total):
            totals_at = behaviours
        if term:
            arrivals += 1
            obs, _ = world.reset()
    return {"random_behaviours": behaviours, "random_arrivals": arrivals,
            "all_collected": not remaining, "collected": {str(k): v for k, v in have.items()},
            "collected_at": {str(k): v for k, v in done_at.items()},
            "totals_needed": need_total, "totals_collected_at": totals_at}


# ------------------------------------------------------------------ summaries
def offline_figures(sets: list[dict], behaviours_per_arrival: float | None) -> dict:
    """§7.4's figures from ``task_offline`` results.

    The paper's "average number of positive instances of all R-Situations" (225.5) is read as
    the sum over a trial set's R-situations, averaged over sets (its 1200 steps held only
    232 arrivals), and likewise for T. Two measured ratios: random behaviours until *every*
    situation has its own on-line count, and until the sums of each kind are reached (the
    paper's arithmetic, which prices one pool of R positives and one of T positives). The
    arithmetic itself is repeated with our rates: (R sum x random behaviours per arrival +
    T sum x 4) / on-line behaviours, per-set means as in the paper.
    """
    n = len(sets)
    online = sum(r["online_behaviours"] for r in sets)
    rand = sum(r["random_behaviours"] for r in sets)

    def per_kind(r: dict, kind: str) -> list[int]:
        return [v for k, v in r["targets"].items() if r["target_kinds"][k] == kind]

    pos_r = [v for r in sets for v in per_kind(r, "R")]
    pos_t = [v for r in sets for v in per_kind(r, "T")]
    sum_r = float(np.mean([sum(per_kind(r, "R")) for r in sets]))
    sum_t = float(np.mean([sum(per_kind(r, "T")) for r in sets]))
    # results written before 2 Dec have no sums: no figure rather than a wrong bound
    has_totals = all("totals_collected_at" in r for r in sets)
    totals_at = [r.get("totals_collected_at") for r in sets]
    rand_totals = (sum(r["random_behaviours"] if at is None else at  # not reached: all of it
                       for r, at in zip(sets, totals_at, strict=True))
                   if has_totals else None)
    est = None
    if online and behaviours_per_arrival:
        est = (sum_r * behaviours_per_arrival + sum_t * 4.0) / (online / n)
    return {
        "online_behaviours_mean": online / n,
        "random_behaviours_mean": rand / n,
        "sets_all_collected": sum(1 for r in sets if r["all_collected"]),
        "ratio_measured": rand / online if online else None,
        "ratio_measured_per_set": [r["random_behaviours"] / r["online_behaviours"]
                                   for r in sets if r["online_behaviours"]],
        "ratio_is_lower_bound": any(not r["all_collected"] for r in sets),
        "positives_r_mean": float(np.mean(pos_r)) if pos_r else None,
        "positives_t_mean": float(np.mean(pos_t)) if pos_t else None,
        "positives_r_sum_mean": sum_r, "positives_t_sum_mean": sum_t,
        "situations_r_mean": len(pos_r) / n, "situations_t_mean": len(pos_t) / n,
        "random_behaviours_totals_mean": None if rand_totals is None else rand_totals / n,
        "ratio_measured_totals": rand_totals / online if online and rand_totals is not None
        else None,
        "ratio_totals_is_lower_bound": None in totals_at,
        "ratio_paper_arithmetic": est,
        "paper_arithmetic": "(R positives summed over the R-situations x random behaviours per "
                            "arrival + T positives summed x 4) / on-line behaviours, per-set "
                            "means, as in §7.4",
    }


def pooled(results: list[dict], key: str) -> tuple[int, int]:
    num = sum(int(r[key][0]) for r in results if r.get(key) is not None)
    den = sum(int(r[key][1]) for r in results if r.get(key) is not None)
    return num, den


def final_level(results: list[dict]) -> float | None:
    """Behaviours to goal over the final window, pooled over trial-set results (None when
    there are none)."""
    if not results:
        return None
    return float(M.ratio(sum(r["final_behaviours"] for r in results),
                         sum(r["final_arrivals"] for r in results)))


def summarise_sets(results: list[dict], params: dict, steps: int) -> dict:
    """Pooled figures of a group of trial-set results with the same block layout."""
    B = params["block_size"]
    if not results:
        return {"trial_sets": 0}
    bs = np.array([r["block_behaviours"] for r in results], dtype=np.int64)
    ar = np.array([r["block_arrivals"] for r in results], dtype=np.int64)
    curve = M.ratio(bs.sum(0), ar.sum(0))
    per_set = M.ratio(bs, ar)
    final = final_level(results)
    tol, tw = params["convergence_tol"], params["trailing_window"]
    conv = M.convergence_block(curve, final, B, tol)
    conv_tr = M.convergence_trailing(bs.sum(0), ar.sum(0), final, B, tw, tol)
    per_set_conv, per_set_conv_tr, per_set_final = [], [], []
    for i, r in enumerate(results):
        f_i = float(M.ratio(r["final_behaviours"], r["final_arrivals"]))
        per_set_final.append(f_i)
        per_set_conv.append(M.convergence_block(per_set[i], f_i, B, tol))
        per_set_conv_tr.append(M.convergence_trailing(bs[i], ar[i], f_i, B, tw, tol))
    lo, hi = M.percentile_band(per_set)
    out = {
        "trial_sets": len(results),
        "behaviours_to_goal_by_block": curve.tolist(),
        "behaviours_to_goal_by_block_q25": lo.tolist(),
        "behaviours_to_goal_by_block_q75": hi.tolist(),
        "final_behaviours_to_goal": final,
        "final_behaviours_to_goal_per_set": per_set_final,
        "convergence_step": conv,
        "convergence_step_trailing": conv_tr,
        "convergence_step_per_set": per_set_conv,
        "convergence_step_trailing_per_set": per_set_conv_tr,
        "convergence_step_per_set_median": _median(per_set_conv),
        "convergence_step_trailing_per_set_median": _median(per_set_conv_tr),
        "success_rate_r": M.frac(*pooled(results, "success_r")),
        "success_rate_t": M.frac(*pooled(results, "success_t")),
        "success_counts_r": list(pooled(results, "success_r")),
        "success_counts_t": list(pooled(results, "success_t")),
        "within_two_behaviours": M.frac(*pooled(results, "within_two")),
        "within_two_counts": list(pooled(results, "within_two")),
        # control time per arrival (None for results written before the tick counts)
        "final_ticks_per_arrival": _ticks_per_arrival(results, "final_ticks", "final_arrivals"),
        "ticks_per_arrival": _ticks_per_arrival(results, "run_ticks", "run_arrivals"),
    }
    for k in ("success_t2", "success_t3", "success_t4plus"):
        if any(r.get(k) is not None for r in results):
            out[k.replace("success_", "success_rate_")] = M.frac(*pooled(results, k))
    sits = [r["situations_final"] for r in results if r.get("situations_final") is not None]
    out["situations_final"] = float(np.mean(sits)) if sits else None
    out["situations_final_per_set"] = sits
    walls = [r["wall_seconds"] for r in results]
    sps = [r["steps_per_second"] for r in results if r.get("steps_per_second")]
    out["set_wall_seconds_mean"] = float(np.mean(walls))
    cpus = [r["cpu_seconds"] for r in results if r.get("cpu_seconds")]
    if cpus:
        out["set_cpu_seconds_mean"] = float(np.mean(cpus))
        out["behaviour_steps_per_cpu_second"] = float(steps * len(cpus) / np.sum(cpus))
    out["behaviour_steps_per_second"] = float(np.mean(sps)) if sps else None
    for key in ("first_situation_step", "first_extraction_step", "first_extraction_behaviours"):
        vals = [r.get(key) for r in results if r.get(key)]
        if vals:
            out[f"{key}_mean"] = float(np.mean(vals))
            out[f"{key}_sets"] = len(vals)
    return out


def _ticks_per_arrival(results: list[dict], ticks: str, arrivals: str) -> float | None:
    """Pooled control ticks per goal arrival (sum / sum); None if a result lacks the counts
    or no set arrived."""
    if any(r.get(ticks) is None or r.get(arrivals) is None for r in results):
        return None
    a = sum(r[arrivals] for r in results)
    return None if a == 0 else float(sum(r[ticks] for r in results) / a)


def _median(values: list) -> float | None:
    v = [x for x in values if x is not None]
    return float(np.median(v)) if v and len(v) * 2 > len(values) else None


def random_summary(results: list[dict]) -> dict:
    if not results:
        return {"random_arrivals_per_100": None}
    arr = sum(r["arrivals"] for r in results)
    steps = sum(r["steps"] for r in results)
    return {"random_arrivals_per_100": 100.0 * arr / steps if steps else None,
            "random_behaviours_per_arrival": (steps - arr) / arr if arr else None,
            "random_steps": steps, "random_arrivals": arr}


def delay_figures(relearn: dict, scratch: dict, block_size: int, tol: float) -> dict:
    """Relearn against scratch: when each curve reaches scratch's final level for good."""
    level = scratch.get("final_behaviours_to_goal")
    if level is None or not math.isfinite(level):
        return {"scratch_level": None, "delay_steps": None}
    rc = np.array(relearn["behaviours_to_goal_by_block"], dtype=float)
    sc = np.array(scratch["behaviours_to_goal_by_block"], dtype=float)
    tr = M.first_block_at_or_below(rc, level, block_size, tol)
    ts = M.first_block_at_or_below(sc, level, block_size, tol)
    return {"scratch_level": level, "relearn_reaches_at": tr, "scratch_reaches_at": ts,
            "delay_steps": None if tr is None or ts is None else tr - ts}


def exp2_level_entry(level: float, fault: dict, relearn: list[dict], scratch: list[dict],
                     params: dict, prefault_level: float | None) -> dict:
    """Exp. 2 figures of one fault level from its relearning and from-scratch trial sets:
    pooled curves, eliminations, blocks above the pre-fault band and the delay."""
    tol = params["convergence_tol"]
    entry: dict[str, Any] = {"level": level, "fault": fault}
    if relearn:
        entry["relearn"] = summarise_sets(relearn, params, params["steps"])
        elim = [r.get("eliminated_after_fault") for r in relearn]
        gone = [r.get("original_situations_gone") for r in relearn]
        entry["eliminated_after_fault_mean"] = float(np.mean([e or 0 for e in elim]))
        entry["sets_without_elimination"] = sum(1 for e in elim if not e)
        entry["original_situations_gone_mean"] = float(np.mean([g or 0 for g in gone]))
        entry["situations_before_mean"] = float(np.mean([r.get("situations_before") or 0
                                                          for r in relearn]))
        if prefault_level is not None and math.isfinite(prefault_level):
            curve = np.array(entry["relearn"]["behaviours_to_goal_by_block"], float)
            worse = ~(np.isfinite(curve) & (curve <= (1 + tol) * prefault_level))
            entry["blocks_worse_than_prefault"] = int(worse.sum())
            entry["prefault_level"] = prefault_level
    if scratch:
        entry["scratch"] = summarise_sets(scratch, params, params["steps"])
    if relearn and scratch:
        entry.update(delay_figures(entry["relearn"], entry["scratch"], params["block_size"], tol))
    return entry


TASK_FUNCTIONS = {"stns": task_stns, "random": task_random, "grid": task_grid,
                  "exp2": task_exp2, "offline": task_offline}


def dispatch(task: dict, progress) -> dict:
    """Worker entry: run the task function named by ``task["fn"]``."""
    task = {**task, "_cpu0": time.process_time()}
    return TASK_FUNCTIONS[task["fn"]](task, progress)
