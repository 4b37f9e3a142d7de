"""The structure analysis (stns_experiments.structure) on small synthetic records with known
answers, and its errors on bad run folders."""

from __future__ import annotations

import gzip
import json

import numpy as np
import pytest
from stns_experiments.agents import Record
from stns_experiments.config import ExperimentError

from stns_experiments import records as R
from stns_experiments import structure as S


def _rec(i, kind="0", sid=0, b=0, target=None, planned=True, arrival=False, trial=1):
    return Record(index=i, x=np.zeros(2), situation=sid, kind=kind,
                  behaviour=None if arrival else b, target=target, planned=planned,
                  reward=0.0, next_situation=None if arrival else 0, success=None, ticks=3,
                  arrival=arrival, trial=trial)


def _table(specs):
    """specs: dicts of _rec's keywords, one per step."""
    return R.to_table([_rec(i + 1, **s) for i, s in enumerate(specs)])


def test_start_types_name_the_target_by_its_latest_planned_start():
    t = _table([
        dict(kind="T", sid=2, b=2, target=1),            # target 1 not seen yet
        dict(kind="R", sid=1, b=0),                       # R0 toward the goal
        dict(kind="T", sid=2, b=2, target=1),            # now T2>R0
        dict(kind="T", sid=3, b=3, target=0),            # toward the margin
        dict(kind="T", sid=2, b=2, target=1, planned=False),
        dict(kind="0", b=1, target=1),                    # planned from the margin
        dict(arrival=True),
        dict(kind="R", sid=1, b=1),                       # situation 1 recycled: R1
        dict(kind="T", sid=3, b=3, target=1),            # T3>R1
    ])
    assert S.start_types(t) == ["T2>?", "R0>G", "T2>R0", "T3>0", None, None, None,
                                "R1>G", "T3>R1"]


def _set_with_late_type():
    """Steps 1-4: R0 and T2>R0; step 5 a rare T3>? (one of 8 typed rows after step 5);
    T3>R0 first at step 7; then the final stretch uses all three main types."""
    specs = [dict(kind="R", sid=1, b=0), dict(arrival=True),
             dict(kind="T", sid=2, b=2, target=1), dict(kind="R", sid=1, b=0),
             dict(kind="T", sid=4, b=3, target=9), dict(arrival=True),
             dict(kind="T", sid=3, b=3, target=1), dict(kind="R", sid=1, b=0)]
    specs += [dict(kind="R", sid=1, b=0), dict(kind="T", sid=2, b=2, target=1),
              dict(kind="T", sid=3, b=3, target=1), dict(arrival=True)] * 3
    return _table(specs)


def test_final_structure_keeps_types_above_the_share():
    t = _set_with_late_type()
    types = S.start_types(t)
    # after step 4: T3>? once among 10 typed rows; with a 20 % share it drops out
    assert S.final_structure(t, types, 4, 0.2) == {"R0>G", "T2>R0", "T3>R0"}
    assert S.final_structure(t, types, 4, 0.05) == {"R0>G", "T2>R0", "T3>R0", "T3>?"}
    # steps after ``start`` only: the T3>? of step 5 is not after step 5
    assert S.final_structure(t, types, 5, 0.05) == {"R0>G", "T2>R0", "T3>R0"}
    assert S.final_structure(t, types, 100, 0.05) == set()


def test_structure_step_is_the_first_use_of_the_last_type():
    t = _set_with_late_type()
    res = S.analyse_set(t, final_window=12, min_share=0.2)
    assert res["final_types"] == ["R0>G", "T2>R0", "T3>R0"]
    assert res["structure_step"] == 7 and res["last_type"] == "T3>R0"
    assert res["late_r"] == "R0>G" and res["late_r_step"] == 1
    assert S.aims_at("T3>R0", "R0>G") and not S.aims_at("T3>R1", "R0>G")
    assert not S.aims_at("R0>G", "R0>G")
    # a wanted type that never occurs: no structure step
    types = S.start_types(t)
    first = S.first_uses(t, types, {"R0>G", "T2>R1"})
    assert S.structure_step(first, {"R0>G", "T2>R1"}) == (None, None)
    assert S.structure_step({}, set()) == (None, None)


def test_split_levels_pool_each_group():
    early = _table([dict(kind="R", sid=1, b=0), dict(arrival=True)] * 6)   # complete at 1
    late = _table([dict(kind="0", planned=False)] * 3 + [dict(arrival=True)]
                  + [dict(kind="0", planned=False), dict(arrival=True)] * 4)
    out = S.split_levels([early, late, early], [1, None, 5], by=4, span=8)
    # steps 5-12: early sets 4 behaviours / 4 arrivals each; the late one 4 / 4; the third
    # set is complete only at step 5, after the split
    assert out["complete"] == {"sets": 1, "behaviours_to_goal": 1.0}
    assert out["incomplete"] == {"sets": 2, "behaviours_to_goal": 1.0}
    out = S.split_levels([late], [None], by=0, span=4)
    assert out["incomplete"] == {"sets": 1, "behaviours_to_goal": 3.0}
    assert out["complete"] == {"sets": 0, "behaviours_to_goal": None}


def _run_folder(tmp_path, experiment="exp1", tables=(), final_window=12):
    folder = tmp_path / "run"
    (folder / "records").mkdir(parents=True)
    (folder / "config.json").write_text(json.dumps(
        {"params": {"experiment": experiment, "final_window": final_window}}))
    for k, t in enumerate(tables):
        R.write_csv(t, folder / "records" / f"set{k:02d}.csv.gz")
    return folder


def test_command_prints_the_analysis_of_a_run(tmp_path, capsys):
    folder = _run_folder(tmp_path, tables=[_set_with_late_type()] * 2)
    assert S.main([str(folder), "--by", "4", "--span", "8", "--min-share", "0.2"]) == 0
    out = capsys.readouterr().out
    assert "2 trial sets" in out
    assert "start types in the final structure (sets): 3: 2" in out
    assert "last type to appear: T3>R0 2" in out
    assert "the last type aims from a T-situation at the R type used last: 2 of 2" in out
    # steps 5-12 of each set: 6 behaviours, 2 arrivals; both complete only at step 7
    assert "sets complete by step 4: 0, -; the others: 2, 3.00" in out


@pytest.mark.parametrize("what, make, message", [
    ("no config", lambda p: p, "no config.json"),
    ("bad json", lambda p: (p / "config.json").write_text("{"), "not readable JSON"),
    ("exp2", lambda p: (p / "config.json").write_text(
        json.dumps({"params": {"experiment": "exp2-sensor"}})), "'exp2-sensor'"),
    ("no records", lambda p: (p / "config.json").write_text(
        json.dumps({"params": {"experiment": "exp1"}})), "no per-step records"),
])
def test_bad_run_folders_are_named(tmp_path, what, make, message):
    folder = tmp_path / what.replace(" ", "_")
    folder.mkdir()
    make(folder)
    with pytest.raises(ExperimentError, match=message):
        S.load_tables(folder)


def test_corrupt_record_file_and_bad_final_window_are_named(tmp_path, capsys):
    folder = _run_folder(tmp_path, tables=[_set_with_late_type()])
    bad = folder / "records" / "set01.csv.gz"
    bad.write_bytes(gzip.compress(b"step,index\n1\n")[:-6])
    with pytest.raises(ExperimentError, match="set01.csv.gz"):
        S.load_tables(folder)
    assert S.main([str(folder)]) == 2
    assert "set01.csv.gz" in capsys.readouterr().err
    bad.unlink()
    (folder / "config.json").write_text(json.dumps(
        {"params": {"experiment": "exp1", "final_window": 0}}))
    with pytest.raises(ExperimentError, match="final_window must be a positive integer, got 0"):
        S.load_tables(folder)


def test_bad_arguments_are_refused(tmp_path):
    folder = _run_folder(tmp_path, tables=[_set_with_late_type()])
    for args in (["--span", "0"], ["--by", "-1"], ["--min-share", "1.5"]):
        with pytest.raises(SystemExit):
            S.main([str(folder), *args])


def test_a_rare_other_behaviour_does_not_retype_a_situation():
    specs = [dict(kind="R", sid=1, b=0)] * 3 + [
        dict(kind="R", sid=1, b=1),                       # the planner drove backward once
        dict(kind="T", sid=2, b=2, target=1)]
    t = _table(specs)
    assert S.start_types(t) == ["R0>G"] * 4 + ["T2>R0"]
    # typed by the latest start only, the same rows read as a backward R-situation
    assert S.start_types(t, window=1)[3:] == ["R1>G", "T2>R1"]


def test_runs_of_two_experiments_or_one_run_twice_are_refused(tmp_path, capsys):
    """Their trial sets would be taken together: an Exp. 1 and an Exp. 3 run mixed into one
    set of quantiles, or one run's sets counted twice, as pool refuses them."""
    one = _run_folder(tmp_path / "a", tables=[_set_with_late_type()])
    three = _run_folder(tmp_path / "b", "exp3", tables=[_set_with_late_type()])
    assert S.main([str(one), str(three)]) == 2
    assert (f"cannot take runs of different experiments together: {str(one)!r} is exp1, "
            f"{str(three)!r} is exp3") in capsys.readouterr().err
    assert S.main([str(one), str(tmp_path / "a" / "." / "run")]) == 2
    assert "is named twice: its trial sets would count twice" in capsys.readouterr().err


def test_a_trial_set_whose_record_file_is_missing_is_named(tmp_path, capsys):
    # sets/set01.json says the run made set 1: analysing set 0 alone would print its figures
    # as the run's
    folder = _run_folder(tmp_path, tables=[_set_with_late_type()] * 2)
    (folder / "sets").mkdir()
    for k in range(2):
        (folder / "sets" / f"set{k:02d}.json").write_text("{}")
    assert "2 trial sets" in S.describe([folder], 4, 8, 0.2)
    (folder / "records" / "set01.csv.gz").unlink()
    assert S.main([str(folder)]) == 2
    err = capsys.readouterr().err
    assert "records/set01.csv.gz is missing" in err and "sets/set01.json" in err, err
