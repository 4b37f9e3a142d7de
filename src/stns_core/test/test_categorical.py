"""Extraction and the five maintenance operations (paper section 5.3)."""

import numpy as np
import pytest
from conftest import make_learner, ring
from stns_core.classifier import MARGIN
from stns_core.history import ARRIVAL

GOAL_PTS = ring((0.0, 0.0), radius=2.0, n=8)[[0, 4, 2, 6, 1, 5, 3, 7]]
FAR_PTS = ring((30.0, 0.0), radius=2.0, n=16)


def add_goal_record(lr, k, b=0, reward=10.0):
    x = GOAL_PTS[k % len(GOAL_PTS)]
    lr.add_record(x, lr.classify(x), b, reward, x, lr.classify(x), True)


def add_move_record(lr, k, b=2, to=(0.5, 0.0)):
    x = FAR_PTS[k % len(FAR_PTS)]
    xn = np.array(to)
    lr.add_record(x, lr.classify(x), b, 0.0, xn, lr.classify(xn), False)


def test_r_extraction_fires_exactly_when_the_count_passes_n_init():
    lr = make_learner(n_init_r=3)
    add_goal_record(lr, 0, b=1)  # another behaviour's rewards do not count for b=0
    for k in range(3):
        add_goal_record(lr, k)
        assert lr.order == []
    add_goal_record(lr, 3)
    assert [s.attributes() for s in lr.order] == [("R", 0, 10.0)]
    sit = lr.order[0]
    assert sit.n_pos == 4 and sit.n_neg == 0  # all records meeting it; no negatives yet
    assert lr.events[-1]["event"] == "extracted"


def test_small_rewards_never_extract():
    lr = make_learner(n_init_r=3)
    for k in range(10):
        add_goal_record(lr, k, reward=5.0)  # not above r_min_r = 5
    assert lr.order == []


def test_t_extraction_fires_exactly_when_the_count_passes_n_init():
    lr = make_learner(n_init_t=5)
    for k in range(4):
        add_goal_record(lr, k)
    r_id = lr.order[0].id
    assert lr.classify(np.array([0.5, 0.0])) == r_id
    for k in range(5):
        add_move_record(lr, k)
        assert len(lr.order) == 1
    add_move_record(lr, 5)
    assert [s.attributes() for s in lr.order] == [("R", 0, 10.0), ("T", 2, r_id)]
    t = lr.order[1]
    assert t.n_pos == 6
    assert lr.classify(FAR_PTS[0]) == t.id  # re-labelled: the region is now the T-situation


def add_punished_move_record(lr, k, b=2, to=(0.5, 0.0)):
    x = FAR_PTS[k % len(FAR_PTS)]
    xn = np.array(to)
    lr.add_record(x, lr.classify(x), b, -1.0, xn, lr.classify(xn), False)


@pytest.mark.parametrize("t_result,extracted", [("reached", True), ("unpunished", False)])
def test_t_result_reading_on_penalised_moves(t_result, extracted):
    """A move that ended with a penalty (a collision; the world may then re-place the rover)
    reaches a situation for the paper's reading, not for t_result="unpunished"."""
    lr = make_learner(n_init_t=5, t_result=t_result)
    for k in range(4):
        add_goal_record(lr, k)
    for k in range(6):
        add_punished_move_record(lr, k)
    assert (len(lr.order) == 2) == extracted
    for k in range(6):
        add_move_record(lr, 6 + k)
    t = lr.order[1]
    assert t.kind == "T" and t.n_pos == (12 if t_result == "reached" else 6)


def test_t_extraction_counts_only_moves_from_situation_zero():
    lr = make_learner(n_init_t=5)
    for k in range(4):
        add_goal_record(lr, k)
    for k in range(12):  # from inside the R-situation itself: not from situation 0
        x = GOAL_PTS[k % 8] * 0.5
        lr.add_record(x, lr.classify(x), 3, 0.0, GOAL_PTS[0], lr.classify(GOAL_PTS[0]), False)
    assert len(lr.order) == 1


def test_operation_1_positives_and_negatives():
    lr = make_learner()
    for k in range(4):
        add_goal_record(lr, k)
    sit = lr.order[0]
    inside = np.array([0.5, 0.5])
    outside = np.array([40.0, 40.0])
    assert lr.classify(inside) == sit.id and lr.classify(outside) == 0
    slots = []

    def add(x, b, reward, terminal):
        slots.append(lr.hist.head)
        lr.add_record(x, lr.classify(x), b, reward, x, lr.classify(x), terminal)

    add(inside, 0, 10.0, True)  # condition behaviour, result met -> positive
    add(inside, 0, -1.0, False)  # classified in it, condition behaviour, not met -> negative
    add(inside, 1, 0.0, False)  # other behaviour -> neither
    add(outside, 0, 10.0, True)  # met, classified elsewhere -> positive all the same
    elsewhere = np.array([-40.0, 40.0])
    assert lr.classify(elsewhere) == 0
    add(elsewhere, 0, 0.0, False)  # not met, classified elsewhere -> neither
    assert [bool(sit.pos[s]) for s in slots] == [True, False, False, True, False]
    assert [bool(sit.neg[s]) for s in slots] == [False, True, False, False, False]


def test_oldest_record_forgotten_everywhere():
    lr = make_learner(history_size=10, n_min_r=1)
    for k in range(4):
        add_goal_record(lr, k)
    sit = lr.order[0]
    first = 0
    assert sit.pos[first]
    for _ in range(6):
        lr.add_record(np.array([60.0, 60.0]), 0, ARRIVAL, 0.0, np.array([60.0, 60.0]), 0, True)
    assert len(lr.hist) == 10 and sit.pos[first]
    lr.add_record(np.array([60.0, 60.0]), 0, ARRIVAL, 0.0, np.array([60.0, 60.0]), 0, True)
    assert not sit.pos[first] and sit.n_pos == 3
    assert len(lr.hist) == 10


def test_reordering_by_utility_changes_who_wins_an_overlap():
    lr = make_learner(n_init_r=3)
    a_pts = ring((0.0, 0.0), 2.0, 8)
    ang = np.linspace(0.0, 2 * np.pi, 8, endpoint=False) + np.pi / 8
    b_pts = np.stack([3.8 + 2.0 * np.cos(ang), 2.0 * np.sin(ang)], 1)  # none inside A
    for p in a_pts:  # A: goal reward 6 by behaviour 0, extracted first
        lr.add_record(p, lr.classify(p), 0, 6.0, p, lr.classify(p), True)
    for p in b_pts:  # B: goal reward 10 by behaviour 1
        lr.add_record(p, lr.classify(p), 1, 10.0, p, lr.classify(p), True)
    a, b = lr.order
    assert (a.reward_key, b.reward_key) == (6.0, 10.0)
    overlap = np.array([1.9, 0.0])
    assert lr.classify(overlap) == a.id
    lr._periodic()
    assert [s.id for s in lr.order] == [b.id, a.id]
    assert b.utility > a.utility > 0
    assert lr.classify(overlap) == b.id
    assert lr.events[-1]["event"] == "reordered"


# -- operation 4: validity, recycling, the five elimination cases ------------------------

def base(**overrides):
    """R1 (b=0) near the origin and T2 (b=1 -> R1) near (20, 0); labels kept as given."""
    lr = make_learner(relabel="never", n_init_t=3, n_min_t=2, n_init_r=2, n_min_r=2,
                      **overrides)
    h = lr.hist
    for p in GOAL_PTS[:3]:
        h.append(p, 0, 0, 10.0, p, 0, True)
    lr._new_situation("R", 0, 0, 10.0, 3)
    r1 = lr.order[0]
    for p in ring((20.0, 0.0), 1.0, 3):
        h.append(p, 0, 1, 0.0, GOAL_PTS[0], r1.id, False)
    lr._new_situation("T", 1, r1.id, 0.0, 3)
    return lr, r1, lr.order[1]


def taken_from(lr, sid, b, to, n, terminal=False):
    for _ in range(n):
        lr.hist.append(np.array([20.0, 0.0]), sid, b, 0.0, np.array([0.0, 0.0]), to, terminal)
    lr._version += 1


def last(lr, kind):
    return [e for e in lr.events if e["event"] == kind][-1]


def test_valid_situations_are_left_alone():
    lr, r1, t2 = base()
    taken_from(lr, t2.id, 1, r1.id, 3)
    lr._validity()
    assert [s.id for s in lr.order] == [r1.id, t2.id]


def test_recycling_redefines_with_the_most_frequent_behaviour_and_result():
    lr, r1, t2 = base()
    lr.hist.append(GOAL_PTS[3], 0, 3, 10.0, GOAL_PTS[3], 0, True)
    for p in GOAL_PTS[4:7]:
        lr.hist.append(p, 0, 3, 10.0, p, 0, True)
    lr._new_situation("R", 3, 0, 10.0, 4)
    r3 = lr.order[2]
    taken_from(lr, t2.id, 2, r3.id, 4)  # behaviour 2 from T2 reaches R3: strict majority
    taken_from(lr, t2.id, 1, r1.id, 1)
    lr._validity()
    assert t2.attributes() == ("T", 2, r3.id)
    ev = last(lr, "redefined")
    assert ev["situation"] == t2.id and ev["reason"] == "not_majority"
    assert (ev["old_behaviour"], ev["old_parent"]) == (1, r1.id)
    assert t2.n_pos == 4 and t2.n_neg == 0
    assert sum(1 for e in lr.events if e["event"] == "redefined") == 1  # once per check


@pytest.mark.parametrize("case,target,expect", [
    ("case 1", "zero", "case 1: new parent is situation 0"),
    ("case 2", "self", "case 2: new parent is itself"),
    ("case 3", "child", "case 3: new parent's parent is itself"),
    ("case 4", "taken", "case 4: attributes already taken"),
    ("case 5", "few", "case 5: too few positive instances"),
])
def test_the_five_elimination_cases(case, target, expect):
    lr, r1, t2 = base()
    if target == "zero":
        to = 0
    elif target == "self":
        to = t2.id
    elif target == "child":  # T4 (b=3 -> T2) exists; T2 would become (2 -> T4)
        for p in ring((40.0, 0.0), 1.0, 3):
            lr.hist.append(p, 0, 3, 0.0, np.array([20.0, 0.0]), t2.id, False)
        lr._new_situation("T", 3, t2.id, 0.0, 3)
        to = lr.order[-1].id
    elif target == "taken":  # T5 = (2 -> R1) exists
        for p in ring((60.0, 0.0), 1.0, 3):
            lr.hist.append(p, 0, 2, 0.0, GOAL_PTS[0], r1.id, False)
        lr._new_situation("T", 2, r1.id, 0.0, 3)
        to = r1.id
    else:  # only 2 records would be positives, fewer than n_init_t = 3
        for p in GOAL_PTS[3:6]:
            lr.hist.append(p, 0, 3, 10.0, p, 0, True)
        lr._new_situation("R", 3, 0, 10.0, 3)
        to = lr.order[-1].id
    n = 2 if target == "few" else 4
    taken_from(lr, t2.id, 2, to, n)
    lr._validity()
    assert t2.id not in lr.by_id
    ev = [e for e in lr.events if e["event"] == "eliminated" and e["situation"] == t2.id]
    assert len(ev) == 1 and ev[0]["reason"] == "not_majority; " + expect


def test_too_few_positives_eliminates_an_r_situation_and_orphans_its_children():
    lr, r1, t2 = base()
    r1.pos[:] = False
    r1.pos[0] = True  # 1 < n_min_r = 2
    lr._validity()
    assert lr.order == []
    reasons = {e["situation"]: e["reason"] for e in lr.events if e["event"] == "eliminated"}
    assert reasons[r1.id] == "too_few_positives"  # R-situations are never recycled
    assert reasons[t2.id].startswith("parent_eliminated")


def test_majority_strict_versus_plurality():
    for majority, survives in (("strict", True), ("plurality", False)):
        lr, r1, t2 = base(majority=majority)
        taken_from(lr, t2.id, 1, r1.id, 3)  # own pair: 3 of 10
        taken_from(lr, t2.id, 2, 0, 4)  # plurality pair, not a strict majority: 4 of 10
        taken_from(lr, t2.id, 3, 0, 3)
        lr._validity()
        assert (t2.id in lr.by_id) is survives, majority


def test_operation_5_eliminates_negative_utility():
    lr = make_learner(n_init_r=3, n_min_r=1, history_size=400)
    for k in range(4):
        add_goal_record(lr, k)
    sit = lr.order[0]
    inside = np.array([0.3, 0.3])
    for b in range(4):  # every behaviour from it now costs more than it earns
        for _ in range(60):
            lr.add_record(inside, sit.id, b, -1.0, inside, sit.id, False)
    lr._periodic()
    assert sit.id not in lr.by_id
    assert last(lr, "eliminated")["reason"].startswith("negative utility")


def test_boundary_refit_interval_versus_every_step():
    for mode, moves in (("every_step", True), ("interval", False)):
        lr = make_learner(boundary_refit=mode, adjust_interval=1000, n_init_r=3)
        for k in range(4):
            add_goal_record(lr, k)
        sit = lr.order[0]
        before = sit.boundary
        far = np.array([6.0, 0.0])
        lr.add_record(far, lr.classify(far), 0, 10.0, far, 0, True)
        assert (sit.boundary != before) is moves, mode


@pytest.mark.parametrize("mode", ["after_modification", "never"])
def test_stored_labels_after_a_big_modification(mode):
    lr = make_learner(relabel=mode)
    for k in range(4):
        add_goal_record(lr, k)  # labelled 0 when stored: no situation existed yet
    rid = lr.order[0].id
    labels = set(lr.hist.s[lr.hist.valid].tolist())
    assert labels == ({rid} if mode == "after_modification" else {0})


# -- option r_break_window (algorithm.md, "Readings") --------------------------------------

@pytest.mark.parametrize("window", [0, 4])
def test_r_break_window_eliminates_a_broken_r_situation_and_forgets_its_old_positives(window):
    lr = make_learner(n_init_r=3, n_min_r=3, r_break_window=window)
    for k in range(6):  # slots 0-5: successes; R extracted at the 4th
        add_goal_record(lr, k)
    (r,) = lr.order
    assert r.n_pos == 6
    away = np.array([40.0, 40.0])
    for k in range(3):  # slots 6-8: its behaviour from inside it now misses the goal
        lr.add_record(GOAL_PTS[k], r.id, 0, -1.0, away, 0, False)
        if k < 2 or window == 0:  # last 4 uses: s s f f -> 2 of 4 failed, not more than half
            assert lr.order == [r]
    if window == 0:
        assert r.n_pos == 6 and lr.hist.valid.sum() == 9
        return
    assert lr.order == []  # s f f f: broken; R-situations are never recycled
    ev = last(lr, "eliminated")
    assert ev["situation"] == r.id and ev["reason"] == "recent_failures"
    assert last(lr, "forgotten")["records"] == 5  # the 5 successes older than the window
    assert lr.hist.valid.tolist() == [False] * 5 + [True] * 4 + [False] * (lr.hist.capacity - 9)
    for k in range(3):  # one kept success + 3 new ones: more than n_init_r again
        add_goal_record(lr, k + 3)
    assert [s.attributes() for s in lr.order] == [("R", 0, 10.0)]
    assert lr.order[0].n_pos == 4


@pytest.mark.parametrize("forget", ["positives", "history"])
def test_r_break_forget_reading(forget):
    """r_break_forget="history": every record older than the first failure that broke the
    R-situation leaves the history (the blank state of section 7.2), not only its positives."""
    lr = make_learner(n_init_r=3, n_min_r=3, r_break_window=4, r_break_forget=forget)
    far = np.array([60.0, -60.0])
    for _ in range(2):  # slots 0-1: another behaviour, far from the goal
        lr.add_record(far, 0, 1, -1.0, far + 1.0, 0, False)
    for k in range(5):  # slots 2-6: successes; R extracted at the 4th (slot 5)
        add_goal_record(lr, k)
    (r,) = lr.order
    for k in range(3):  # slots 7-9: its uses since extraction s f f f -> broken
        lr.add_record(GOAL_PTS[k], r.id, 0, -1.0, np.array([40.0, 40.0]), 0, False)
    assert lr.order == []
    kept = lr.hist.valid[:10].tolist()
    if forget == "positives":  # the 4 successes older than the window
        assert last(lr, "forgotten")["records"] == 4
        assert kept == [True, True] + [False] * 4 + [True] * 4
    else:  # every record older than the first miss: the 2 others and all 5 successes
        assert last(lr, "forgotten")["records"] == 7
        assert kept == [False] * 7 + [True] * 3


@pytest.mark.parametrize("fraction,misses_to_break", [(0.5, 3), (0.75, 4)])
def test_r_break_fraction(fraction, misses_to_break):
    """The break needs more than r_break_fraction of the window to have missed: with a
    window of 4 after one success, 3 misses break it at 0.5, 4 at 0.75."""
    lr = make_learner(n_init_r=3, n_min_r=3, r_break_window=4, r_break_fraction=fraction)
    for k in range(5):
        add_goal_record(lr, k)
    (r,) = lr.order
    for k in range(4):
        lr.add_record(GOAL_PTS[k], r.id, 0, -1.0, np.array([40.0, 40.0]), 0, False)
        assert (lr.order == []) is (k + 1 >= misses_to_break), k
        if not lr.order:
            return
    raise AssertionError("never broken")


def test_r_break_window_counts_only_uses_since_extraction():
    """Failures stored before an R-situation existed (re-labelled into it) do not break it."""
    lr = make_learner(n_init_r=3, n_min_r=3, r_break_window=4)
    for k in range(3):
        add_goal_record(lr, k)
    for k in range(3):  # misses from where the R-situation will be, before it exists
        lr.add_record(np.array([0.1 * k, 0.0]), 0, 0, -1.0, np.array([40.0, 40.0]), 0, False)
    add_goal_record(lr, 3)  # 4 successes: extracted; its stored uses: f f f s
    (r,) = lr.order
    assert lr.classify(np.array([0.1, 0.0])) == r.id
    assert int(np.count_nonzero(lr.hist.s[lr.hist.valid] == r.id)) == 7
    assert lr._broken(r) is None


@pytest.mark.parametrize("useless,survives", [("negative", True), ("no_positive_plan", False)])
def test_useless_reading_of_operation_5(useless, survives):
    """T2's only tried behaviour always costs -1 and leads back to T2; the untried ones count
    0 in Eq. 1, so its utility is 0: the paper's operation 5 keeps it, the reading does not."""
    lr, r1, t2 = base(useless=useless)
    for _ in range(20):
        lr.hist.append(np.array([20.0, 0.0]), t2.id, 1, -1.0, np.array([20.0, 0.5]), t2.id,
                       False)
    lr._version += 1
    lr._periodic()
    assert t2.utility == 0.0 or t2.id not in lr.by_id
    assert (t2.id in lr.by_id) is survives
    assert r1.id in lr.by_id  # the R-situation has a positive plan
    if not survives:
        assert last(lr, "eliminated")["reason"] == "no positive plan 0"


def test_nn_window_lets_a_recent_miss_outweigh_older_successes():
    """A miss at the R-situation's centre, nearer the query than the new success but farther
    than an old one: the paper's NN test accepts (the old success is nearest); with the
    window holding only the newest records it rejects; once the miss has left the window (no
    instance of the situation in it) every instance counts again."""
    query = np.array([1.2, 0.0])  # nearest instance: the old success at (2, 0)
    results = {}
    for window in (0, 3):
        lr = make_learner(n_init_r=3, n_min_r=3, nn_window=window)
        for k in range(8):
            add_goal_record(lr, k)  # successes on a ring of radius 2; (-2, 0) is k = 1
        (r,) = lr.order
        assert lr.classify(query) == r.id
        add_goal_record(lr, 1)  # a new success, far from the query
        lr.add_record(np.zeros(2), r.id, 0, -1.0, np.array([40.0, 40.0]), 0, False)  # miss
        assert r.neg.any()
        results[window] = [lr.classify(query) == r.id]
        for _ in range(3):  # other behaviours elsewhere: no instances of r
            lr.add_record(np.array([30.0, 0.0]), 0, 1, 0.0, np.array([31.0, 0.0]), 0, False)
        results[window].append(lr.classify(query) == r.id)
        if window:
            assert int(np.count_nonzero(lr._recent)) == window
            assert not (lr._recent & (r.pos | r.neg)).any()
    assert results == {0: [True, True], 3: [False, True]}


def test_nn_window_also_bounds_the_bitten_reach():
    """margin_plan="nearest_r_bitten" compares the same windowed instances beyond the
    ellipsoid: a recent miss outside outweighs an older success nearer the input."""
    out = {}
    for window in (0, 2):
        lr = make_learner(n_init_r=3, n_min_r=3, nn_window=window)
        for k in range(8):
            add_goal_record(lr, k)
        (r,) = lr.order
        lr.add_record(np.array([-3.0, 0.0]), 0, 0, -1.0, np.array([40.0, 40.0]), 0, False)
        out[window] = lr.reach_accepts(r.id, np.array([-2.45, 0.0]))
    assert out == {0: True, 2: False}


def test_margin_stn_no_positives_leaves_bitten_out_successes_out_of_the_margin_node():
    """With the NN window a recent miss bites the old successes out of their R-situation and
    re-labelling puts them into the margin. By default their stored goal arrivals then count
    as the margin node's "behaviour 0 reaches the goal"; margin_stn="no_positives" leaves
    those positive instances out, and keeps every other margin record."""
    stns = {}
    for opt in ("all", "no_positives"):
        lr = make_learner(n_init_r=3, n_min_r=3, nn_window=3, margin_stn=opt)
        for k in range(8):
            add_goal_record(lr, k)  # successes on a ring of radius 2
        (r,) = lr.order
        miss = GOAL_PTS[0] * 0.95
        lr.add_record(miss, r.id, 0, -1.0, np.array([40.0, 40.0]), 0, False)
        for _ in range(2):  # other behaviours elsewhere: the old successes leave the window
            lr.add_record(np.array([30.0, 0.0]), 0, 1, 0.0, np.array([31.0, 0.0]), 0, False)
        lr.relabel()
        assert lr.classify(GOAL_PTS[0]) == MARGIN and r.pos.sum() == 8
        stns[opt] = lr.stn()
    every, kept = stns["all"], stns["no_positives"]
    # behaviour 0 from the margin: the 8 old arrivals and the miss, or the miss alone
    assert every.counts[0, 0].sum() == 9 and every.p[0, 0, every.goal] == pytest.approx(8 / 9)
    assert kept.counts[0, 0].sum() == 1 and kept.p[0, 0, kept.goal] == 0.0
    # the margin's other records count either way
    assert every.counts[0, 1].sum() == kept.counts[0, 1].sum() == 2


@pytest.mark.parametrize("radius", [0.0, 0.5])
def test_contradiction_radius_replaces_the_outcomes_around_a_new_one(radius):
    lr = make_learner(n_init_r=3, contradiction_radius=radius)
    for k in range(4):  # four goal arrivals of behaviour 0 around the origin: an R-situation
        add_goal_record(lr, k)
    add_goal_record(lr, 4, b=1)  # another behaviour's arrival at the same place
    far = np.array([30.0, 0.0])
    lr.add_record(far, lr.classify(far), 0, 10.0, far, lr.classify(far), True)
    sit = lr.order[0]
    before = sit.n_pos
    # behaviour 0 from the first arrival's start now ends in the margin without the goal
    x = GOAL_PTS[0] + 0.01
    lr.add_record(x, lr.classify(x), 0, 0.0, far + 5.0, MARGIN, False)
    h = lr.hist
    gone = h.valid[:6] == False  # noqa: E712
    if radius == 0.0:
        assert not gone.any() and sit.n_pos == before
        return
    std = h.x[:7].std(axis=0)  # the scale over the stored records, the new one included
    near = np.sum(((GOAL_PTS[:4] - x) / std) ** 2, axis=1) <= radius ** 2
    assert near.any() and not near.all()  # the test separates near from far
    assert list(gone[:4]) == list(near)  # behaviour 0's arrivals within the radius left
    assert not gone[4] and not gone[5]  # another behaviour's, and a far one, stay
    assert sit.n_pos == before - int(near.sum())
    assert lr.events[-1]["event"] == "contradicted"
    assert lr.events[-1]["records"] == int(near.sum())


def test_contradiction_radius_keeps_outcomes_that_agree():
    lr = make_learner(n_init_r=3, contradiction_radius=5.0)
    for k in range(8):
        add_goal_record(lr, k)
    assert int(lr.hist.valid.sum()) == 8  # every arrival agrees with the others


@pytest.mark.parametrize("window", [0, 4])
def test_contradiction_window_waits_for_a_change_point(window):
    lr = make_learner(n_init_r=3, contradiction_radius=5.0, contradiction_window=window)
    for k in range(4):  # slots 0-3: the arrivals that extract the R-situation
        add_goal_record(lr, k)
    add_goal_record(lr, 4)  # slot 4: its first use, a success
    far = np.array([30.0, 0.0])
    valid = []
    for k in range(3):  # slots 5-7: three uses that miss, ending in the margin
        x = GOAL_PTS[k]
        lr.add_record(x, lr.classify(x), 0, 0.0, far, MARGIN, False)
        valid.append(lr.hist.valid[:8].tolist())
    before = [False] * 5 + [True] * 3  # the five arrivals gone, the misses kept
    if window == 0:  # every miss contradicts the arrivals around it at once
        assert valid[0][:6] == [False] * 5 + [True]
    else:  # the last 4 uses hold more than half misses only at slot 7; the change point
        # is the oldest of those misses (slot 5), and only what came before it can leave
        assert valid[0][:6] == [True] * 6 and valid[1][:7] == [True] * 7
        assert lr._change_at == 5
    assert valid[2] == before


# -- option validity_check (algorithm.md, "Readings") --------------------------------------

@pytest.mark.parametrize("check", ["before_periodic", "also_after_periodic"])
def test_validity_check_after_the_periodic_operations(check):
    """Operation 5 eliminates R1 at the adjust interval; its child T2 is then inappropriate
    (parent eliminated). The second check handles T2 in the same step; without it T2 stays
    in the discrimination order, where a plan can use it, until the next step's check."""
    interval = 6 + 40 + 1  # base() stores 6 records, 40 below, the add_record makes 47
    lr, r1, t2 = base(adjust_interval=interval, validity_check=check)
    inside = GOAL_PTS[0]
    for k in range(40):  # every behaviour from R1 costs: its utility turns negative
        lr.hist.append(inside, r1.id, k % 4, -1.0, inside, r1.id, False)
    lr._version += 1
    lr.add_record(inside, r1.id, 0, -1.0, inside, r1.id, False)
    assert lr.hist.total == interval
    assert r1.id not in lr.by_id
    assert last(lr, "eliminated")["reason"].startswith(
        "negative utility" if check == "before_periodic" else "parent_eliminated")
    if check == "before_periodic":
        assert [s.id for s in lr.order] == [t2.id] and lr._any_inappropriate()
    else:
        assert lr.order == []  # T2 eliminated: no behaviour was taken from it to recycle
