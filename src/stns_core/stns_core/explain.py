"""Explanation as plain, json-serialisable data (issue 4: situations, plan, events)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from .categorical import GOAL
from .situation import T_KIND

if TYPE_CHECKING:
    from .agent import StnsAgent


def _target(d: int | None):
    return "goal" if d == GOAL else d


def explain(agent: StnsAgent, fresh_utilities: bool = True) -> dict[str, Any]:
    learner = agent.learner
    utilities = (learner.compute_utilities_readonly() if fresh_utilities
                 else {s.id: s.utility for s in learner.order})
    run = agent._run
    plan: list[dict[str, Any]] = []
    if run is not None and run.planned:
        plan.append({"behaviour": run.b, "target": _target(run.target), "running": True})
    plan += [{"behaviour": b, "target": _target(d), "running": False} for b, d in agent._plan]
    situations = []
    for rank, sit in enumerate(learner.order):
        situations.append({
            "id": sit.id,
            "rank": rank,
            "kind": sit.kind,
            "behaviour": sit.behaviour,
            "parent": sit.parent if sit.kind == T_KIND else None,
            "goal_reward": sit.reward_key if sit.kind != T_KIND else None,
            "utility": float(utilities[sit.id]),
            "n_positive": sit.n_pos,
            "n_negative": sit.n_neg,
            "mean": [float(v) for v in sit.mean],
            "cov": [[float(v) for v in row] for row in sit.cov],
            "boundary": float(sit.boundary),
            "fitted": bool(sit.fitted),
            "created": sit.created,
        })
    return {
        "behaviour_steps": agent.behaviour_steps,
        "trial": agent.trial,
        "current_situation": int(agent._current),
        "running": None if run is None else {
            "behaviour": run.b, "target": _target(run.target), "planned": run.planned,
            "ticks": run.ticks, "start_situation": run.s0},
        "master_plan": plan,
        "plan_utility": float(agent._plan_utility),
        "order": [s.id for s in learner.order],
        "situations": situations,
        "events": [dict(e) for e in learner.events],
        "event_count": learner.event_count,
        "obs_dim": agent.obs_dim,
        "n_behaviours": agent.n_behaviours,
        "config": agent.config.to_dict(),
    }
