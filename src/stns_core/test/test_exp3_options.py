"""The paper section 7.3 remedies (options off by default): each test fails if its option
does nothing, and the defaults are the plain learner."""

import numpy as np
import pytest
from conftest import make_learner
from stns_core.agent import BACKWARD, CLOCKWISE, COUNTER_CLOCKWISE, FORWARD, greedy_behaviour
from stns_core.situation import R_KIND, T_KIND, Situation

from stns_core import StnsAgent, StnsConfig, StnsConfigError, StnsInputError


def _polar(bearing_deg, dist=50.0):
    a = np.radians(bearing_deg)
    return np.array([dist * np.cos(a), dist * np.sin(a)])


def test_defaults_switch_the_options_off():
    cfg = StnsConfig()
    assert cfg.exploration == "uniform"
    assert cfg.elimination_grace_steps == 0
    assert cfg.shape_trim == 1.0
    assert cfg.range_clip == 0.0 and cfg.explore_max_ticks == 0
    assert cfg.boundary_quantile == 1.0 and cfg.shape_scope == "all"
    assert cfg.negatives_from_history is False


@pytest.mark.parametrize("key,value,match", [
    ("exploration", "greedy", "exploration must be one of"),
    ("greedy_prob", 1.5, "greedy_prob must be in"),
    ("greedy_align_deg", 0.0, "greedy_align_deg must be in"),
    ("elimination_grace_steps", -1, "elimination_grace_steps must be >= 0"),
    ("shape_trim", 0.0, "shape_trim must be in"),
    ("shape_trim", 1.2, "shape_trim must be in"),
    ("range_clip", -1.0, "range_clip must be >= 0"),
    ("explore_max_ticks", -2, "explore_max_ticks must be >= 0"),
    ("boundary_quantile", 0.0, "boundary_quantile must be in"),
    ("shape_scope", "r_only", "shape_scope must be one of"),
])
def test_bad_option_values_raise(key, value, match):
    with pytest.raises(StnsConfigError, match=match):
        StnsConfig(**{key: value})


@pytest.mark.parametrize("bearing,expected", [
    (0.0, FORWARD), (10.0, FORWARD), (-14.0, FORWARD),
    (180.0, BACKWARD), (-170.0, BACKWARD),
    (45.0, COUNTER_CLOCKWISE), (-45.0, CLOCKWISE),   # bring the goal ahead
    (120.0, CLOCKWISE), (-120.0, COUNTER_CLOCKWISE),  # bring it behind
])
def test_greedy_behaviour_heads_for_the_goal(bearing, expected):
    assert greedy_behaviour(_polar(bearing), 15.0) == expected


def test_greedy_exploration_changes_the_choice_and_stops_when_aligned():
    obs = np.concatenate([_polar(60.0), np.full(6, 30.0)])
    cfg = StnsConfig.preset("exp3", exploration="greedy_goal", greedy_prob=1.0)
    agent = StnsAgent(cfg, obs_dim=8, n_behaviours=4)
    assert agent.step(obs, 0.0, False) == COUNTER_CLOCKWISE  # no situation: exploration
    # turning: goes on while the goal is off the line, stops once it is within 15 degrees
    assert agent.step(np.concatenate([_polar(30.0), obs[2:]]), 0.0, False) == COUNTER_CLOCKWISE
    agent.step(np.concatenate([_polar(5.0), obs[2:]]), 0.0, False)
    (rec,) = agent.pop_records()
    assert rec.behaviour == COUNTER_CLOCKWISE and not rec.planned and rec.ticks == 2
    # uniform exploration from the same seed picks other behaviours for the same input
    uni = StnsAgent(StnsConfig.preset("exp3"), obs_dim=8, n_behaviours=4)
    greedy = StnsAgent(cfg, obs_dim=8, n_behaviours=4)
    picks_u, picks_g = set(), set()
    for _ in range(20):
        picks_u.add(uni.step(obs, 0.0, False))
        uni.reset_trial()
        picks_g.add(greedy.step(obs, 0.0, False))
        greedy.reset_trial()
    assert picks_g == {COUNTER_CLOCKWISE} and len(picks_u) > 1


def test_greedy_prob_mixes_with_uniform_and_uses_the_agents_generator():
    obs = np.concatenate([_polar(0.0), np.full(6, 30.0)])
    cfg = StnsConfig.preset("exp3", exploration="greedy_goal", greedy_prob=0.5, seed=4)

    def picks():
        agent = StnsAgent(cfg, obs_dim=8, n_behaviours=4)
        out = []
        for _ in range(200):
            out.append(agent.step(obs, 0.0, False))
            agent.reset_trial()
        return out

    a, b = picks(), picks()
    assert a == b  # seeded
    share = a.count(FORWARD) / len(a)
    assert 0.5 < share < 0.8  # 0.5 greedy + 0.5 x 1/4 uniform = 0.625


def test_greedy_needs_the_goal_sensor_and_four_behaviours():
    cfg = StnsConfig(exploration="greedy_goal")
    with pytest.raises(StnsInputError, match="greedy_goal"):
        StnsAgent(cfg, obs_dim=2, n_behaviours=3)


def test_greedy_agent_saves_and_loads_mid_step(tmp_path):
    obs = np.concatenate([_polar(60.0), np.full(6, 30.0)])
    cfg = StnsConfig.preset("exp3", exploration="greedy_goal", greedy_prob=1.0)
    agent = StnsAgent(cfg, obs_dim=8, n_behaviours=4)
    agent.step(obs, 0.0, False)
    agent.save(tmp_path / "a.npz")
    back = StnsAgent.load(tmp_path / "a.npz")
    assert back._run.greedy
    nxt = np.concatenate([_polar(5.0), obs[2:]])
    back.step(nxt, 0.0, False)
    assert back.pop_records()[-1].ticks == 1  # stopped as a greedy turn


def _negative_young_situation(grace):
    lrn = make_learner(elimination_grace_steps=grace)
    for _ in range(5):
        lrn.add_record(np.zeros(2), 0, 0, 0.0, np.zeros(2), 0, False)
    sit = Situation(lrn.next_id, T_KIND, 0, lrn.hist.capacity, 2, parent=0,
                    created=lrn.hist.total)
    lrn.next_id += 1
    lrn.order.append(sit)
    lrn.by_id[sit.id] = sit
    lrn.compute_utilities = lambda: {s.id: -1.0 for s in lrn.order}
    lrn._structure_changed = lambda: None
    return lrn, sit


def test_elimination_grace_protects_young_situations_from_operation_5():
    lrn, sit = _negative_young_situation(0)
    lrn._periodic()
    assert sit.id not in lrn.by_id  # the paper's operation 5
    lrn, sit = _negative_young_situation(50)
    lrn._periodic()
    assert sit.id in lrn.by_id  # younger than the grace period: kept
    for _ in range(50):
        lrn.hist.append(np.zeros(2), 0, 0, 0.0, np.zeros(2), 0, False)
    lrn._periodic()
    assert sit.id not in lrn.by_id  # grace over: operation 5 again


def test_shape_trim_fits_the_core_of_the_positives():
    rng = np.random.default_rng(0)
    core = rng.normal(size=(40, 3))
    outliers = rng.normal(size=(4, 3)) * 2.0 + np.array([12.0, -9.0, 6.0])
    pts = np.vstack([core, outliers])
    full = Situation(1, R_KIND, 0, len(pts), 3, reward_key=10.0)
    full.pos[:] = True
    full.fit(pts, 1e-3)
    same = Situation(1, R_KIND, 0, len(pts), 3, reward_key=10.0)
    same.pos[:] = True
    same.fit(pts, 1e-3, 1.0)
    assert np.array_equal(full.mean, same.mean) and full.boundary == same.boundary
    trimmed = Situation(1, R_KIND, 0, len(pts), 3, reward_key=10.0)
    trimmed.pos[:] = True
    trimmed.fit(pts, 1e-3, 0.9)
    assert np.linalg.det(trimmed.cov) < 0.05 * np.linalg.det(full.cov)
    assert np.linalg.norm(trimmed.mean) < 0.5
    assert not trimmed.accepts(outliers[0], pts) and full.accepts(outliers[0], pts)
    assert all(trimmed.accepts(p, pts) for p in core[np.linalg.norm(core, axis=1) < 1.5])


def test_range_clip_preprocesses_the_range_dims_only():
    obs = np.array([80.0, -70.0, 10.0, 45.0, 120.0, 30.0, 31.0, 90.0])
    plain = StnsAgent(StnsConfig.preset("exp3"), obs_dim=8, n_behaviours=4)
    clip = StnsAgent(StnsConfig.preset("exp3", range_clip=40.0), obs_dim=8, n_behaviours=4)
    for agent in (plain, clip):
        agent.step(obs, 0.0, False)
        agent.step(obs, -1.0, False)
    (rp,), (rc,) = plain.pop_records(), clip.pop_records()
    assert np.array_equal(rp.x, obs)
    assert np.array_equal(rc.x, [80.0, -70.0, 10.0, 40.0, 40.0, 30.0, 31.0, 40.0])


def test_explore_max_ticks_cuts_exploration_steps_only():
    obs = np.concatenate([_polar(60.0), np.full(6, 30.0)])
    out = {}
    for limit in (0, 3):
        agent = StnsAgent(StnsConfig.preset("exp3", explore_max_ticks=limit), 8, 4)
        agent.step(obs, 0.0, False)
        for _ in range(5):
            agent.step(obs, 0.0, False)
        out[limit] = [r.ticks for r in agent.pop_records()]
    assert out[0] == []  # the random step goes on: no reward, no change of situation
    assert out[3] == [3]


def test_boundary_quantile_tightens_the_boundary():
    rng = np.random.default_rng(1)
    pts = rng.normal(size=(100, 8))
    sits = {}
    for q in (1.0, 0.8):
        sit = Situation(1, T_KIND, 0, len(pts), 8, parent=2)
        sit.pos[:] = True
        sit.fit(pts, 1e-3, 1.0, q)
        sits[q] = sit
    d = np.sqrt(sits[1.0].mahalanobis2(pts))
    assert sits[1.0].boundary == pytest.approx(d.max())
    assert sits[0.8].boundary == pytest.approx(np.sqrt(np.quantile(d * d, 0.8)))
    assert np.mean(d <= sits[0.8].boundary + 1e-9) == pytest.approx(0.8, abs=0.011)


def test_shape_scope_t_only_leaves_r_situations_alone():
    rng = np.random.default_rng(2)
    pts = rng.normal(size=(60, 2)) * np.array([3.0, 1.0])
    boundaries = {}
    for scope in ("all", "t_only"):
        lrn = make_learner(boundary_quantile=0.5, shape_scope=scope, history_size=100)
        for p in pts:
            lrn.hist.append(p, 0, 0, 10.0, p, 0, True)
        r = Situation(1, R_KIND, 0, lrn.hist.capacity, 2, reward_key=10.0)
        t = Situation(2, T_KIND, 0, lrn.hist.capacity, 2, parent=1)
        for sit in (r, t):
            sit.pos[:60] = True
            lrn._fit(sit)
        boundaries[scope] = (r.boundary, t.boundary)
    full = Situation(3, R_KIND, 0, 60, 2, reward_key=10.0)
    full.pos[:] = True
    full.fit(pts, 1e-3)
    assert boundaries["all"][0] < full.boundary and boundaries["all"][1] < full.boundary
    assert boundaries["t_only"][0] == full.boundary
    assert boundaries["t_only"][1] == boundaries["all"][1]


def _learner_with_a_t_situation(negatives_from_history):
    from conftest import ring
    lrn = make_learner(negatives_from_history=negatives_from_history)
    goal_side = ring((-20.0, 0.0), radius=2.0, n=4)
    for p in goal_side:  # R-situation (behaviour 0, reward 10) after the 4th
        lrn.add_record(p, 0, 0, 10.0, p, 0, True)
    (r_sit,) = lrn.order
    inner = ring((20.0, 20.0), radius=0.7, n=6)  # behaviour 1 failed here ...
    for p in inner:
        lrn.add_record(p, 0, 1, -1.0, p + 1.0, 0, False)
    outer = ring((20.0, 20.0), radius=3.0, n=8)  # ... and reached the R-situation from here
    for p in outer:
        lrn.add_record(p, lrn.classify(p), 1, 0.0, goal_side[0], r_sit.id, False)
    t_sits = [s for s in lrn.order if s.kind == T_KIND]
    assert len(t_sits) == 1
    return lrn, t_sits[0], inner


def test_negatives_from_history_bite_a_new_situation_at_once():
    lrn, sit, inner = _learner_with_a_t_situation(False)
    assert sit.n_neg == 0
    assert lrn.classify(np.array([20.0, 20.0])) == sit.id  # the ellipsoid swallows the hole
    lrn, sit, inner = _learner_with_a_t_situation(True)
    assert sit.n_neg == len(inner)
    assert lrn.classify(np.array([20.0, 20.0])) == 0  # bitten out where behaviour 1 failed
    assert lrn.classify(np.array([22.9, 20.0])) == sit.id
    assert any(e["event"] == "negatives_seeded" for e in lrn.events)


@pytest.mark.parametrize("name,preset,overrides", [
    ("stns_exp3_improved.yaml", "exp3",
     dict(exploration="greedy_goal", greedy_prob=1.0, greedy_align_deg=5.0)),
    ("stns_exp1_improved.yaml", "exp1",
     dict(target_stop="deepest", target_lookahead_ticks=1, plan_stop="higher_utility",
          t_result="unpunished", margin_plan="nearest_r_bitten", margin_plan_reach=2.5,
          margin_plan_window=0, miss_stop="all", pending_r_try="planned_nearest_success",
          pending_t_try="planned_nearest_success")),
])
def test_improved_yaml_files_are_the_preset_plus_their_options(name, preset, overrides):
    from pathlib import Path

    yaml = pytest.importorskip("yaml")
    path = Path(__file__).resolve().parents[3] / "config" / name
    if not path.exists():
        pytest.skip(f"{path} not in this checkout")
    params = yaml.safe_load(path.read_text())["/**"]["ros__parameters"]
    assert StnsConfig.from_dict(params) == StnsConfig.preset(preset, **overrides)
