"""The tick protocol of docs/INTERFACES.md, end to end on the kinematic toy world."""

import json

import numpy as np
import pytest
from stns_core.toyworld import KinematicRover, run_learning

from stns_core import StepRecord, StnsAgent, StnsConfig


def test_tick_protocol_records_and_arrival():
    agent = StnsAgent(StnsConfig.preset("exp1", seed=1), obs_dim=2, n_behaviours=4)
    world = KinematicRover(seed=1)
    obs, reward, terminated = world.reset(), 0.0, False
    arrivals = 0
    while arrivals < 3:
        action = agent.step(obs, reward, terminated)
        if action is None:
            arrivals += 1
            obs, reward, terminated = world.reset(), 0.0, False
            continue
        assert 0 <= action < 4
        obs, reward, terminated = world.step(action)
    records = agent.pop_records()
    assert all(isinstance(r, StepRecord) for r in records)
    assert [r.index for r in records] == list(range(len(records)))
    assert agent.behaviour_steps == len(records)
    arrival_records = [r for r in records if r.arrival]
    assert len(arrival_records) == 3
    assert all(r.behaviour is None for r in arrival_records)
    # the step just before each arrival got the goal reward and ended the trial
    for r in arrival_records:
        before = records[r.index - 1]
        assert not before.arrival and before.reward >= 10.0 and before.trial == r.trial
    assert [r.trial for r in arrival_records] == [0, 1, 2]
    assert agent.pop_records() == []


def test_learns_and_explains():
    agent = StnsAgent(StnsConfig.preset("exp1", seed=2), obs_dim=2, n_behaviours=4)
    run_learning(agent, 600, seed=2)
    ex = agent.explain()
    json.dumps(ex)
    assert ex["situations"], "no situation extracted in 600 steps"
    assert {s["kind"] for s in ex["situations"]} <= {"R", "T"}
    assert agent.classify(np.array(ex["situations"][0]["mean"])) in ex["order"] + [0]


def test_same_seed_same_decisions():
    def actions(seed):
        agent = StnsAgent(StnsConfig.preset("exp1", seed=seed), obs_dim=2, n_behaviours=4)
        recs = run_learning(agent, 400, seed=5)
        return [(r.behaviour, r.ticks, r.next_situation) for r in recs]

    assert actions(3) == actions(3)
    assert actions(3) != actions(4)


@pytest.mark.parametrize("preset", ["exp1", "exp3"])
def test_presets(preset):
    cfg = StnsConfig.preset(preset)
    assert cfg.gamma == 0.7 and cfg.n_max == 7


def test_learning_smoke_exp1_kinematic():
    """After 3000 behaviour steps the learner needs far fewer behaviours than random (~40)."""
    from stns_core.toyworld import behaviours_per_arrival

    agent = StnsAgent(StnsConfig.preset("exp1", seed=0), obs_dim=2, n_behaviours=4)
    records = run_learning(agent, 3000, seed=0)
    assert behaviours_per_arrival(records[-1000:], 1000) < 4.0
    kinds = {s["kind"] for s in agent.explain()["situations"]}
    assert kinds == {"R", "T"}
    planned = [r for r in records[-1000:] if r.planned and r.kind in ("R", "T")]
    assert sum(r.success for r in planned) / len(planned) > 0.7


def test_iprl_memo_does_not_change_the_agents_decisions():
    out = []
    for memo in (True, False):
        agent = StnsAgent(StnsConfig.preset("exp1", seed=4, iprl_memo=memo), 2, 4)
        out.append([(r.behaviour, r.target, r.ticks) for r in run_learning(agent, 900, seed=4)])
    assert out[0] == out[1]
