"""§7.4 figures: the random collection with a frozen segmentation, and the summary over
trial sets, on toy worlds and synthetic results with known answers."""

from __future__ import annotations

import numpy as np
import pytest
from stns_experiments.experiments import offline_figures, offline_random


class ToyWorld:
    """State 0 or 1 (the observation is the state). Behaviour 0 or 2: goal reward, the trial
    ends; behaviour 1 toggles the state; behaviour 3: a penalty, the state stays."""

    def __init__(self) -> None:
        self.state = 0

    def reset(self):
        self.state = 0
        return self.state, {}

    def step(self, b: int):
        if b in (0, 2):
            return self.state, 10.0, True, False, {}
        if b == 1:
            self.state = 1 - self.state
            return self.state, 0.0, False, False, {}
        return self.state, -1.0, False, False, {}


class ToyAgent:
    """The frozen segmentation: the situation is the state."""

    def classify(self, obs: int) -> int:
        return int(obs)


# Two R-situations (behaviours 0 and 2) and a T-situation of behaviour 1 whose parent is
# situation 1 (so a positive is a toggle from state 0).
SITS = [{"id": 1, "kind": "R", "behaviour": 0, "parent": None, "positives": 1},
        {"id": 3, "kind": "R", "behaviour": 2, "parent": None, "positives": 4},
        {"id": 2, "kind": "T", "behaviour": 1, "parent": 1, "positives": 3}]


def _oracle(seed: int, sits: list[dict]):
    """Replays the same random behaviours by hand: (behaviour by which each situation has
    its count, behaviour by which the R and T sums are reached)."""
    rng = np.random.default_rng(seed)
    need = {s["id"]: s["positives"] for s in sits}
    need_r = sum(s["positives"] for s in sits if s["kind"] == "R")
    need_t = sum(s["positives"] for s in sits if s["kind"] == "T")
    have = dict.fromkeys(need, 0)
    done: dict[int, int] = {}
    totals = None
    state, n = 0, 0
    while len(done) < len(need):
        b = int(rng.integers(4))
        n += 1
        if b == 0:
            have[1] += 1
        elif b == 2:
            have[3] += 1
        elif b == 1:
            if state == 0:
                have[2] += 1
            state = 1 - state
        if b in (0, 2):
            state = 0
        for i in need:
            if i not in done and have[i] >= need[i]:
                done[i] = n
        if totals is None and have[1] + have[3] >= need_r and have[2] >= need_t:
            totals = n
    return done, totals


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_offline_random_counts_each_situation_and_the_sums(seed):
    out = offline_random(ToyWorld(), ToyAgent(), SITS, np.random.default_rng(seed),
                         max_behaviours=10_000, max_ticks=5, r_min=5.0)
    done, totals = _oracle(seed, SITS)
    assert out["all_collected"]
    assert out["collected_at"] == {str(k): v for k, v in done.items()}
    assert out["random_behaviours"] == max(done.values())
    assert out["totals_needed"] == {"R": 5, "T": 3}
    assert out["totals_collected_at"] == totals
    # per-situation counts imply the sums, never the other way round
    assert out["totals_collected_at"] <= out["random_behaviours"]


def test_sums_can_be_reached_before_every_situation_has_its_own_count():
    # with R-situation 1 needing 1 and 3 needing 4, five arrivals by behaviour 0 alone reach
    # the R sum; some seed must show the sums well before the per-situation criterion
    gaps = []
    for seed in range(20):
        out = offline_random(ToyWorld(), ToyAgent(), SITS, np.random.default_rng(seed),
                             max_behaviours=10_000, max_ticks=5, r_min=5.0)
        gaps.append(out["random_behaviours"] - out["totals_collected_at"])
    assert max(gaps) > 0


def test_offline_random_cap_leaves_the_sums_unreached():
    out = offline_random(ToyWorld(), ToyAgent(), SITS, np.random.default_rng(0),
                         max_behaviours=2, max_ticks=5, r_min=5.0)
    assert not out["all_collected"] and out["random_behaviours"] == 2
    assert out["totals_collected_at"] is None


def _set(online, targets, kinds, random_behaviours, totals_at, collected=True):
    return {"online_behaviours": online, "targets": targets, "target_kinds": kinds,
            "random_behaviours": random_behaviours, "totals_collected_at": totals_at,
            "all_collected": collected}


def test_offline_figures_sums_per_set_and_the_papers_arithmetic():
    sets = [_set(1000, {"1": 100, "2": 60, "3": 40}, {"1": "R", "2": "R", "3": "T"}, 9000, 6000),
            _set(800, {"5": 120, "6": 30, "7": 50}, {"5": "R", "6": "T", "7": "T"}, 7000, 5000)]
    f = offline_figures(sets, behaviours_per_arrival=40.0)
    # sums per set: R 160 and 120, T 40 and 80
    assert f["positives_r_sum_mean"] == pytest.approx(140.0)
    assert f["positives_t_sum_mean"] == pytest.approx(60.0)
    assert f["positives_r_mean"] == pytest.approx((100 + 60 + 120) / 3)
    assert f["positives_t_mean"] == pytest.approx((40 + 30 + 50) / 3)
    assert f["situations_r_mean"] == pytest.approx(1.5)
    assert f["situations_t_mean"] == pytest.approx(1.5)
    assert f["online_behaviours_mean"] == pytest.approx(900.0)
    assert f["ratio_measured"] == pytest.approx(16000 / 1800)
    assert f["ratio_measured_totals"] == pytest.approx(11000 / 1800)
    assert f["random_behaviours_totals_mean"] == pytest.approx(5500.0)
    assert not f["ratio_is_lower_bound"] and not f["ratio_totals_is_lower_bound"]
    # (140 x 40 + 60 x 4) / 900
    assert f["ratio_paper_arithmetic"] == pytest.approx((140 * 40 + 60 * 4) / 900)


def test_offline_figures_the_papers_own_numbers_give_its_ratio():
    # §7.4: 225.5 R and 212.7 T positives, 48.09 random behaviours per arrival, 967.9 on-line
    # behaviours -> 12.1; one set whose sums are the paper's, split over 2 R and 4 T
    sets = [_set(967.9, {"a": 112.75, "b": 112.75, "c": 53.175, "d": 53.175, "e": 53.175,
                         "f": 53.175}, dict(zip("abcdef", "RRTTTT", strict=True)), 1, 1)]
    f = offline_figures(sets, behaviours_per_arrival=48.09)
    assert f["ratio_paper_arithmetic"] == pytest.approx(12.08, abs=0.01)


def test_offline_figures_a_set_that_never_reached_the_sums_is_a_lower_bound():
    sets = [_set(1000, {"1": 10}, {"1": "R"}, 300, None, collected=False),
            _set(1000, {"1": 10}, {"1": "R"}, 500, 400)]
    f = offline_figures(sets, behaviours_per_arrival=None)
    assert f["ratio_totals_is_lower_bound"] and f["ratio_is_lower_bound"]
    assert f["ratio_measured_totals"] == pytest.approx((300 + 400) / 2000)
    assert f["ratio_paper_arithmetic"] is None


def test_offline_figures_results_without_the_sums_give_no_sums_ratio():
    old = _set(1000, {"1": 10}, {"1": "R"}, 500, None)
    del old["totals_collected_at"]
    f = offline_figures([old], behaviours_per_arrival=40.0)
    assert f["ratio_measured_totals"] is None and f["random_behaviours_totals_mean"] is None
    assert f["ratio_measured"] == pytest.approx(0.5)
