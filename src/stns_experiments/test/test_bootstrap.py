"""The bootstrap over trial sets (stns_experiments.bootstrap) on small synthetic run folders
with known answers."""

from __future__ import annotations

import json

import pytest
from conftest import PARAMS, synthetic_run, synthetic_set
from stns_experiments.config import ExperimentError

from stns_experiments import bootstrap as BS
from stns_experiments import pool as P

LONG = dict(PARAMS, steps=600)  # 6 blocks of 100, final window the last 2
FAST = ([40, 20, 20, 20, 20, 20], [10] * 6)  # 4, then 2 per arrival: converged from 100
SLOW = ([40, 40, 40, 40, 20, 20], [10] * 6)  # 4 until block 3: converged from 400


@pytest.fixture(autouse=True)
def same_code(monkeypatch):
    monkeypatch.setattr(P, "library_changes", lambda commits, cwd=None: [])


def _run(tmp_path, name, seed, counts, params=LONG):
    sets = [synthetic_set(f"set{i:02d}", list(b), list(a)) for i, (b, a) in enumerate(counts)]
    return synthetic_run(tmp_path / name, seed, sets, params=params)


def test_identical_sets_leave_no_spread_and_give_the_pooled_figures(tmp_path):
    runs = [_run(tmp_path, "a", 0, [FAST] * 3), _run(tmp_path, "b", 1, [FAST] * 2)]
    s = BS.bootstrap(runs, resamples=50, at=[0, 100])
    pooled = P.pool(runs)
    f = s["figures"]
    assert s["trial_sets"] == 5
    assert f["convergence_step"]["sample"] == pooled["convergence_step"] == 100
    assert f["convergence_step_trailing"]["sample"] == pooled["convergence_step_trailing"]
    assert f["final"]["sample"] == pytest.approx(pooled["final_behaviours_to_goal"])
    assert set(f["convergence_step"]["quantiles"].values()) == {100}
    assert f["convergence_step"]["at_or_below"] == {"0": 0.0, "100": 1.0}
    assert f["convergence_step"]["undefined"] == 0.0


def test_resampling_two_kinds_of_sets_spans_both_and_repeats_with_its_seed(tmp_path):
    # one fast and one slow set: the pooled curve 4, 3, 3, 3, 2, 2 converges from 400; a
    # resample holds the fast set twice with probability 1/4 and then converges from 100
    run = _run(tmp_path, "a", 0, [FAST, SLOW])
    s = BS.bootstrap([run], resamples=4000, seed=3, at=[100])
    conv = s["figures"]["convergence_step"]
    assert conv["sample"] == 400
    assert conv["quantiles"]["2.5"] == 100 and conv["quantiles"]["97.5"] == 400
    assert conv["at_or_below"]["100"] == pytest.approx(0.25, abs=0.03)
    again = BS.bootstrap([run], resamples=4000, seed=3, at=[100])
    assert again["figures"] == s["figures"]


def test_a_curve_that_never_enters_the_band_is_undefined_not_a_step(tmp_path):
    # the last block (4) is outside 10 % of the final level (3): no convergence step
    run = _run(tmp_path, "a", 0, [([40, 40, 40, 40, 20, 40], [10] * 6)])
    s = BS.bootstrap([run], resamples=20, at=[500])
    conv = s["figures"]["convergence_step"]
    assert conv["sample"] is None and conv["undefined"] == 1.0
    assert set(conv["quantiles"].values()) == {None}
    assert conv["at_or_below"] == {"500": 0.0}
    assert "| convergence (block rule), steps | never | never / never" in BS.describe(s)


def test_exp2_resamples_each_level_and_matches_the_pooled_delay(tmp_path):
    exp2 = dict(PARAMS, experiment="exp2-sensor", block_size=250, steps=1000,
                final_window=500, pretrain_steps=1000, fault="goal_sensor_rotation_deg",
                scratch=True)
    base = [synthetic_set("set00", [50, 20], [10, 10], final_window_blocks=1),
            synthetic_set("set01", [30, 20], [10, 10], final_window_blocks=1)]
    sets = []
    for mode, counts in (("relearn", [60, 25, 23, 23]), ("scratch", [80, 21, 21, 21])):
        sets += [synthetic_set(f"10deg-{mode}-{i:02d}", counts, [10] * 4, mode=mode,
                               level=10.0) for i in range(3)]
    run = synthetic_run(tmp_path / "a", 0, sets, params=exp2, base_sets=base)
    s = BS.bootstrap([run], resamples=30)
    pooled = P.pool([run])["levels"]["10deg"]
    e = s["levels"]["10deg"]
    assert e["relearn_sets"] == 3 and e["scratch_sets"] == 3 and s["trial_sets"] == 2
    # relearning within 1.1 x scratch's final 2.1 from block 2, scratch from block 1: +250
    # steps; blocks above 1.1 x the pre-fault 2.0: 6.0, 2.5, 2.3 and 2.3
    assert e["delay_steps"]["sample"] == pooled["delay_steps"] == 250
    assert e["blocks_worse_than_prefault"]["sample"] == pooled["blocks_worse_than_prefault"] == 4
    assert set(e["delay_steps"]["quantiles"].values()) == {250}
    assert "| 10deg | delay against scratch, steps | 250 | 250 / 250" in BS.describe(s)


def test_exp2_relearning_and_scratch_sets_are_resampled_independently(tmp_path):
    """Both curves from the same two kinds of sets: drawn with one index they would always
    agree (delay 0); drawn independently they often do not."""
    exp2 = dict(PARAMS, experiment="exp2-sensor", block_size=250, steps=1000,
                final_window=500, pretrain_steps=1000, fault="goal_sensor_rotation_deg",
                scratch=True)
    kinds = ([60, 21, 21, 21], [90, 60, 40, 21])
    sets = [synthetic_set(f"10deg-{mode}-{i:02d}", kinds[i], [10] * 4, mode=mode, level=10.0)
            for mode in ("relearn", "scratch") for i in range(2)]
    base = [synthetic_set("set00", [50, 20], [10, 10], final_window_blocks=1)]
    run = synthetic_run(tmp_path / "a", 0, sets, params=exp2, base_sets=base)
    e = BS.bootstrap([run], resamples=400, seed=1)["levels"]["10deg"]
    assert e["delay_steps"]["sample"] == 0
    q = e["delay_steps"]["quantiles"]
    assert q["2.5"] < 0 < q["97.5"]


def test_exp2_without_scratch_sets_still_gives_the_blocks_above_the_band(tmp_path):
    exp2 = dict(PARAMS, experiment="exp2-sensor", block_size=250, steps=1000,
                final_window=500, pretrain_steps=1000, fault="goal_sensor_rotation_deg",
                scratch=False)
    base = [synthetic_set("set00", [50, 20], [10, 10], final_window_blocks=1)]
    sets = [synthetic_set(f"10deg-relearn-{i:02d}", [60, 25, 23, 21], [10] * 4,
                          mode="relearn", level=10.0) for i in range(2)]
    run = synthetic_run(tmp_path / "a", 0, sets, params=exp2, base_sets=base)
    e = BS.bootstrap([run], resamples=20)["levels"]["10deg"]
    # above 1.1 x the pre-fault 2.0: 6.0, 2.5 and 2.3; no scratch curve, so no delay
    assert e["scratch_sets"] == 0 and e["blocks_worse_than_prefault"]["sample"] == 3
    assert e["delay_steps"]["sample"] is None and e["delay_steps"]["undefined"] == 1.0
    assert "| 10deg | delay against scratch, steps | - | no from-scratch sets | - |" in \
        BS.describe(BS.bootstrap([run], resamples=20))
    with pytest.raises(ExperimentError, match="--at is for exp1 and exp3 runs, not exp2"):
        BS.bootstrap([run], resamples=20, at=[100])


EXP2 = dict(PARAMS, experiment="exp2-sensor", block_size=250, steps=1000, final_window=500,
            pretrain_steps=1000, fault="goal_sensor_rotation_deg", scratch=False)


def _learner(tmp_path, name, seed, base_level, relearn_blocks, n=1):
    """A run of ``n`` pre-trained learners, each at ``base_level`` behaviours per arrival
    before the fault, each relearning a 10-degree fault with ``relearn_blocks`` behaviours
    per 10 arrivals."""
    base = [synthetic_set(f"set{i:02d}", [50, 10 * base_level], [10, 10], index=i,
                          final_window_blocks=1) for i in range(n)]
    sets = [synthetic_set(f"10deg-relearn-{i:02d}", relearn_blocks, [10] * 4, index=i,
                          mode="relearn", level=10.0) for i in range(n)]
    return synthetic_run(tmp_path / name, seed, sets, params=EXP2, base_sets=base)


def test_exp2_size_draws_learners_with_their_own_relearning(tmp_path):
    """Learner A (root seed 0) is at 2 before the fault and relearns 6, 2, 2, 2; learner B
    (root seed 1, the same set index) is at 4 and relearns 6, 4, 4, 4: each is one block above
    its own band. A draw of one learner with its own relearning gives 1 every time; A's
    pre-fault level (band 2.2) with B's relearning would give 4."""
    runs = [_learner(tmp_path, "a", 0, 2, [60, 20, 20, 20]),
            _learner(tmp_path, "b", 1, 4, [60, 40, 40, 40])]
    one = BS.bootstrap(runs, resamples=400, seed=2, size=1, blocks_at=[0, 1])
    e = one["levels"]["10deg"]["blocks_worse_than_prefault"]
    assert one["size"] == 1 and one["trial_sets"] == 2
    assert set(e["quantiles"].values()) == {1}
    assert e["at_or_below"] == {"0": 0.0, "1": 1.0}
    text = BS.describe(one)
    assert "each draw 1 of them without replacement, with their own relearning sets" in text
    assert "| at most 0 blocks | at most 1 blocks |" in text
    assert "| 10deg | blocks above the pre-fault band | 1 | 1 / 1 / 1 / 1 / 1 | 0.0 % | 0.0 % " \
           "| 100.0 % |" in text
    # resampled with replacement, the groups are drawn on their own and the mismatches show
    free = BS.bootstrap(runs, resamples=400, seed=2, blocks_at=[0])
    q = free["levels"]["10deg"]["blocks_worse_than_prefault"]["quantiles"]
    assert q["2.5"] == 1 and q["97.5"] == 4


@pytest.mark.parametrize("size", [None, 1])
def test_exp2_draws_keep_each_scratch_set_whole(tmp_path, size):
    """Two from-scratch sets: A (2.1 per arrival at the end, there from block 1: delay +250
    against the relearning curve 6, 2.5, 2.3, 2.1) and B (20, 15, 5, 5: delay -250). A draw
    that took one set's behaviours with another's arrivals or final counts would give other
    delays."""
    exp2 = dict(EXP2, scratch=True)
    base = [synthetic_set("set00", [50, 20], [10, 10], index=0, final_window_blocks=1)]
    sets = [synthetic_set("10deg-relearn-00", [60, 25, 23, 21], [10] * 4, index=0,
                          mode="relearn", level=10.0),
            synthetic_set("10deg-scratch-00", [80, 21, 21, 21], [10] * 4, index=0,
                          mode="scratch", level=10.0),
            synthetic_set("10deg-scratch-01", [400, 300, 100, 100], [20] * 4, index=1,
                          mode="scratch", level=10.0)]
    run = synthetic_run(tmp_path / "a", 0, sets, params=exp2, base_sets=base)
    q = BS.bootstrap([run], resamples=300, seed=0, size=size)["levels"]["10deg"][
        "delay_steps"]["quantiles"]
    assert set(q.values()) <= {-250.0, 0.0, 250.0}  # 0: A and B pooled (with replacement)
    assert q["2.5"] == -250 and q["97.5"] == 250


def test_exp2_size_refuses_a_draw_it_cannot_make(tmp_path):
    run = _learner(tmp_path, "a", 0, 2, [60, 20, 20, 20], n=2)
    with pytest.raises(ExperimentError, match="--size 3 is more than the 2 pre-trained "
                                              "learners pooled"):
        BS.bootstrap([run], resamples=10, size=3)
    (run / "sets" / "10deg-relearn-01.json").unlink()
    with pytest.raises(ExperimentError, match="10deg holds relearning sets for 1 of the 2 "
                                              "pre-trained learners"):
        BS.bootstrap([run], resamples=10, size=1)
    exp1 = _run(tmp_path, "e1", 0, [FAST])
    with pytest.raises(ExperimentError, match="--blocks-at is for exp2 runs, not exp1"):
        BS.bootstrap([exp1], resamples=10, blocks_at=[3])
    with pytest.raises(ExperimentError, match="--blocks-at takes block counts >= 0, got -1"):
        BS.bootstrap([run], resamples=10, blocks_at=[-1])


@pytest.mark.parametrize("resamples", [0, -3, True, 2.5])
def test_a_bad_resample_count_is_named(tmp_path, resamples):
    run = _run(tmp_path, "a", 0, [FAST])
    with pytest.raises(ExperimentError, match=f"--resamples .* got {resamples!r}"):
        BS.bootstrap([run], resamples=resamples)


def test_bad_arguments_and_folders_fail_with_the_value_named(tmp_path, capsys):
    run = _run(tmp_path, "a", 0, [FAST])
    with pytest.raises(ExperimentError, match="--at takes steps >= 0, got -5"):
        BS.bootstrap([run], at=[100, -5])
    assert BS.main([str(tmp_path / "nothing")]) == 2
    assert "nothing" in capsys.readouterr().err
    assert BS.main([str(run), "--resamples", "0"]) == 2
    assert "got 0" in capsys.readouterr().err
    assert BS.main([str(run), "--seed", "-1"]) == 2  # was numpy's ValueError traceback
    assert "--seed must be a whole number >= 0, got -1" in capsys.readouterr().err
    assert BS.main([str(run), str(run)]) == 2
    assert "is named twice" in capsys.readouterr().err
    (run / "config.json").write_text("[]")
    assert BS.main([str(run)]) == 2
    assert capsys.readouterr().err == (f"error: run config: {str(run / 'config.json')!r} "
                                       f"holds a list [], not a JSON object\n")


def test_main_prints_the_table_and_writes_strict_json(tmp_path, capsys):
    run = _run(tmp_path, "a", 0, [FAST, SLOW])
    out = tmp_path / "boot.json"
    assert BS.main([str(run), "--resamples", "200", "--at", "1200", "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert "2 trial sets." in text and "at or below 1200 |" in text
    assert "| convergence (block rule), steps | 400 | 100 / " in text

    def refuse(name):
        raise ValueError(f"not strict JSON: {name}")

    s = json.loads(out.read_text(), parse_constant=refuse)
    assert s["resamples"] == 200 and s["figures"]["convergence_step"]["sample"] == 400


def test_size_draws_that_many_sets_without_replacement(tmp_path):
    """Three fast and three slow sets. A draw of one set gives that set's own figure (100
    or 400), each about half the time; a draw of all six without replacement is the pool
    itself, every time: no spread, the pooled figure."""
    run = _run(tmp_path, "a", 0, [FAST, SLOW] * 3)
    pooled = P.pool([run])["convergence_step"]
    one = BS.bootstrap([run], resamples=4000, seed=1, at=[100], size=1)
    conv = one["figures"]["convergence_step"]
    assert one["size"] == 1 and one["trial_sets"] == 6
    assert conv["sample"] == pooled
    assert conv["quantiles"]["2.5"] == 100 and conv["quantiles"]["97.5"] == 400
    assert conv["at_or_below"]["100"] == pytest.approx(0.5, abs=0.03)
    assert "each draw 1 of them without replacement" in BS.describe(one)
    every = BS.bootstrap([run], resamples=50, seed=1, at=[100], size=6)
    assert set(every["figures"]["convergence_step"]["quantiles"].values()) == {pooled}
    assert BS.bootstrap([run], resamples=50, seed=1)["size"] is None


@pytest.mark.parametrize("size, match", [
    (0, "--size must be a whole number >= 1, got 0"),
    (True, "--size must be a whole number >= 1, got True"),
    (7, "--size 7 is more than the 6 trial sets pooled"),
])
def test_a_bad_size_is_named(tmp_path, size, match):
    run = _run(tmp_path, "a", 0, [FAST, SLOW] * 3)
    with pytest.raises(ExperimentError, match=match):
        BS.bootstrap([run], resamples=10, size=size)
