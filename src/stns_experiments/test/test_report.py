"""The Markdown report of run folders (stns_experiments.report): its tables on small
synthetic summaries with known figures, and its errors on bad run folders."""

from __future__ import annotations

import json

import pytest
from stns_experiments.config import ExperimentError

from stns_experiments import report


def _run(tmp_path, summary, name="run"):
    folder = tmp_path / name
    folder.mkdir()
    (folder / "summary.json").write_text(
        summary if isinstance(summary, str) else json.dumps(summary))
    return folder


EXP1 = {
    "experiment": "exp1", "command": "stns-experiment exp1 --seed 3", "seed": 3,
    "trial_sets": 2, "steps": 500, "wall_seconds": 12.4, "final_window": 100,
    "paper": {"convergence_step": 1200, "final_behaviours_to_goal": 2.2,
              "success_rate_r": 0.943},
    "convergence_step": 300, "final_behaviours_to_goal": 2.125,
    "success_rate_r": 0.5, "success_counts_r": [7, 14],
}

EXP2 = {
    "experiment": "exp2-sensor", "command": "c", "seed": 0, "trial_sets": 1, "steps": 500,
    "levels": {"10deg": {
        "relearn": {"final_behaviours_to_goal": 2.5, "trial_sets": 4,
                    "behaviours_to_goal_by_block": [4.0, 3.0, 2.0]},
        "scratch": {"final_behaviours_to_goal": 2.25},
        "relearn_reaches_at": 250, "scratch_reaches_at": 750, "delay_steps": -500,
        "blocks_worse_than_prefault": 2, "eliminated_after_fault_mean": 0.25,
        "sets_without_elimination": 3, "original_situations_gone_mean": 0.5,
        "situations_before_mean": 6.0}},
}


def test_exp1_table_sets_the_measured_figures_beside_the_papers(tmp_path):
    text = report.describe(_run(tmp_path, EXP1))
    assert "Command: `stns-experiment exp1 --seed 3` (seed 3, 2 trial sets x 500 steps; " \
           "wall 12 s)" in text
    assert "| convergence (block rule), steps | 1200 | 300 |" in text
    assert "| behaviours to goal, last 100 steps | 2.20 | 2.12 |" in text
    assert "| success from R situations | 94.3 % | 50.0 % (7/14) |" in text
    assert "| success from T situations | - | - |" in text  # absent figures print "-"


def test_exp2_row_per_fault(tmp_path):
    text = report.describe(_run(tmp_path, EXP2))
    assert "| 10deg | 2.50 | 2.25 | 250 | 750 | -500 | 2 of 3 | 0.2 | 3/4 | 0.5 of 6.0 |" in text


def test_main_prints_every_folder_in_order(tmp_path, capsys):
    a, b = _run(tmp_path, EXP1, "a"), _run(tmp_path, EXP2, "b")
    assert report.main([str(a), str(b)]) == 0
    out = capsys.readouterr().out
    assert out.index("### exp1: `") < out.index("### exp2-sensor: `")


@pytest.mark.parametrize("summary, message", [
    (None, "does not exist"),
    ("{bad", "is not readable JSON"),
    ("[1, 2]", "holds a list [1, 2], not a JSON object"),
    ({"experiment": "exp9"}, "its \"experiment\" is 'exp9'"),
    ({**EXP1, "final_behaviours_to_goal": "fast"}, 'final_behaviours_to_goal holds a string'),
    ({**EXP2, "levels": {"10deg": 3}}, "holds a value of the wrong kind"),
    # a success pair cut to one number: named, not an IndexError traceback
    ({**EXP1, "success_counts_r": [1]}, "holds a value of the wrong kind"),
])
def test_bad_run_folders_are_named(tmp_path, summary, message):
    folder = tmp_path / "run" if summary is None else _run(tmp_path, summary)
    with pytest.raises(ExperimentError, match="summary.json") as err:
        report.describe(folder)
    assert message in str(err.value)


@pytest.mark.parametrize("key, value, shown", [
    ("final_behaviours_to_goal", "fast", 'a string "fast"'),
    ("success_rate_r", True, "a boolean true"),  # not "100.0 %"
    ("convergence_step", [1200], "a list [1200]"),
])
def test_a_hand_edited_figure_is_named_by_its_key(tmp_path, key, value, shown):
    folder = _run(tmp_path, {**EXP1, key: value})
    with pytest.raises(ExperimentError, match="summary.json") as err:
        report.describe(folder)
    assert f"{key} holds {shown}, not a number or null" in str(err.value)


def test_main_reports_the_error_and_prints_nothing(tmp_path, capsys):
    good = _run(tmp_path, EXP1, "good")
    assert report.main([str(good), str(tmp_path / "missing")]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    assert err.startswith("error: run summary: ") and "missing" in err


def test_grid_table_rows_match_its_header_with_and_without_stns():
    learner = {"final_behaviours_to_goal": 800.0, "final_ratio_to_stns": 147.1,
               "final_ticks_per_arrival": 2000.0, "ticks_per_arrival": 2184.9,
               "ticks_per_arrival_ratio_to_stns": 35.8, "cells": 321489,
               "cells_visited_mean": 6201.0,
               "behaviours_needed_to_reach": {"20": None, "10": None}}
    stns = {"final_behaviours_to_goal": 5.43, "final_ticks_per_arrival": 55.0,
            "ticks_per_arrival": 61.1, "behaviours_needed_to_reach": {"20": 447, "10": 447}}
    for with_stns in (True, False):
        text = report.grid_table({"learners": {"orthogonal-model": learner},
                                  "stns": stns if with_stns else None})
        lines = text.splitlines()
        widths = {line.count("|") for line in lines}
        assert len(widths) == 1, lines   # every row has the header's columns
        row = next(line for line in lines if line.startswith("| orthogonal-model"))
        assert "| 147.1 |" in row and "2000.0 / 2184.9 (x35.8)" in row and "6201/321489" in row
        assert ("behaviours to reach 20" in lines[0]) is with_stns
        assert lines[2].startswith("| STNS | 5.43 |") is with_stns
