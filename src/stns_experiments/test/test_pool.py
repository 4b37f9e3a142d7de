"""Pooling the trial sets of several runs (stns_experiments.pool) on small synthetic run
folders with known answers, and on two real smoke runs."""

from __future__ import annotations

import json
import math
import shutil
import subprocess

import numpy as np
import pytest
from conftest import PARAMS
from conftest import synthetic_run as _write_run
from conftest import synthetic_set as _set
from stns_experiments.config import ExperimentError

from stns_experiments import pool as P


@pytest.fixture
def same_code(monkeypatch):
    monkeypatch.setattr(P, "library_changes", lambda commits, cwd=None: [])


def test_pooled_figures_are_those_of_the_union_of_the_sets(tmp_path, same_code):
    # seed 0: one set at 3 behaviours per arrival at the end; seed 1: two sets, 2 and 4
    a = _write_run(tmp_path / "a", 0, [_set("set00", [50, 40, 30, 30], [5, 8, 10, 10])],
                   random={"steps": 60, "arrivals": 2})
    b = _write_run(tmp_path / "b", 1, [_set("set00", [60, 40, 20, 20], [2, 10, 10, 10]),
                                       _set("set01", [40, 40, 40, 40], [4, 10, 10, 10])],
                   random={"steps": 60, "arrivals": 1})
    s = P.pool([a, b])
    assert s["trial_sets"] == 3 and s["pooled_from"]["root_seeds"] == [0, 1]
    # final window = the last 2 blocks: (60 + 40 + 80) / (20 + 20 + 20)
    assert s["final_behaviours_to_goal"] == pytest.approx(180 / 60)
    # pooled block curve: 150/11, 120/28, 90/30, 90/30 -> converged from block 2
    assert s["behaviours_to_goal_by_block"][0] == pytest.approx(150 / 11)
    assert s["convergence_step"] == 200
    # success counts add up over the three sets
    assert s["success_counts_r"] == [27, 30] and s["within_two_counts"] == [9, 12]
    # per-set final levels 3, 2, 4: mean 3, standard error 1 / sqrt(3)
    spread = s["final_behaviours_to_goal_per_set_spread"]
    assert spread["mean"] == pytest.approx(3.0)
    assert spread["standard_error"] == pytest.approx(1 / math.sqrt(3))
    # the random-policy runs of both seeds: 3 arrivals in 120 steps
    assert s["random_arrivals_per_100"] == pytest.approx(2.5)
    assert s["behaviours_to_goal_last"] == {"200": pytest.approx(3.0)}
    text = P.describe(s)
    assert "3 trial sets x 400 steps" in text and "| behaviours to goal, last 200 steps" in text


def test_json_file_is_strict_json_like_a_run_summary(tmp_path, same_code, capsys):
    """A block without any arrival has no level (NaN in memory); --json writes it as null,
    as summary.json does, so strict JSON readers open the pooled file too."""
    a = _write_run(tmp_path / "a", 0, [_set("set00", [50, 40, 30, 30], [0, 8, 10, 10])])
    out = tmp_path / "pooled.json"
    assert P.main([str(a), "--json", str(out)]) == 0

    def refuse(name):
        raise ValueError(f"not strict JSON: {name}")

    s = json.loads(out.read_text(), parse_constant=refuse)
    assert s["behaviours_to_goal_by_block"][0] is None
    assert s["behaviours_to_goal_by_block"][1] == pytest.approx(5.0)


@pytest.mark.parametrize("target", ["summary.json", "config.json", "sets/set00.json",
                                    "pooled.json"])
def test_json_is_never_written_into_a_run_folder(tmp_path, same_code, capsys, target):
    """--json a/summary.json wrote the pooled figures over run a's own summary (after which a
    could not be pooled at all); a run folder's files are its record: refused, none changed."""
    a = _write_run(tmp_path / "a", 0, [_set("set00", [50, 40, 30, 30], [5, 8, 10, 10])])
    before = {f: f.read_bytes() for f in a.rglob("*") if f.is_file()}
    assert P.main([str(a), "--json", str(a / target)]) == 2
    err = capsys.readouterr().err
    assert f"--json {str(a / target)!r} is inside the run folder {str(a)!r}" in err, err
    assert {f: f.read_bytes() for f in a.rglob("*") if f.is_file()} == before
    assert P.main([str(a), "--json", str(tmp_path / "pooled.json")]) == 0


def test_refuses_runs_with_other_settings_naming_the_setting(tmp_path, same_code):
    a = _write_run(tmp_path / "a", 0, [_set("set00", [4] * 4, [2] * 4)])
    b = _write_run(tmp_path / "b", 1, [_set("set00", [4] * 4, [2] * 4)],
                   agent_config={"seed": 0, "p_min": 0.2})
    with pytest.raises(ExperimentError, match=r"setting agent_config\.p_min is 0\.1 .* 0\.2"):
        P.pool([a, b])
    c = _write_run(tmp_path / "c", 1, [_set("set00", [2] * 8, [1] * 8)],
                   params=dict(PARAMS, block_size=50))
    with pytest.raises(ExperimentError, match="setting params.block_size is 100"):
        P.pool([a, c])


def test_an_option_given_at_its_default_is_the_same_learner(tmp_path, same_code):
    """The recorded, resolved learner and world decide, not the --set lines that gave them."""
    a = _write_run(tmp_path / "a", 0, [_set("set00", [4] * 4, [2] * 4)])
    given = dict(PARAMS, agent={"preset": "exp1", "overrides": {"p_min": 0.1}},
                 world={"preset": "exp1", "overrides": {"tick_s": 0.1}})
    b = _write_run(tmp_path / "b", 1, [_set("set00", [4] * 4, [2] * 4)], params=given)
    assert P.pool([a, b])["trial_sets"] == 2
    c = _write_run(tmp_path / "c", 2, [_set("set00", [4] * 4, [2] * 4)], params=given,
                   agent_config={"seed": 0, "p_min": 0.2})
    with pytest.raises(ExperimentError, match=r"agent_config\.p_min is 0\.1 .* 0\.2"):
        P.pool([a, c])


def test_an_option_missing_from_an_older_run_counts_as_its_default(tmp_path, same_code):
    pytest.importorskip("stns_core")
    old = _write_run(tmp_path / "old", 0, [_set("set00", [4] * 4, [2] * 4)])
    same = _write_run(tmp_path / "same", 1, [_set("set00", [4] * 4, [2] * 4)],
                      agent_config={"seed": 0, "p_min": 0.1, "nn_window": 0})
    other = _write_run(tmp_path / "other", 2, [_set("set00", [4] * 4, [2] * 4)],
                       agent_config={"seed": 0, "p_min": 0.1, "nn_window": 300})
    assert P.pool([old, same])["trial_sets"] == 2
    with pytest.raises(ExperimentError, match="agent_config.nn_window is 0 in the first and 300"):
        P.pool([old, other])


def test_refuses_a_trial_set_held_by_two_runs(tmp_path, same_code):
    a = _write_run(tmp_path / "a", 0, [_set("set00", [4] * 4, [2] * 4)])
    b = _write_run(tmp_path / "b", 0, [_set("set00", [4] * 4, [2] * 4),
                                       _set("set01", [4] * 4, [2] * 4)])
    with pytest.raises(ExperimentError, match="set00 of root seed 0 is in both"):
        P.pool([a, b])
    with pytest.raises(ExperimentError, match=r"run folder '.*a' is named twice"):
        P.pool([a, a])


def test_corrupt_or_missing_files_are_named(tmp_path, same_code):
    a = _write_run(tmp_path / "a", 0, [_set("set00", [4] * 4, [2] * 4)])
    (a / "sets" / "set00.json").write_text("{not json")
    with pytest.raises(ExperimentError, match=r"set00\.json' is not readable JSON"):
        P.pool([a])
    with pytest.raises(ExperimentError, match=r"config\.json' does not exist"):
        P.pool([tmp_path / "nowhere"])
    assert P.main([str(tmp_path / "nowhere")]) == 2
    (a / "sets" / "set00.json").write_text(json.dumps({"key": "set00", "block_arrivals": [1]}))
    with pytest.raises(ExperimentError, match="lacks block_behaviours, final_behaviours"):
        P.pool([a])
    bad = _set("set00", [4, 4, -1, 4], [2] * 4)
    (a / "sets" / "set00.json").write_text(json.dumps(bad))
    with pytest.raises(ExperimentError, match=r"block_behaviours must be a list of counts, "
                                              r"got \[4, 4, -1, 4\]"):
        P.pool([a])


@pytest.mark.parametrize(("edit", "message"), [
    (lambda s: s.update(block_behaviours=[4] * 3, block_arrivals=[2] * 3),
     r"set00\.json': it holds 3 blocks, the run's 400 steps in blocks of 100 make 4"),
    (lambda s: s.update(block_arrivals=[2] * 5),
     r"set00\.json': block_behaviours holds 4 blocks but block_arrivals 5"),
    (lambda s: s.update(success_r=[5, "x"]),
     r"set00\.json': success_r must be a pair of counts \[successes, tries\], got \[5, 'x'\]"),
    (lambda s: s.update(within_two=[7, 4]),
     r"set00\.json': within_two must be a pair of counts \[successes, tries\], got \[7, 4\]"),
    (lambda s: s.update(situations_final=-1),
     r"set00\.json': situations_final must be a count, got -1"),
    (lambda s: s.update(cpu_seconds="fast"),
     r"set00\.json': cpu_seconds must be a number >= 0, got 'fast'"),
])
def test_a_hand_edited_trial_set_result_is_named_not_a_traceback(tmp_path, same_code, edit,
                                                                 message):
    # pooling reads the sets/*.json of each run; an edited one must not end in a numpy error
    a = _write_run(tmp_path / "a", 0, [_set("set00", [4] * 4, [2] * 4)])
    assert P.pool([a])["trial_sets"] == 1
    s = json.loads((a / "sets" / "set00.json").read_text())
    edit(s)
    (a / "sets" / "set00.json").write_text(json.dumps(s))
    with pytest.raises(ExperimentError, match=message):
        P.pool([a])


@pytest.mark.parametrize(("name", "content", "held"), [
    ("summary.json", "[1, 2]", "run summary: '{}' holds a list [1, 2], not a JSON object"),
    ("config.json", "[]", "run config: '{}' holds a list [], not a JSON object"),
    ("sets/random.json", "3", "random-policy result: '{}' holds a number 3, not a JSON object"),
    ("sets/set00.json", '"x"', "trial-set result: '{}' holds a string \"x\", not a JSON object"),
])
def test_a_run_file_holding_other_json_than_an_object_is_named(tmp_path, same_code, capsys,
                                                               name, content, held):
    a = _write_run(tmp_path / "a", 0, [_set("set00", [4] * 4, [2] * 4)],
                   random={"steps": 60, "arrivals": 2})
    (a / name).write_text(content)
    assert P.main([str(a)]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err == f"error: {held.format(a / name)}\n"


@pytest.mark.parametrize(("key", "file"), [("params", "config.json"),
                                           ("agent_config", "config.json"),
                                           ("world_config", "config.json"),
                                           ("code_version", "summary.json"),
                                           ("paper", "summary.json")])
def test_a_recorded_mapping_holding_another_kind_is_named(tmp_path, same_code, key, file):
    a = _write_run(tmp_path / "a", 0, [_set("set00", [4] * 4, [2] * 4)])
    d = json.loads((a / file).read_text())
    d[key] = [1]
    (a / file).write_text(json.dumps(d))
    with pytest.raises(ExperimentError, match=rf"{file}': {key} holds a list \[1\], not a JSON"):
        P.pool([a])


def test_refuses_other_library_code_unless_asked(tmp_path, monkeypatch):
    a = _write_run(tmp_path / "a", 0, [_set("set00", [4] * 4, [2] * 4)], commit="aaaaaaa")
    b = _write_run(tmp_path / "b", 1, [_set("set00", [4] * 4, [2] * 4)], commit="bbbbbbb")
    monkeypatch.setattr(P, "library_changes",
                        lambda commits, cwd=None: ["src/stns_core/stns_core/agent.py"])
    with pytest.raises(ExperimentError, match=r"different library code .*agent\.py"):
        P.pool([a, b])
    s = P.pool([a, b], any_code=True)
    assert "POOLED ACROSS LIBRARY CHANGES" in s["pooled_from"]["code"]
    assert "pool --any-code " in P.describe(s)  # the printed command repeats the run


def test_a_resumed_run_is_checked_on_the_code_of_each_session_that_ran_sets(tmp_path,
                                                                             monkeypatch):
    """A run resumed on other library code holds sets of two codes, whatever its latest
    summary's code_version says; a session that only loaded sets (figures) is left out."""
    a = _write_run(tmp_path / "a", 0, [_set("set00", [4] * 4, [2] * 4)], commit="aaaaaaa")
    summ = json.loads((a / "summary.json").read_text())
    seen = []

    def changes(commits, cwd=None):
        seen.append(list(commits))
        return ["src/stns_core/stns_core/agent.py"] if len(set(commits)) > 1 else []

    monkeypatch.setattr(P, "library_changes", changes)
    run_sets = {"commit": "bbbbbbb", "uncommitted": []}
    summ["sessions"] = [{"code_version": {"commit": "bbbbbbb"}, "sets_run": 1},
                        {"code_version": summ["code_version"], "sets_run": 0}]
    (a / "summary.json").write_text(json.dumps(summ))
    assert "commits bbbbbbb, the same library code" in P.pool([a])["pooled_from"]["code"]
    summ["sessions"][1]["sets_run"] = 1
    summ["sessions"][0]["code_version"] = run_sets
    (a / "summary.json").write_text(json.dumps(summ))
    with pytest.raises(ExperimentError, match=r"commits bbbbbbb, aaaaaaa; changed: .*agent"):
        P.pool([a])
    assert seen[-1] == ["bbbbbbb", "aaaaaaa"]
    # a session that stopped before its summary (sets_run unknown) counts; its code unknown
    summ["sessions"][0] = {"code_version": None, "sets_run": None}
    (a / "summary.json").write_text(json.dumps(summ))
    assert P.pool([a])["pooled_from"]["code"].startswith("code: a run has no recorded commit")


def test_git_that_cannot_tell_is_not_taken_for_the_same_code(tmp_path):
    assert P.library_changes(["0000000000", "1111111111"], cwd=tmp_path) is None


def test_library_changes_between_commits_leave_out_the_report_only_modules(tmp_path):
    if shutil.which("git") is None:
        pytest.skip("git is not installed")

    def git(*args):
        out = subprocess.run(["git", "-c", "user.name=t", "-c", "user.email=t@t", *args],
                             cwd=tmp_path, capture_output=True, text=True, check=True)
        return out.stdout.strip()

    pkg = tmp_path / "src" / "stns_experiments" / "stns_experiments"
    core = tmp_path / "src" / "stns_core" / "stns_core"
    pkg.mkdir(parents=True)
    core.mkdir(parents=True)
    git("init", "-q")
    for f in (pkg / "pool.py", pkg / "experiments.py", core / "agent.py"):
        f.write_text("x = 1\n")
    git("add", "-A")
    git("commit", "-qm", "a")
    first = git("rev-parse", "HEAD")
    (pkg / "pool.py").write_text("x = 2\n")
    (tmp_path / "README.md").write_text("docs\n")
    git("add", "-A")
    git("commit", "-qm", "b")
    second = git("rev-parse", "HEAD")
    assert P.library_changes([first, second], cwd=tmp_path) == []
    (core / "agent.py").write_text("x = 3\n")
    git("add", "-A")
    git("commit", "-qm", "c")
    third = git("rev-parse", "HEAD")
    assert P.library_changes([first, second, third], cwd=tmp_path) == [
        "src/stns_core/stns_core/agent.py"]


def test_exp2_levels_of_one_seed_from_two_runs_share_their_pre_training(tmp_path, same_code):
    exp2 = dict(PARAMS, experiment="exp2-sensor", block_size=250, steps=1000,
                final_window=500, pretrain_steps=1000, fault="goal_sensor_rotation_deg",
                scratch=True)
    base = [_set("set00", [50, 20], [10, 10], final_window_blocks=1),
            _set("set01", [30, 20], [10, 10], final_window_blocks=1)]

    def level_sets(level, relearn, scratch):
        out = []
        for mode, counts in (("relearn", relearn), ("scratch", scratch)):
            for i, bs in enumerate(counts):
                out.append(_set(f"{level:g}deg-{mode}-{i:02d}", bs, [10] * 4, mode=mode,
                                level=level, eliminated_after_fault=i))
        return out

    # pre-fault level 40 / 20 = 2.0; scratch ends at 2.1 at 10 degrees, and relearning is
    # within 1.1 x 2.1 from block 2 on, scratch from block 1: delay +250 steps
    a = _write_run(tmp_path / "a", 0, level_sets(10.0, [[60, 25, 21, 21], [60, 25, 21, 21]],
                                                 [[80, 21, 21, 21], [80, 21, 21, 21]]),
                   params=exp2, base_sets=base)
    b_params = dict(exp2, **{"from": str(a / "base")})
    b = _write_run(tmp_path / "b", 0, level_sets(20.0, [[90, 21, 21, 21]] * 2,
                                                 [[90, 21, 21, 21]] * 2), params=b_params)
    s = P.pool([a, b])
    assert s["trial_sets"] == 2 and s["prefault_final_behaviours_to_goal"] == pytest.approx(2.0)
    ten, twenty = s["levels"]["10deg"], s["levels"]["20deg"]
    assert ten["relearn"]["trial_sets"] == 2 and twenty["scratch"]["trial_sets"] == 2
    assert ten["delay_steps"] == 250 and twenty["delay_steps"] == 0
    # blocks above 1.1 x 2.0: 6.0 and 2.5 at 10 degrees, 9.0 at 20 degrees
    assert ten["blocks_worse_than_prefault"] == 2 and twenty["blocks_worse_than_prefault"] == 1
    assert ten["eliminated_after_fault_mean"] == 0.5 and ten["sets_without_elimination"] == 1
    assert "| 10deg |" in P.describe(s)


def test_pooling_one_real_run_gives_its_own_summary_and_two_seeds_add_up(tmp_path):
    pytest.importorskip("rover_sim")
    pytest.importorskip("stns_core")
    from stns_experiments.cli import main
    small = ["exp1", "--steps", "200", "--trial-sets", "2", "--jobs", "1", "--quiet",
             "--no-figures", "--set", "random_steps=60"]
    runs = []
    for seed in (0, 1):
        out = tmp_path / f"seed{seed}"
        assert main(small + ["--seed", str(seed), "--out", str(out)]) == 0
        runs.append(out)
    own = json.loads((runs[0] / "summary.json").read_text())
    one = P.pool([runs[0]])
    for k in ("final_behaviours_to_goal", "convergence_step", "behaviours_to_goal_by_block",
              "success_counts_r", "success_counts_t", "within_two_counts",
              "random_arrivals_per_100"):
        np.testing.assert_equal(one[k], own[k], err_msg=k)  # NaN blocks compare equal
    both = P.pool(runs)
    second = json.loads((runs[1] / "summary.json").read_text())
    assert both["trial_sets"] == 4
    assert both["success_counts_t"] == [a + b for a, b in zip(own["success_counts_t"],
                                                               second["success_counts_t"], strict=True)]


def test_a_run_whose_result_files_were_lost_is_refused(tmp_path, same_code):
    a = _write_run(tmp_path / "a", 0, [_set("set00", [4] * 4, [2] * 4),
                                       _set("set01", [4] * 4, [2] * 4)])
    assert P.pool([a])["trial_sets"] == 2
    (a / "sets" / "set01.json").unlink()
    with pytest.raises(ExperimentError, match=r"a': its summary.json counts 2 trial sets but "
                                              r"sets/ holds 1 result files"):
        P.pool([a])


def test_runs_of_different_experiments_are_named_with_their_experiment(tmp_path, same_code):
    a = _write_run(tmp_path / "a", 0, [_set("set00", [4] * 4, [2] * 4)])
    b = _write_run(tmp_path / "b", 1, [_set("set00", [4] * 4, [2] * 4)],
                   params=dict(PARAMS, experiment="exp3"), agent_config={"seed": 0, "p_min": 0.2})
    with pytest.raises(ExperimentError, match=rf"different experiments: '{a}' is exp1, "
                                              rf"'{b}' is exp3$"):
        P.pool([a, b])
