"""Metrics on small synthetic records with known answers."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import make_trials

from stns_experiments import metrics as M
from stns_experiments import records as R


def test_block_counts_and_ratio():
    # trials of 3 behaviours + arrival = 4 steps each; 5 trials = 20 steps
    table = R.to_table(make_trials([3] * 5))
    bs, ar = M.block_counts(table, 10, 20)
    # steps 1-10: trials 1, 2 complete (8 steps) + 2 behaviours of trial 3
    assert bs.tolist() == [8, 7] and ar.tolist() == [2, 3]
    assert M.ratio(bs, ar).tolist() == [4.0, pytest.approx(7 / 3)]
    assert M.behaviours_to_goal(table, 0, 20) == 3.0


def test_block_without_arrival_is_nan_and_pooled_curve_stays_finite():
    a = R.to_table(make_trials([9]))          # 10 steps: 9 behaviours, arrival at step 10
    b = R.to_table(make_trials([1] * 5))      # 10 steps: 5 arrivals
    curve, per_set, bsum, asum = M.pooled_curve([a, b], 5, 10)
    assert math.isnan(per_set[0, 0]) and per_set[0, 1] == 4.0
    assert bsum.tolist() == [5 + 3, 4 + 2] and asum.tolist() == [2, 1 + 3]
    assert curve.tolist() == [4.0, 1.5]


def test_convergence_block_rule_known_answer():
    curve = [10, 8, 5, 2.5, 2.2, 2.0, 2.1, 2.05, 2.0, 2.0]
    # final level 2.0; band [1.8, 2.2]; block 3 (2.5) is the last outside
    assert M.convergence_block(curve, 2.0, 100, 0.1) == 400
    # a late outlier moves convergence behind it
    assert M.convergence_block(curve[:8] + [2.5, 2.0], 2.0, 100, 0.1) == 900
    # last block outside: never converged
    assert M.convergence_block(curve[:9] + [3.0], 2.0, 100, 0.1) is None
    assert M.convergence_block([2.0, 2.0], 2.0, 100) == 0


def test_convergence_trailing_rule_known_answer():
    b = np.array([40, 30, 20, 20, 20, 20, 20, 20])
    a = np.array([1, 5, 10, 10, 10, 10, 10, 10])
    # window of 2 blocks (200 steps): block ends 200: 70/6, 300: 50/15, 400: 40/20 = 2.0 ...
    tr = M.trailing_curve(b, a, 100, 200)
    assert math.isnan(tr[0]) and tr[1] == pytest.approx(70 / 6) and tr[3] == 2.0
    assert M.convergence_trailing(b, a, 2.0, 100, 200, 0.1) == 400
    assert M.first_reaching(b, a, 2.0, 100, 200, 0.1) == 400


def test_first_block_at_or_below():
    assert M.first_block_at_or_below([9, 5, 2.1, 1.5, 2.0], 2.0, 250, 0.1) == 500
    assert M.first_block_at_or_below([9, 5, 2.1, 3.0], 2.0, 250, 0.1) is None


def test_success_rates_and_within_two():
    kinds = [["T", "R"], ["R"], ["T", "T", "R"], ["0", "T", "R"]]
    success = [[True, True], [False], [True, False, True], [None, True, True]]
    recs = make_trials([2, 1, 3, 3], kinds, success)
    table = R.to_table(recs)
    n = len(recs)                                  # 2+1+3+3 behaviours + 4 arrivals = 13
    assert n == 13
    assert M.success_counts(table, "R", 0, n) == (3, 4)
    assert M.success_counts(table, "T", 0, n) == (3, 4)
    assert M.within_counts(table, 0, n, 2) == (2, 4)
    # a window that cuts trial 1 off (it starts at step 1): trials 2..4 only
    assert M.within_counts(table, 1, n, 2) == (1, 3)
    assert M.trial_lengths(table, 1, n).tolist() == [1, 3, 3]
    assert M.frac(0, 0) is None


def test_unplanned_steps_do_not_count_for_success():
    recs = make_trials([2], [["R", "R"]], [[True, False]], planned=False)
    assert M.success_counts(R.to_table(recs), "R", 0, 3) == (0, 0)


def test_csv_round_trip(tmp_path):
    recs = make_trials([2, 1], [["T", "R"], ["R"]], [[True, None], [False]])
    table = R.to_table(recs)
    table["x"][:] = np.arange(len(recs) * 2).reshape(-1, 2) / 3.0
    path = tmp_path / "r.csv.gz"
    R.write_csv(table, path)
    back = R.read_csv(path)
    for k in table:
        if table[k].dtype.kind == "f":
            np.testing.assert_array_equal(np.isnan(back[k]), np.isnan(table[k]))
            np.testing.assert_array_equal(np.nan_to_num(back[k]), np.nan_to_num(table[k]))
        else:
            np.testing.assert_array_equal(back[k], table[k])


def test_percentile_band_ignores_nan():
    lo, hi = M.percentile_band(np.array([[1.0, np.nan], [3.0, np.nan]]))
    assert lo[0] == 1.5 and hi[0] == 2.5 and math.isnan(lo[1])


def test_ticks_per_arrival_counts_control_time_and_pools_sums():
    from stns_experiments.experiments import summarise_sets, window_result
    # every behaviour record of make_trials lasts 3 ticks, an arrival record 0
    a = R.to_table(make_trials([3] * 5))   # 20 steps: 15 behaviours, 5 arrivals
    b = R.to_table(make_trials([9, 9]))    # 20 steps: 18 behaviours, 2 arrivals
    assert M.span_ticks(a, 0, 20) == 45 and M.span_ticks(a, 16, 20) == 9
    params = {"final_window": 8, "block_size": 10, "convergence_tol": 0.1,
              "trailing_window": 10}
    results = []
    for t in (a, b):
        bs, ar = M.block_counts(t, 10, 20)
        results.append({"block_behaviours": bs.tolist(), "block_arrivals": ar.tolist(),
                        "situations_final": None, "wall_seconds": 1.0,
                        **window_result(t, 20, params)})
    assert results[1]["run_ticks"] == 54 and results[1]["run_arrivals"] == 2
    s = summarise_sets(results, params, 20)
    assert s["ticks_per_arrival"] == pytest.approx((45 + 54) / (5 + 2))
    # steps 13-20: a has 6 behaviours and 2 arrivals; b 7 behaviours and its second arrival
    assert s["final_ticks_per_arrival"] == pytest.approx((18 + 21) / (2 + 1))
    old = [{k: v for k, v in r.items() if k != "run_ticks"} for r in results]
    assert summarise_sets(old, params, 20)["ticks_per_arrival"] is None
