"""Tick protocol details: stop rules, look-ahead, plan execution, input validation."""

import numpy as np
import pytest
from conftest import ring

from stns_core import (
    StnsAgent,
    StnsConfig,
    StnsDimensionError,
    StnsError,
    StnsInputError,
)

R_PTS = ring((0.0, 0.0), 2.0, 8)[[0, 4, 2, 6, 1, 5, 3, 7]]
FAR = np.array([30.0, 0.0])


def agent_with_r_situation(**overrides):
    cfg = StnsConfig(n_init_r=3, n_min_r=3, n_init_t=5, n_min_t=3, history_size=300,
                     **overrides)
    agent = StnsAgent(cfg, obs_dim=2, n_behaviours=4)
    lr = agent.learner
    for p in R_PTS[:4]:
        lr.add_record(p, lr.classify(p), 0, 10.0, p, lr.classify(p), True)
    assert len(lr.order) == 1
    return agent, lr.order[0].id


def test_first_call_random_when_no_plan_has_positive_utility():
    agent = StnsAgent(StnsConfig(seed=5), obs_dim=2, n_behaviours=4)
    a = agent.step(FAR, 0.0, False)
    assert agent._run.planned is False and 0 <= a < 4
    draws = np.random.default_rng(5).integers(4)
    assert a == draws  # from the config's seeded generator


@pytest.mark.parametrize("random_stop,stops", [("situation_change", True), ("reward", False)])
def test_random_behaviour_stop_reading(random_stop, stops):
    agent, rid = agent_with_r_situation(random_stop=random_stop)
    a = agent.step(FAR, 0.0, False)
    assert agent._run.planned is False
    out = agent.step(np.array([0.2, 0.0]), 0.0, False)  # now classified into R
    recs = agent.pop_records()
    if stops:
        assert len(recs) == 1 and recs[0].next_situation == rid and recs[0].planned is False
        assert recs[0].success is None and recs[0].ticks == 1 and recs[0].behaviour == a
    else:
        assert recs == [] and out == a
    agent.step(np.array([0.3, 0.0]), -1.0, False)  # any reward stops any behaviour
    assert len(agent.pop_records()) == 1


def trained_agent(**overrides):
    """R (b=0) at the origin; from FAR, behaviour 2 always reaches it: plan [(2, R), (0, goal)]."""
    agent, rid = agent_with_r_situation(**overrides)
    lr = agent.learner
    inside = np.array([0.5, 0.0])
    for k in range(3):
        x = FAR + k
        lr.add_record(x, lr.classify(x), 2, 0.0, inside, lr.classify(inside), False)
    assert lr.plan(0)[1] == [(2, rid), (0, -1)]
    return agent, rid


def test_planned_behaviour_stops_at_target_then_plan_goes_on():
    agent, rid = trained_agent()
    assert agent.step(FAR, 0.0, False) == 2
    assert agent._run.target == rid and agent._run.planned
    assert agent.step(FAR + [-5.0, 0.0], 0.0, False) == 2  # margin still: goes on
    nxt = agent.step(np.array([0.4, 0.1]), 0.0, False)
    rec = agent.pop_records()[-1]
    assert rec.success is True and rec.target == rid and rec.ticks == 2
    assert nxt == 0 and agent._run.target == -1  # second plan element: goal by behaviour 0
    assert agent.explain()["master_plan"][0] == {"behaviour": 0, "target": "goal", "running": True}
    assert agent.step(np.array([0.4, 0.0]), 10.0, True) is None  # goal arrival
    recs = agent.pop_records()
    assert recs[0].success is True and recs[0].reward == 10.0 and recs[0].target is None
    assert recs[1].arrival and recs[1].behaviour is None and recs[1].next_situation is None
    assert agent.trial == 1


@pytest.mark.parametrize("lookahead", [0, 1, 3])
def test_target_lookahead_goes_on_while_inside(lookahead):
    agent, rid = trained_agent(target_lookahead_ticks=lookahead)
    start = np.array([2.5, 0.0])  # just outside R, moving inwards
    assert agent.learner.classify(start) == 0
    assert agent.step(start, 0.0, False) == 2
    inside = [np.array([1.5 - 0.1 * k, 0.0]) for k in range(5)]
    for k, x in enumerate(inside):
        agent.step(x, 0.0, False)
        recs = agent.pop_records()
        if recs:
            assert k == lookahead and recs[0].ticks == lookahead + 1
            assert recs[0].next_situation == rid and recs[0].success
            break
    else:
        pytest.fail("never stopped")


def test_lookahead_stops_when_the_next_tick_would_leave_the_target():
    agent, rid = trained_agent(target_lookahead_ticks=3)
    agent.step(FAR, 0.0, False)
    agent.step(np.array([1.0, 0.0]), 0.0, False)  # entered; extrapolation (1.0 - 29) is out
    rec = agent.pop_records()[0]
    assert rec.ticks == 1 and rec.success and rec.next_situation == rid


def test_lookahead_leaving_the_target_after_all_is_recorded_honestly():
    agent, rid = trained_agent(target_lookahead_ticks=3)
    agent.step(np.array([0.6, 0.0]), 0.0, False)
    assert agent.learner.classify(np.array([0.6, 0.0])) == rid
    agent._run.target = rid  # (the plan starts inside R here; force the look-ahead case)
    agent.step(np.array([0.5, 0.0]), 0.0, False)  # inside, extrapolation inside: go on
    assert agent.pop_records() == []
    out = np.array([9.0, 9.0])
    assert agent.learner.classify(out) == 0
    agent.step(out, 0.0, False)  # jumped out against the extrapolation
    rec = agent.pop_records()[0]
    assert rec.next_situation == 0 and rec.success is False and rec.ticks == 2
    h = agent.learner.hist
    slot = (h.head - 1) % h.capacity
    assert np.array_equal(h.x_next[slot], out)


def _run_through_target(agent, xs):
    """Feed a straight run of inputs; return the record that closed first."""
    for x in xs:
        agent.step(np.array([x, 0.0]), 0.0, False)
        recs = agent.pop_records()
        if recs:
            return recs[0]
    pytest.fail("never stopped")


RUN_THROUGH_R = [2.5 - 0.3 * k for k in range(12)]  # 2.5 (margin), 2.2 (R boundary), ... -0.8


@pytest.mark.parametrize("stop,cap,end,ticks", [
    ("first", 0, 1.9, 2),       # faithful: the first tick classified into the target
    ("deepest", 0, 0.1, 8),     # on while the next tick would be nearer the centre
    ("deepest", 2, 1.3, 4),     # at most 2 ticks more inside
])
def test_target_stop_reading(stop, cap, end, ticks):
    agent, rid = trained_agent(target_stop=stop, target_lookahead_ticks=cap)
    h = agent.learner.hist
    assert agent.learner.classify(np.array([2.2, 0.0])) == 0  # R's boundary lies within 2.2
    rec = _run_through_target(agent, RUN_THROUGH_R)
    assert rec.success is True and rec.next_situation == rid and rec.ticks == ticks
    assert h.x_next[(h.head - 1) % h.capacity][0] == pytest.approx(end)


def test_target_stop_deepest_into_the_margin_stops_at_once():
    agent, rid = trained_agent(target_stop="deepest")
    agent.step(np.array([0.5, 0.0]), 0.0, False)
    agent._run.planned, agent._run.target = True, 0  # (a plan may target the margin)
    rec = _run_through_target(agent, [9.0, 8.0])
    assert rec.ticks == 1 and rec.success is True and rec.next_situation == 0


@pytest.mark.parametrize("plan_stop,stops", [("target", False), ("higher_utility", True)])
def test_plan_stop_reading(plan_stop, stops):
    agent, rid = trained_agent(plan_stop=plan_stop)
    lr = agent.learner
    inside = np.array([0.5, 0.0])
    for k in range(6):  # a T-situation (behaviour 2 -> R) around FAR
        x = FAR + [0.0, 0.5 * k]
        lr.add_record(x, lr.classify(x), 2, 0.0, inside, lr.classify(inside), False)
    tid = next(s.id for s in lr.order if s.kind == "T")
    lr.by_id[rid].utility, lr.by_id[tid].utility = 7.0, 4.9
    agent.step(np.array([10.0, 10.0]), 0.0, False)
    agent._run.planned, agent._run.target = True, tid  # heading for T, passing through R
    agent.step(np.array([0.4, 0.0]), 0.0, False)
    recs = agent.pop_records()
    if stops:
        assert len(recs) == 1 and recs[0].next_situation == rid and recs[0].success is False
    else:
        assert recs == [] and agent._run.target == tid


PASS_BY_R = [np.array([x, 5.0]) for x in (5.0, 4.0, 3.0, 2.0, 1.0, 0.0, -1.0, -2.0, -3.0)]


@pytest.mark.parametrize("miss_stop,started_in_r,ticks", [
    ("never", False, None),  # faithful: runs on past R (until a reward or the target)
    ("margin", False, 6),   # stops at (0, 5), nearest R's centre; the next tick is farther
    ("all", False, 6),
    ("margin", True, None),  # "margin" judges only behaviours started in the margin
    ("all", True, 6),
])
def test_miss_stop_reading(miss_stop, started_in_r, ticks):
    agent, rid = trained_agent(miss_stop=miss_stop)
    assert all(agent.learner.classify(x) == 0 for x in PASS_BY_R)  # R is never entered
    assert agent.step(np.array([6.0, 5.0]), 0.0, False) == 2
    assert agent._run.planned and agent._run.target == rid
    if started_in_r:
        agent._run.s0 = rid  # (as if the plan had started in a situation)
    for x in PASS_BY_R:
        agent.step(x, 0.0, False)
        recs = agent.pop_records()
        if recs:
            break
    if ticks is None:
        assert recs == [] and agent._run.ticks == len(PASS_BY_R)
        return
    rec = recs[0]
    assert rec.ticks == ticks and rec.success is False and rec.next_situation == 0
    h = agent.learner.hist
    assert np.array_equal(h.x_next[(h.head - 1) % h.capacity], [0.0, 5.0])


def test_miss_stop_leaves_a_behaviour_that_starts_off_away_from_its_target():
    agent, rid = trained_agent(miss_stop="all")
    agent.step(np.array([0.0, 5.0]), 0.0, False)
    assert agent._run.target == rid
    for y in (6.0, 7.0, 8.0, 9.0):  # never nearer R's centre: not a pass, not stopped
        agent.step(np.array([0.0, y]), 0.0, False)
    assert agent.pop_records() == [] and agent._run.approached is False
    agent.step(np.array([0.0, 8.0]), 0.0, False)  # comes nearer now: remembered
    assert agent._run.approached is True
    saved = agent._run.to_dict()
    assert saved["approached"] is True
    assert type(agent._run).from_dict(saved).approached is True


def test_max_behaviour_ticks():
    agent = StnsAgent(StnsConfig(max_behaviour_ticks=3, random_stop="reward"), 2, 4)
    agent.step(FAR, 0.0, False)
    for _ in range(3):
        agent.step(FAR, 0.0, False)
    assert [r.ticks for r in agent.pop_records()] == [3]


@pytest.mark.parametrize("obs,err,match", [
    (np.zeros(3), StnsDimensionError, r"shape \(3,\) does not match obs_dim 2"),
    (np.zeros((1, 2)), StnsDimensionError, "does not match obs_dim 2"),
    ([1.0, float("nan")], StnsInputError, "non-finite values: \\[1.0, nan\\]"),
    ([1.0, float("inf")], StnsInputError, "non-finite"),
    (["a", "b"], StnsInputError, "not numeric"),
])
def test_bad_observations_raise_named_errors(obs, err, match):
    agent = StnsAgent(StnsConfig(), 2, 4)
    with pytest.raises(err, match=match):
        agent.step(obs, 0.0, False)
    with pytest.raises(StnsError):
        agent.classify(obs)


@pytest.mark.parametrize("reward,match", [
    (float("nan"), "reward must be finite, got nan"),
    (float("-inf"), "reward must be finite"),
    ("x", "reward must be a number, got 'x'"),
    (True, "reward must be a number"),
])
def test_bad_rewards_raise_named_errors(reward, match):
    agent = StnsAgent(StnsConfig(), 2, 4)
    with pytest.raises(StnsInputError, match=match):
        agent.step(np.zeros(2), reward, False)


def test_bad_constructor_arguments():
    with pytest.raises(StnsInputError, match="config must be a StnsConfig"):
        StnsAgent({"gamma": 0.7}, 2, 4)
    with pytest.raises(StnsInputError, match="obs_dim must be >= 1, got 0"):
        StnsAgent(StnsConfig(), 0, 4)
    with pytest.raises(StnsInputError, match="n_behaviours must be an int"):
        StnsAgent(StnsConfig(), 2, 4.0)


@pytest.mark.parametrize("margin_plan,reach,planned", [
    ("margin", 2.0, False), ("nearest_r", 2.0, True), ("nearest_r", 1.2, False)])
def test_margin_plan_reading(margin_plan, reach, planned):
    """Just outside R (1.5 boundaries from its centre): the margin has no records, so the
    paper's planner explores; nearest_r plans from R (drive to the goal) when within reach."""
    agent, rid = agent_with_r_situation(margin_plan=margin_plan, margin_plan_reach=reach)
    sit = agent.learner.by_id[rid]
    x = np.array([1.5 * sit.boundary * float(np.sqrt(sit.cov[0, 0])), 0.0])
    assert agent.classify(x) == 0
    assert float(np.sqrt(sit.mahalanobis2(x)[0])) == pytest.approx(1.5 * sit.boundary)
    b = agent.step(x, 0.0, False)
    assert agent._run.planned is planned and agent._run.s0 == 0
    if planned:
        assert (b, agent._run.target) == (0, -1)  # R's plan: its behaviour, to the goal


def _without_own_plan(agent, rid, monkeypatch):
    """Situation ``rid``'s own plan is empty (utility 0); every other plan is the real one."""
    real_plan = agent.learner.plan
    monkeypatch.setattr(agent.learner, "plan",
                        lambda sid: (0.0, []) if sid == rid else real_plan(sid))


@pytest.mark.parametrize("no_plan,planned", [("explore", False), ("margin_plan", True)])
def test_no_plan_reading(no_plan, planned, monkeypatch):
    """Inside a situation whose own plan has no positive utility the paper explores;
    no_plan="margin_plan" follows the margin's plan there ([(2, R), (0, goal)] here)."""
    agent, rid = trained_agent(no_plan=no_plan)
    _without_own_plan(agent, rid, monkeypatch)
    inside = np.array([0.5, 0.0])
    assert agent.classify(inside) == rid
    b = agent.step(inside, 0.0, False)
    assert agent._run.planned is planned and agent._run.s0 == rid
    if planned:
        assert (b, agent._run.target) == (2, rid)
        assert agent._plan == [(0, -1)]  # the rest of the margin's plan


def test_no_plan_margin_plan_explores_when_the_margin_has_no_plan_either(monkeypatch):
    agent, rid = agent_with_r_situation(no_plan="margin_plan")  # no margin records yet
    assert agent.learner.plan(0)[0] <= 0.0
    _without_own_plan(agent, rid, monkeypatch)
    agent.step(np.array([0.5, 0.0]), 0.0, False)
    assert agent._run.planned is False and agent._run.s0 == rid


def test_margin_plan_stops_using_an_r_plan_that_misses_from_the_margin(tmp_path):
    """nearest_r keeps the outcomes of its margin uses: once more than half of the last
    margin_plan_window missed the goal, the margin plans for itself again (and a saved
    learner remembers it)."""
    agent, rid = agent_with_r_situation(margin_plan="nearest_r", margin_plan_reach=2.0,
                                        margin_plan_window=2)
    sit = agent.learner.by_id[rid]
    x = np.array([1.5 * sit.boundary * float(np.sqrt(sit.cov[0, 0])), 0.0])
    for k in range(2):  # two uses from the margin, both end in a collision
        agent.step(x, 0.0, False)
        assert agent._run.planned and agent._run.root == rid, k
        agent.step(x + [0.1, 0.0], -1.0, False)  # the penalty ends it; the next one begins
        assert agent.pop_records()[0].success is False
        agent.reset_trial()
    assert agent._margin_uses == {rid: [False, False]}
    agent.save(tmp_path / "a.npz")
    for a in (agent, StnsAgent.load(tmp_path / "a.npz")):
        a.step(x, 0.0, False)
        assert a._run.planned is False and a._run.root == 0  # margin: nothing planned yet
    unguarded, rid = agent_with_r_situation(margin_plan="nearest_r", margin_plan_window=0)
    unguarded._margin_uses = {rid: [False, False]}
    unguarded.step(x, 0.0, False)
    assert unguarded._run.root == rid  # window 0: no guard


def test_margin_plan_bitten_reach_follows_the_nearest_miss_or_success():
    """nearest_r_bitten carries the bite beyond the R-ellipsoid: from the margin, R's plan is
    taken unless a margin record of R's behaviour that missed the goal lies nearer the input
    than every R instance; a success from the margin nearer still brings it back."""
    agent, rid = agent_with_r_situation(margin_plan="nearest_r_bitten", margin_plan_reach=3.0)
    lr = agent.learner
    sit = lr.by_id[rid]
    sx = float(np.sqrt(sit.cov[0, 0]))
    x = np.array([2.0 * sit.boundary * sx, 0.0])
    assert lr.classify(x) == 0 and lr.nearest(x, 3.0, "R") == rid
    assert lr.reach_accepts(rid, x)  # nothing missed out here yet
    assert agent._plan_root(x, 0) == rid
    miss = x + [0.05 * sx, 0.0]
    lr.add_record(miss, 0, 0, -1.0, miss, 0, False)  # R's behaviour from beside R: a collision
    assert not lr.reach_accepts(rid, x)
    assert agent._plan_root(x, 0) == 0
    lr.add_record(miss, 0, 1, -1.0, miss, 0, False)  # another behaviour's miss does not bite
    far_side = np.array([-2.0 * sit.boundary * sx, 0.0])
    assert lr.classify(far_side) == 0 and agent._plan_root(far_side, 0) == rid
    hit = x - [0.01 * sx, 0.0]
    lr.add_record(hit, 0, 0, 10.0, hit, 0, True)  # a drive from here reached the goal
    assert lr.reach_accepts(rid, x)
    plain, rid2 = agent_with_r_situation(margin_plan="nearest_r", margin_plan_reach=3.0)
    plain.learner.add_record(miss, 0, 0, -1.0, miss, 0, False)
    assert plain._plan_root(x, 0) == rid2  # the unbitten reading ignores the miss


def test_explore_untried_tries_every_behaviour_k_times_in_each_situation(tmp_path):
    """explore_untried K: inside a situation the least-started behaviour is taken, unplanned,
    until every behaviour has started K times there (the plan then rules again); off (0), the
    R-situation's plan is taken every time; a saved learner keeps its counts."""
    x = R_PTS[0] * 0.1  # inside the R-situation
    off, rid = agent_with_r_situation()
    assert off.classify(x) == rid
    for _ in range(6):
        assert off.step(x, 0.0, False) == 0 and off._run.planned
        off.reset_trial()
    agent, rid = agent_with_r_situation(explore_untried=2)
    started = []
    for _ in range(8):
        b = agent.step(x, 0.0, False)
        assert agent._run.planned is False and agent._run.target is None
        started.append(b)
        agent.reset_trial()
    assert sorted(started) == [0, 0, 1, 1, 2, 2, 3, 3]
    assert sorted(started[:4]) == [0, 1, 2, 3]  # the least-started first
    assert agent._tries == {rid: [2, 2, 2, 2]}
    agent.save(tmp_path / "a.npz")
    for a in (agent, StnsAgent.load(tmp_path / "a.npz")):
        assert a.step(x, 0.0, False) == 0 and a._run.planned  # K reached: R's plan
        assert a._tries[rid] == [3, 2, 2, 2]
    assert agent.step(FAR, 0.0, False) is not None  # the margin: not counted
    assert set(agent._tries) == {rid}


def test_explore_untried_forgets_eliminated_situations_and_checks_saved_counts(tmp_path):
    agent, rid = agent_with_r_situation(explore_untried=1)
    agent._tries = {rid + 7: [1, 1, 1, 1]}  # a situation since eliminated
    agent.step(R_PTS[0] * 0.1, 0.0, False)
    assert set(agent._tries) == {rid}
    agent.reset_trial()
    agent._tries[rid] = [1, 1]  # a wrong length, as a corrupt file would give
    agent.save(tmp_path / "bad.npz")
    with pytest.raises(StnsError, match="n_behaviours"):
        StnsAgent.load(tmp_path / "bad.npz")
    with pytest.raises(StnsError, match="explore_untried must be >= 0, got -1"):
        StnsConfig(explore_untried=-1)


@pytest.mark.parametrize("stop,ends_on_leaving", [("random_stop", True), ("reward", False)])
def test_explore_untried_stop_reading(stop, ends_on_leaving):
    """A try stops as the random behaviour does (here: on leaving its situation), or with
    explore_untried_stop="reward" only on a reward: it runs on through the margin."""
    agent, rid = agent_with_r_situation(explore_untried=1, explore_untried_stop=stop)
    agent.step(R_PTS[0] * 0.1, 0.0, False)
    assert agent._run.trying and not agent._run.planned
    b = agent.step(FAR, 0.0, False)  # now in the margin
    recs = agent.pop_records()
    assert (len(recs) == 1) is ends_on_leaving
    if ends_on_leaving:
        assert recs[0].situation == rid and recs[0].next_situation == 0
        assert agent._run.trying is False  # the margin is not counted
    else:
        assert agent._run.trying and agent._run.ticks == 1 and b == agent._run.b
        agent.step(FAR, -1.0, False)  # a collision ends it
        assert [r.reward for r in agent.pop_records()] == [-1.0]
    with pytest.raises(StnsError, match="explore_untried_stop must be one of"):
        StnsConfig(explore_untried_stop="never")


def agent_with_pending_drive(**overrides):
    """Behaviour 0 has an R-situation; behaviour 1 reached the goal once at GOAL_AT, missed
    with a penalty at MISS_AT and was cut short without a reward right beside GOAL_AT."""
    agent, rid = agent_with_r_situation(**overrides)
    lr = agent.learner
    for p, reward, terminal in ((GOAL_AT, 10.0, True), (MISS_AT, -1.0, False),
                                (GOAL_AT + 0.5, 0.0, False)):
        lr.add_record(p, lr.classify(p), 1, reward, p, lr.classify(p), terminal)
    assert [s.behaviour for s in lr.order] == [0]
    return agent, rid


GOAL_AT = np.array([12.0, 12.0])
MISS_AT = np.array([-12.0, -12.0])


def test_pending_r_try_drives_where_the_nearest_outcome_was_a_goal(tmp_path):
    """pending_r_try="nearest_success": a behaviour with a goal arrival but no R-situation is
    taken, unplanned, where its nearest outcome (a step ended on a reward) was the arrival,
    not where it was a penalty; a step cut short without a reward is not an outcome. Off, it
    is never taken there."""
    near_goal, near_miss = GOAL_AT + 1.0, MISS_AT + 1.0
    off, _ = agent_with_pending_drive(seed=3)
    for _ in range(12):
        off.step(near_goal, 0.0, False)
        assert off._run.pending is False
        off.reset_trial()
    agent, _ = agent_with_pending_drive(pending_r_try="nearest_success")
    assert agent.learner.pending_r_behaviours(near_goal) == [1]
    assert agent.learner.pending_r_behaviours(near_miss) == []
    assert agent.step(near_goal, 0.0, False) == 1
    assert agent._run.pending and not agent._run.planned and agent._run.target is None
    agent.save(tmp_path / "a.npz")
    assert StnsAgent.load(tmp_path / "a.npz")._run.pending  # a running try is saved as such
    agent.reset_trial()
    agent.step(near_miss, 0.0, False)
    assert agent._run.pending is False
    with pytest.raises(StnsError, match="pending_r_try must be one of"):
        StnsConfig(pending_r_try="yes")


def test_pending_r_try_stops_only_on_a_reward_and_ends_with_the_r_situation():
    """A try runs on through other situations until a reward ends it; once the behaviour has
    its own R-situation it is no longer pending anywhere."""
    agent, rid = agent_with_pending_drive(pending_r_try="nearest_success")
    x_r = R_PTS[0] * 0.1
    agent.step(GOAL_AT + 1.0, 0.0, False)
    assert agent.step(x_r, 0.0, False) == 1 and agent._run.ticks == 1  # on through rid
    assert agent.pop_records() == []
    agent.step(x_r, -1.0, False)  # a penalty ends it
    assert [(r.behaviour, r.reward, r.planned) for r in agent.pop_records()] == [(1, -1.0, False)]
    lr = agent.learner
    for k in range(3):  # three more arrivals: N_init^R + 1 = 4, so its R-situation is extracted
        p = GOAL_AT + 0.2 * k
        lr.add_record(p, lr.classify(p), 1, 10.0, p, lr.classify(p), True)
    assert sorted(s.behaviour for s in lr.order if s.kind == "R") == [0, 1]
    assert lr.pending_r_behaviours(GOAL_AT + 1.0) == []


@pytest.mark.parametrize("mode,tried", [("nearest_success", True),
                                        ("planned_nearest_success", False)])
def test_pending_r_try_planned_reading_leaves_exploration_as_it_was(mode, tried):
    """Where no plan has positive utility (one arrival of behaviour 1 among 20 penalties
    from the margin), "nearest_success" still tries the pending behaviour beside its goal
    arrival; "planned_nearest_success" tries it only instead of a plan, so the step is the
    random behaviour of §6.2."""
    agent = StnsAgent(StnsConfig(n_init_r=3, n_min_r=3, history_size=300,
                                 pending_r_try=mode), obs_dim=2, n_behaviours=4)
    lr = agent.learner
    lr.add_record(GOAL_AT, 0, 1, 10.0, GOAL_AT, 0, True)
    for k in range(20):
        p = MISS_AT + [0.0, k]
        lr.add_record(p, 0, 1, -1.0, p, 0, False)
    assert lr.plan(0) == (0.0, [])
    assert lr.pending_r_behaviours(GOAL_AT + 1.0) == [1]
    agent.step(GOAL_AT + 1.0, 0.0, False)
    assert agent._run.pending is tried and not agent._run.planned


TURN_AT = np.array([10.0, -10.0])


def agent_with_pending_turn(**overrides):
    """An R-situation of behaviour 0; from the margin, turn 2 reached it twice at TURN_AT and
    missed with a penalty at MISS_AT; turn 3 reached it three times far off and missed beside
    TURN_AT. No T-situation: each pair has fewer than N_init^T + 1 = 6 records."""
    agent, rid = agent_with_r_situation(**overrides)
    lr = agent.learner
    recs = [(TURN_AT, 2, 0.0, rid), (TURN_AT + [0.0, 1.0], 2, 0.0, rid), (MISS_AT, 2, -1.0, 0),
            (TURN_AT + [1.0, 0.0], 3, -1.0, 0)]
    recs += [(np.array([0.0, 20.0 + k]), 3, 0.0, rid) for k in range(3)]
    for p, b, reward, s_next in recs:
        lr.add_record(p, 0, b, reward, R_PTS[0], s_next, False)
    assert [s.kind for s in lr.order] == ["R"]
    return agent, rid


def test_pending_t_try_turns_where_the_nearest_margin_outcome_reached_the_r_situation():
    """pending_t_try="planned_nearest_success": from the margin, instead of the margin's plan
    (turn 3, the likelier one), the turn whose nearest margin outcome reached the R-situation
    is taken as a planned step aimed at it; not where that outcome was a miss, not the R's
    own behaviour, and never with the option off."""
    near_turn = TURN_AT + [0.5, 0.0]
    off, rid = agent_with_pending_turn()
    assert off.learner.plan(0)[1][0] == (3, rid)
    assert off.step(near_turn, 0.0, False) == 3
    agent, rid = agent_with_pending_turn(pending_t_try="planned_nearest_success")
    assert agent.learner.pending_t_pairs(near_turn) == [(2, rid)]
    assert (2, rid) not in agent.learner.pending_t_pairs(MISS_AT + 0.5)
    assert agent.step(near_turn, 0.0, False) == 2
    assert agent._run.planned and agent._run.target == rid and agent._plan == []
    agent.step(R_PTS[1], 0.0, False)  # in the R-situation: the step met its target
    rec = agent.pop_records()[0]
    assert (rec.behaviour, rec.target, rec.planned, rec.success) == (2, rid, True, True)
    with pytest.raises(StnsError, match="pending_t_try must be one of"):
        StnsConfig(pending_t_try="yes")


def test_pending_t_try_ends_with_the_t_situation():
    """Once the pair has its T-situation (N_init^T + 1 records of turn 2 from the margin into
    the R-situation), it is no longer pending where it was."""
    agent, rid = agent_with_pending_turn(pending_t_try="planned_nearest_success")
    lr = agent.learner
    for k in range(4):
        lr.add_record(TURN_AT + [0.0, 2.0 + k], 0, 2, 0.0, R_PTS[0], rid, False)
    assert [(s.kind, s.behaviour, s.parent) for s in lr.order if s.kind == "T"] == [("T", 2, rid)]
    assert (2, rid) not in lr.pending_t_pairs(TURN_AT + [0.5, 0.0])
