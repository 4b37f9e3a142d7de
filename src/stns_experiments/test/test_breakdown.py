"""The per-arrival breakdown of behaviour steps (stns_experiments.breakdown) on small
synthetic records with known answers, and its errors."""

from __future__ import annotations

import json

import numpy as np
import pytest
from stns_experiments.agents import Record
from stns_experiments.config import ExperimentError

from stns_experiments import breakdown as B
from stns_experiments import records as R


def _rec(i, kind="0", b=0, planned=True, success=None, arrival=False):
    return Record(index=i, x=np.zeros(2), situation=0 if kind == "0" else 1, kind=kind,
                  behaviour=None if arrival else b, target=None, planned=planned,
                  reward=0.0, next_situation=None if arrival else 0, success=success, ticks=3,
                  arrival=arrival, trial=1)


def _table(specs):
    return R.to_table([_rec(i + 1, **s) for i, s in enumerate(specs)])


# steps 1-6: a margin plan that missed, a random margin step, a T plan that reached its
# target, an R plan that reached the goal, the arrival, an R plan that missed;
# steps 7-9: a T plan, an R plan, the arrival
SET = _table([
    dict(kind="0", success=False), dict(kind="0", planned=False),
    dict(kind="T", b=2, success=True), dict(kind="R", success=True), dict(arrival=True),
    dict(kind="R", success=False),
    dict(kind="T", b=3, success=True), dict(kind="R", success=True), dict(arrival=True),
])


def test_counts_of_a_span_by_start_kind_and_choice():
    c = B.counts([SET], 0, 6)
    assert c["arrivals"] == 1 and c["behaviours"] == 5
    assert (c["0_planned"], c["0_missed"], c["0_unplanned"]) == (1, 1, 1)
    assert (c["R_planned"], c["R_missed"], c["R_unplanned"]) == (2, 1, 0)
    assert (c["T_planned"], c["T_missed"], c["T_unplanned"]) == (1, 0, 0)
    # pooled over two sets and per arrival: the row adds up to behaviours per arrival
    r = B.per_arrival(B.counts([SET, SET], 0, 9))
    assert r["arrivals"] == 4 and r["behaviours"] == pytest.approx(14 / 4)
    parts = sum(r[f"{k}_{w}"] for k, _ in B.KINDS for w in ("planned", "unplanned"))
    assert parts == pytest.approx(r["behaviours"])
    assert r["R_missed"] == pytest.approx(2 / 4)
    assert B.per_arrival(B.counts([SET], 5, 6))["behaviours"] is None  # no arrival


def test_spans_parsed_and_defaulted():
    assert B.parse_span("1200:1700") == (1200, 1700)
    for bad in ("1200", "a:b", "5:3", "-1:4", "1:2:3"):
        with pytest.raises(ExperimentError, match=repr(bad).replace("'", ".")):
            B.parse_span(bad)
    assert B.default_spans(10000, 1000) == [(0, 500), (500, 1000), (1000, 1500),
                                            (1500, 2000), (9000, 10000)]
    assert B.default_spans(1200, 1000) == [(0, 500), (500, 1000), (1000, 1200), (200, 1200)]
    assert B.default_spans(2000, 500) == [(0, 500), (500, 1000), (1000, 1500), (1500, 2000)]


def _run(tmp_path, experiment="exp1", files=None, steps=9, final_window=3, name="run"):
    folder = tmp_path / name
    (folder / "records").mkdir(parents=True)
    (folder / "config.json").write_text(json.dumps({"params": {
        "experiment": experiment, "steps": steps, "final_window": final_window}}))
    for f in files or ["set00.csv.gz"]:
        R.write_csv(SET, folder / "records" / f)
    return folder


def test_command_prints_the_rows_of_exp1_and_one_exp2_fault(tmp_path, capsys):
    run = _run(tmp_path, files=["set00.csv.gz", "set01.csv.gz"])
    assert B.main([str(run), "--span", "0:6", "--span", "6:9"]) == 0
    out = capsys.readouterr().out
    assert "2 trial sets" in out
    # per set, steps 1-6: 5 behaviours, 1 arrival (see SET); steps 7-9: 2 behaviours
    assert ("| 1-6 | 2 | 5.000 | 1.000 (1.000) | 1.000 | 2.000 (1.000) | 0.000 | "
            "1.000 (0.000) | 0.000 |") in out
    assert "| 7-9 | 2 | 2.000 |" in out
    exp2 = _run(tmp_path, "exp2-sensor", ["10deg-relearn-00.csv.gz", "10deg-scratch-00.csv.gz",
                                          "10deg-scratch-01.csv.gz"], name="exp2")
    assert B.main([str(exp2), "--level", "10deg", "--mode", "scratch"]) == 0
    out = capsys.readouterr().out
    assert "2 trial sets (10deg, scratch" in out
    assert "| 1-9 | 4 | 3.500 |" in out and "| 7-9 |" in out  # default spans of a short run


@pytest.mark.parametrize("args, message", [
    (["--level", "10deg"], "--level is for Exp. 2 runs"),
    (["--span", "9"], "a span is A:B in behaviour steps, got '9'"),
])
def test_bad_arguments_are_named(tmp_path, capsys, args, message):
    run = _run(tmp_path)
    assert B.main([str(run), *args]) == 2
    assert message in capsys.readouterr().err


def test_bad_run_folders_are_named(tmp_path):
    with pytest.raises(ExperimentError, match="no config.json"):
        B.load(tmp_path, None, "relearn")
    exp2 = _run(tmp_path, "exp2-actuator", ["5pct-relearn-00.csv.gz"], name="exp2")
    with pytest.raises(ExperimentError, match="name the fault with --level"):
        B.load(exp2, None, "relearn")
    with pytest.raises(ExperimentError, match=r"no per-step records records/10pct-relearn-"):
        B.load(exp2, "10pct", "relearn")
    grid = _run(tmp_path, "grid", name="grid")
    with pytest.raises(ExperimentError, match="experiment 'grid' has no per-step records"):
        B.load(grid, None, "relearn")
    bad = _run(tmp_path, steps=0, name="bad")
    with pytest.raises(ExperimentError, match="steps must be a positive integer, got 0"):
        B.load(bad, None, "relearn")
    other = _run(tmp_path, steps=12, name="other")
    run = _run(tmp_path)
    with pytest.raises(ExperimentError, match="different lengths .* give the spans"):
        B.describe([run, other], None, None, "relearn")
    (run / "records" / "set00.csv.gz").write_bytes(b"\x1f\x8b broken")
    with pytest.raises(ExperimentError, match="set00.csv.gz.*not a readable record file"):
        B.load(run, None, "relearn")


def test_runs_of_two_experiments_or_one_run_twice_are_refused(tmp_path, capsys):
    one, three = _run(tmp_path), _run(tmp_path, "exp3", name="exp3")
    assert B.main([str(one), str(three)]) == 2
    assert (f"cannot take runs of different experiments together: {str(one)!r} is exp1, "
            f"{str(three)!r} is exp3") in capsys.readouterr().err
    assert B.main([str(one), str(one)]) == 2
    assert "is named twice: its trial sets would count twice" in capsys.readouterr().err


def test_a_trial_set_whose_record_file_is_missing_is_named(tmp_path):
    exp2 = _run(tmp_path, "exp2-sensor", ["10deg-relearn-00.csv.gz"], name="exp2")
    (exp2 / "sets").mkdir()
    for key in ("10deg-relearn-00", "10deg-relearn-01", "10deg-scratch-00"):
        (exp2 / "sets" / f"{key}.json").write_text("{}")
    with pytest.raises(ExperimentError, match=r"records/10deg-relearn-01.csv.gz is missing"):
        B.load(exp2, "10deg", "relearn")
