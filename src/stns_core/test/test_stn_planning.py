"""STN estimates (6.1), IPRL (6.2) with p_min / n_max / memo, PIA agreement."""

import math

import numpy as np
import pytest
from conftest import make_learner
from stns_core.planning import Iprl, Pia, iprl_plan
from stns_core.stn import Stn


def test_stn_maximum_likelihood_on_a_known_sequence():
    # nodes: 0 margin, 1, 2, goal 3; two behaviours
    s = np.array([0, 0, 0, 0, 1, 1, 1, 2])
    b = np.array([0, 0, 0, 1, 0, 0, 1, 1])
    sn = np.array([1, 1, 2, 0, 3, 1, 3, 1])
    r = np.array([0.0, 0.0, -1.0, -1.0, 10.0, 0.0, 10.0, 0.0])
    stn = Stn.from_records(s, b, sn, r, 4, 2)
    assert stn.p[0, 0].tolist() == pytest.approx([0, 2 / 3, 1 / 3, 0])
    assert stn.r[0, 0, 2] == -1.0 and stn.p[0, 1, 0] == 1.0
    assert stn.p[1, 0].tolist() == pytest.approx([0, 0.5, 0, 0.5])
    assert stn.r[1, 0, 3] == 10.0
    assert not stn.tried[2, 0] and stn.tried[2, 1]
    assert stn.successors[2][0] is None


def test_weighted_counts_are_a_weighted_maximum_likelihood():
    s = np.array([0, 0, 0])
    b = np.array([0, 0, 0])
    sn = np.array([2, 1, 1])  # goal (node 2) once, node 1 twice
    r = np.array([10.0, 0.0, -1.0])
    stn = Stn.from_records(s, b, sn, r, 3, 1, weights=np.array([4.0, 1.0, 3.0]))
    assert stn.p[0, 0].tolist() == pytest.approx([0, 0.5, 0.5])
    assert stn.r[0, 0, 1] == pytest.approx(-3.0 / 4.0)  # weighted mean reward
    assert stn.r[0, 0, 2] == 10.0


@pytest.mark.parametrize("half_life", [0.0, 2.0])
def test_stn_half_life_lets_new_outcomes_outweigh_old_ones_in_the_plan(half_life):
    lr = make_learner(relabel="never", stn_half_life=half_life)
    h = lr.hist
    for reached in (True, False, False, True):  # behaviour 1 from the margin, long ago
        h.append(np.zeros(2), 0, 1, 10.0 if reached else -1.0, np.zeros(2), 0, reached)
    for _ in range(6):  # behaviour 0 reached the goal six times
        h.append(np.zeros(2), 0, 0, 10.0, np.zeros(2), 0, True)
    for _ in range(4):  # then missed four times in a row
        h.append(np.zeros(2), 0, 0, -1.0, np.zeros(2), 0, False)
    lr._version += 1
    plain, weighted = lr.stn(), lr.plan_stn()
    assert plain.p[0, 0, 1] == pytest.approx(0.6) and plain.p[0, 1, 1] == pytest.approx(0.5)
    age = np.arange(13, -1, -1)  # the newest record has age 0
    w = np.exp2(-age / half_life) if half_life else np.ones(14)
    assert weighted.p[0, 0, 1] == pytest.approx(w[4:10].sum() / w[4:].sum())
    assert weighted.p[0, 1, 1] == pytest.approx((w[0] + w[3]) / w[:4].sum())
    assert weighted.tried.tolist() == plain.tried.tolist()
    if half_life:
        assert weighted.p[0, 0, 1] < 0.25  # the four new misses outweigh six older arrivals
        assert abs(weighted.p[0, 1, 1] - 0.5) < 0.05  # outcomes of about one age: the
        # weights nearly cancel, the estimate stays near the plain 0.5
        assert lr.plan(0)[1][0][0] == 1  # so the plan now takes behaviour 1
    else:
        assert weighted is plain and lr.plan(0)[1][0][0] == 0  # the paper's choice


def test_stn_half_life_ages_count_from_the_newest_record_after_the_ring_wraps():
    lr = make_learner(relabel="never", history_size=6, stn_half_life=1.0)
    h = lr.hist
    for reached in (1, 1, 1, 0, 0, 1, 0, 1, 1):  # the last six stay, oldest first: 0 0 1 0 1 1
        h.append(np.zeros(2), 0, 0, 10.0 if reached else -1.0, np.zeros(2), 0, bool(reached))
    lr._version += 1
    assert h.head == 3  # the ring has wrapped: slot 2 holds the newest record
    w = np.exp2(-np.arange(5.0, -1.0, -1.0))  # ages 5 .. 0 in the order the six were made
    goal = np.array([0, 0, 1, 0, 1, 1], dtype=bool)
    assert lr.plan_stn().p[0, 0, 1] == pytest.approx(w[goal].sum() / w.sum())
    assert lr.stn().p[0, 0, 1] == pytest.approx(0.5)


def test_learner_stn_uses_goal_node_and_current_labels():
    lr = make_learner(relabel="never")
    h = lr.hist
    for _ in range(3):
        h.append(np.zeros(2), 0, 0, 10.0, np.zeros(2), 0, True)
    h.append(np.zeros(2), 0, 1, 0.0, np.zeros(2), 0, False)
    h.append(np.zeros(2), 0, -1, 0.0, np.zeros(2), 0, True)  # arrival: no behaviour
    lr._version += 1
    stn = lr.stn()
    assert stn.n_nodes == 2  # margin + goal
    assert stn.p[0, 0, 1] == 1.0 and stn.r[0, 0, 1] == 10.0
    assert stn.p[0, 1, 0] == 1.0
    assert stn.counts.sum() == 4


def chain_stn():
    """0 margin, 1 R-like, 2 and 3 T-like, 4 a long shot, 5 goal; behaviours 0..2."""
    n, nb = 6, 3
    p = np.zeros((n, nb, n))
    r = np.zeros((n, nb, n))
    p[1, 0, 5], p[1, 0, 0] = 0.9, 0.1
    r[1, 0, 5] = 10.0
    p[2, 1, 1], p[2, 1, 0] = 0.8, 0.2
    p[3, 2, 2] = 1.0
    p[3, 1, 4], p[3, 1, 0] = 0.15, 0.85  # rare jackpot path
    p[4, 0, 5] = 1.0
    r[4, 0, 5] = 100.0
    p[0, 0, 0] = 1.0
    r[0, 0, 0] = -1.0
    return Stn.from_model(p, r)


def test_iprl_returns_the_known_best_plan():
    stn = chain_stn()
    u, plan = iprl_plan(stn, 3, gamma=0.7, p_min=0.2, n_max=7)
    assert plan == ((2, 2), (1, 1), (0, 5))
    assert u == pytest.approx(0.7 * 0.8 * 0.7 * 0.9 * 10.0)


def test_iprl_respects_p_min():
    stn = chain_stn()
    # the jackpot path has success probability 0.15: searched only when p_min < 0.15
    u, plan = iprl_plan(stn, 3, gamma=0.7, p_min=0.1, n_max=7)
    assert plan == ((1, 4), (0, 5))
    assert u == pytest.approx(0.15 * 0.7 * 100.0)
    u, plan = iprl_plan(stn, 3, gamma=0.7, p_min=0.2, n_max=7)
    assert plan[0] == (2, 2)
    # node 1 is reached with path probability 0.8: expanded above p_min = 0.75 ...
    u, plan = iprl_plan(stn, 3, gamma=0.7, p_min=0.75, n_max=7)
    assert plan == ((2, 2), (1, 1), (0, 5)) and u > 0
    # ... a leaf (utility 0) at p_min = 0.85: no plan reaches the goal any more
    u, plan = iprl_plan(stn, 3, gamma=0.7, p_min=0.85, n_max=7)
    assert u == 0.0 and all(d != 5 for _, d in plan)


def test_iprl_respects_n_max():
    stn = chain_stn()
    for n_max in range(1, 5):
        u, plan = iprl_plan(stn, 3, gamma=0.7, p_min=0.2, n_max=n_max)
        assert len(plan) <= n_max
    assert iprl_plan(stn, 3, 0.7, 0.2, 3)[1] == ((2, 2), (1, 1), (0, 5))
    u2, _ = iprl_plan(stn, 3, 0.7, 0.2, 2)
    assert u2 == pytest.approx(0.0)  # the goal lies 3 behaviours away
    assert iprl_plan(stn, 2, 0.7, 0.2, 2)[1] == ((1, 1), (0, 5))


def test_untried_behaviours_count_as_zero_and_no_data_gives_no_plan():
    stn = chain_stn()
    u, plan = iprl_plan(stn, 0, 0.7, 0.1, 7)  # only a -1 self-loop tried, others untried
    assert u == 0.0 and plan == ()


def random_stn(rng, n=8, nb=4, acyclic=False, density=0.5):
    p = np.zeros((n + 1, nb, n + 1))
    r = np.zeros((n + 1, nb, n + 1))
    for i in range(n):
        for b in range(nb):
            if rng.random() > 0.8:
                continue
            js = np.arange(i + 1, n + 1) if acyclic else np.arange(n + 1)
            if len(js) == 0:
                continue
            mask = rng.random(len(js)) < density
            mask[rng.integers(len(js))] = True
            w = rng.random(mask.sum()) ** 4  # skewed: deep, repeated sub-searches
            p[i, b, js[mask]] = w / w.sum()
            r[i, b, js[mask]] = rng.normal(0.0, 1.0, mask.sum())
            r[i, b, n] = 10.0 * rng.random()
    return Stn.from_model(p, r, scale=97.0)


@pytest.mark.parametrize("seed", range(6))
def test_memo_gives_identical_decisions(seed):
    stn = random_stn(np.random.default_rng(seed), n=10)
    saved = 0
    for p_min, n_max in ((0.1, 7), (0.05, 6), (0.2, 7), (0.01, 7)):
        with_memo = Iprl(stn, 0.7, p_min, n_max, memo=True)
        without = Iprl(stn, 0.7, p_min, n_max, memo=False)
        for root in range(stn.n_nodes - 1):
            assert with_memo.plan(root) == without.plan(root)
        assert with_memo.expansions <= without.expansions
        saved += without.expansions - with_memo.expansions
    assert saved > 0


@pytest.mark.parametrize("seed", range(5))
def test_pia_agrees_with_iprl_where_the_search_reaches_everywhere(seed):
    stn = random_stn(np.random.default_rng(100 + seed), n=6, acyclic=True)
    pia = Pia(stn, 0.7, n_max=10)
    iprl = Iprl(stn, 0.7, p_min=0.0, n_max=10)
    for root in range(stn.n_nodes - 1):
        u_i, plan_i = iprl.plan(root)
        u_p, plan_p = pia.plan(root)
        assert u_p == pytest.approx(max(u_i, 0.0) if u_i > 0 else u_p, abs=1e-9)
        assert math.isclose(max(u_p, 0.0), max(u_i, 0.0), abs_tol=1e-9)
        if u_i > 0:
            assert plan_i[0] == plan_p[0]


def test_pia_solves_a_cyclic_stn():
    stn = chain_stn()
    pia = Pia(stn, 0.7, n_max=7)
    assert pia.plan(3)[1] == ((1, 4), (0, 5))  # no p_min: the jackpot path wins
    # fixed point of Eq. 1 for the policy found
    u = pia.u
    q = np.einsum("ibj,ibj->ib", stn.p, stn.r) + 0.7 * np.einsum("ibj,j->ib", stn.p, u)
    q[~stn.tried] = 0.0
    assert np.allclose(u[:-1], q.max(axis=1)[:-1])
