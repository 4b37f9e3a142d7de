"""Short smoke runs of every experiment through the command line (1 trial set, jobs 1)."""

from __future__ import annotations

import json

import pytest
from stns_experiments.cli import main
from stns_experiments.run import SUMMARY_KEYS

pytest.importorskip("rover_sim")
pytest.importorskip("stns_core")

SMALL = ["--trial-sets", "1", "--jobs", "1", "--quiet", "--set", "random_steps=60"]


def _run(tmp_path, argv):
    out = tmp_path / "out"
    code = main(argv + ["--out", str(out)])
    assert code == 0
    summary = json.loads((out / "summary.json").read_text())
    missing = [k for k in SUMMARY_KEYS if k not in summary]
    assert not missing, missing
    assert summary["errors"] == {}
    return out, summary


def test_smoke_exp1(tmp_path):
    out, s = _run(tmp_path, ["exp1", "--steps", "300", "--seed", "3"] + SMALL)
    assert s["experiment"] == "exp1" and s["steps"] == 300 and s["trial_sets"] == 1
    assert len(s["behaviours_to_goal_by_block"]) == 3
    assert (out / "records" / "set00.csv.gz").exists() and (out / "states" / "set00.npz").exists()
    assert s["random_arrivals_per_100"] is not None
    assert any(f.endswith(".png") for f in s["figures"])
    assert s["behaviour_steps_per_second"] > 0


def test_first_extraction_is_the_learners_first_extracted_event(tmp_path):
    from stns_core import StnsAgent
    out, s = _run(tmp_path, ["exp1", "--steps", "700", "--seed", "1", "--no-figures"] + SMALL)
    (res,) = [json.loads((out / "sets" / "set00.json").read_text())]
    events = StnsAgent.load(out / "states" / "set00.npz").explain()["events"]
    first = min(int(e["step"]) for e in events if e["event"] == "extracted")
    assert res["first_extraction_step"] == first
    # behaviours exclude the goal arrivals among those steps, and use follows extraction
    assert 0 < res["first_extraction_behaviours"] < first
    assert res["first_situation_step"] > first
    assert s["first_extraction_behaviours_mean"] == res["first_extraction_behaviours"]


def test_smoke_exp1_same_seed_same_records(tmp_path):
    a = _run(tmp_path / "a", ["exp1", "--steps", "120", "--no-figures"] + SMALL)[0]
    b = _run(tmp_path / "b", ["exp1", "--steps", "120", "--no-figures"] + SMALL)[0]
    import gzip
    ra = gzip.open(a / "records" / "set00.csv.gz", "rt").read()
    rb = gzip.open(b / "records" / "set00.csv.gz", "rt").read()
    assert ra == rb


@pytest.mark.parametrize("exp,level", [("exp2-sensor", "20"), ("exp2-actuator", "10")])
def test_smoke_exp2(tmp_path, exp, level):
    out, s = _run(tmp_path, [exp, "--steps", "100", "--levels", level, "--no-figures",
                             "--set", "pretrain_steps=150"] + SMALL)
    (entry,) = s["levels"].values()
    assert entry["relearn"]["trial_sets"] == 1 and entry["scratch"]["trial_sets"] == 1
    assert "delay_steps" in entry and "eliminated_after_fault_mean" in entry
    # --from reuses the pre-trained learners
    out2 = tmp_path / "again"
    assert main([exp, "--steps", "100", "--levels", level, "--no-figures", "--from",
                 str(out / "base"), "--out", str(out2)] + SMALL) == 0


def test_from_refuses_states_saved_with_other_agent_settings(tmp_path, capsys):
    """The relearning learners would silently keep the saved settings while the from-scratch
    ones took the new: --from refuses, naming the setting."""
    out, _ = _run(tmp_path, ["exp2-sensor", "--steps", "50", "--levels", "20", "--no-figures",
                             "--set", "pretrain_steps=100"] + SMALL)
    argv = ["exp2-sensor", "--steps", "50", "--levels", "20", "--no-figures", "--from",
            str(out / "base"), "--out", str(tmp_path / "again")] + SMALL
    assert main(argv + ["--set", "agent.overrides.nn_window=50"]) == 2
    err = capsys.readouterr().err
    assert "set00.npz' was saved with other agent settings: nn_window=0 (state) vs 50" in err
    assert not (tmp_path / "again" / "summary.json").exists()


def test_from_refuses_states_of_another_input_size(tmp_path, capsys):
    """Learner states of 8-D inputs (an Exp. 3 learner) on the 2-D Exp. 2 world: the agent
    settings may match, the input size does not; refused before any task runs."""
    from stns_core import StnsAgent, StnsConfig
    (tmp_path / "exp3" / "states").mkdir(parents=True)
    StnsAgent(StnsConfig.preset("exp3"), obs_dim=8, n_behaviours=4).save(
        tmp_path / "exp3" / "states" / "set00.npz")
    argv = ["exp2-sensor", "--steps", "50", "--levels", "20", "--no-figures", "--from",
            str(tmp_path / "exp3"), "--set", "agent.preset=exp3",
            "--out", str(tmp_path / "again")] + SMALL
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "set00.npz' takes 8-D inputs, but world preset 'exp1' gives 2-D ones" in err
    assert not (tmp_path / "again" / "summary.json").exists()


def test_smoke_exp3(tmp_path):
    _, s = _run(tmp_path, ["exp3", "--steps", "100", "--no-figures"] + SMALL)
    assert s["experiment"] == "exp3"


def test_smoke_offline(tmp_path):
    _, s = _run(tmp_path, ["offline", "--steps", "600", "--set", "max_random_behaviours=2000"]
                + SMALL)
    assert s["online_behaviours_mean"] > 0 and s["random_behaviours_mean"] > 0


def test_smoke_grid(tmp_path):
    _, s = _run(tmp_path, ["grid", "--steps", "200"] + SMALL)
    assert set(s["learners"]) == {"polar-q", "polar-model", "orthogonal-q", "orthogonal-model"}
    assert s["stns"]["trial_sets"] == 1
    assert "grid_vs_stns.png" in " ".join(s["figures"])


def test_smoke_grid_8d(tmp_path):
    from stns_experiments.config import find_config_dir
    cfg = find_config_dir() / "grid-exp3.yaml"
    _, s = _run(tmp_path, ["grid", "--config", str(cfg), "--steps", "300", "--no-figures",
                           "--set", "compare_stns=false"] + SMALL)
    cells = {k: g["cells"] for k, g in s["learners"].items()}
    assert cells == {"polar-q": 69984, "polar-model": 69984,
                     "orthogonal-q": 321489, "orthogonal-model": 321489}
    assert s["grid_settings"]["range_edges"] == [20.0, 32.0] and s["stns"] is None
    # the range levels split the goal cells: more 8-D cells are visited than goal cells exist
    assert s["learners"]["polar-q"]["cells_visited_mean"] > 96


def test_resume_reuses_finished_trial_sets(tmp_path):
    out, s1 = _run(tmp_path, ["exp1", "--steps", "120", "--no-figures"] + SMALL)
    stamp = (out / "sets" / "set00.json").stat().st_mtime_ns
    code = main(["exp1", "--steps", "120", "--no-figures", "--resume", "--out", str(out)] + SMALL)
    assert code == 0
    s2 = json.loads((out / "summary.json").read_text())
    assert (out / "sets" / "set00.json").stat().st_mtime_ns == stamp
    assert s2["behaviours_to_goal_by_block"] == s1["behaviours_to_goal_by_block"]


def _json(path):
    return json.loads(path.read_text())


def test_resume_keeps_the_earlier_sessions_command_code_and_time(tmp_path):
    """A --resume (here: only the figures drawn) used to rewrite the summary's command, code
    version and wall time as its own, so the run's record lost the commit that made its sets.
    Every session is kept; the wall time is theirs summed."""
    out, s1 = _run(tmp_path, ["exp1", "--steps", "120", "--no-figures"] + SMALL)
    assert [x["sets_run"] for x in s1["sessions"]] == [2]  # set00 and the random policy
    assert s1["sessions"][0]["code_version"] == s1["code_version"]
    argv = ["exp1", "--steps", "120", "--resume", "--out", str(out)] + SMALL
    assert main(argv) == 0
    s2 = _json(out / "summary.json")
    first, second = s2["sessions"]
    assert first == s1["sessions"][0]
    assert (second["sets_loaded"], second["sets_run"]) == (2, 0)
    assert second["command"] == s2["command"] and "--resume" in second["command"]
    assert s2["wall_seconds"] == pytest.approx(first["wall_seconds"] + second["wall_seconds"])
    assert s2["figures"]
    assert [x["command"] for x in _json(out / "config.json")["sessions"]] == [
        first["command"], second["command"]]


def test_resume_keeps_a_session_that_stopped_and_an_older_runs_record(tmp_path):
    out, s1 = _run(tmp_path, ["exp1", "--steps", "120", "--no-figures"] + SMALL)
    # a session that was killed after writing config.json, before its summary
    cfg = _json(out / "config.json")
    killed = dict(cfg["sessions"][0], command="stns-experiment exp1 ... (killed)",
                  started_utc="2026-12-07T00:00:00Z")
    cfg["sessions"].append(killed)
    (out / "config.json").write_text(json.dumps(cfg))
    argv = ["exp1", "--steps", "120", "--no-figures", "--resume", "--out", str(out)] + SMALL
    assert main(argv) == 0
    sessions = _json(out / "summary.json")["sessions"]
    assert sessions[0] == s1["sessions"][0] and sessions[1] == killed and len(sessions) == 3
    # a run recorded before sessions were kept: one session from its command, code and time
    for name in ("config.json", "summary.json"):
        d = _json(out / name)
        d.pop("sessions")
        d["command"] = "stns-experiment exp1 (an older run)"
        (out / name).write_text(json.dumps(d))
    old = _json(out / "summary.json")
    assert main(argv) == 0
    first = _json(out / "summary.json")["sessions"][0]
    assert first["command"] == "stns-experiment exp1 (an older run)"
    assert (first["code_version"], first["wall_seconds"]) == (old["code_version"],
                                                              old["wall_seconds"])


@pytest.mark.parametrize("content, message", [
    ("{cut", "the earlier run's summary (move it away to resume"),
    ('{"sessions": 3}', "'sessions' is not a list of objects: 3"),
])
def test_resume_names_a_damaged_summary_and_changes_nothing(tmp_path, capsys, content,
                                                            message):
    out, _ = _run(tmp_path, ["exp1", "--steps", "120", "--no-figures"] + SMALL)
    (out / "summary.json").write_text(content)
    files = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    argv = ["exp1", "--steps", "120", "--no-figures", "--resume", "--out", str(out)] + SMALL
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and "summary.json" in err, err
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == files


def test_an_earlier_run_is_not_written_over(tmp_path, capsys):
    """Without --resume, or with other parameters, a run into an earlier run's folder is
    refused before anything there changes; --resume may add trial sets and figures."""
    out, _ = _run(tmp_path, ["exp1", "--steps", "120", "--no-figures"] + SMALL)
    files = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    assert main(["exp1", "--steps", "120", "--no-figures", "--out", str(out)] + SMALL) == 2
    assert "holds an earlier run" in capsys.readouterr().err
    assert main(["exp1", "--steps", "150", "--no-figures", "--resume", "--out", str(out)]
                + SMALL) == 2
    assert "steps: 120 (earlier) vs 150 (now)" in capsys.readouterr().err
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == files
    assert main(["exp1", "--steps", "120", "--resume", "--out", str(out)] + SMALL
                + ["--trial-sets", "2"]) == 0  # one set more, and the figures
    assert (out / "sets" / "set00.json").read_bytes() == files[out / "sets" / "set00.json"]
    assert (out / "sets" / "set01.json").is_file()
    assert json.loads((out / "summary.json").read_text())["trial_sets"] == 2
    # fewer sets would rewrite the summary of set00 alone beside set01's files, which pool
    # then refuses: the earlier run's summary lost
    files = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    assert main(["exp1", "--steps", "120", "--resume", "--out", str(out)] + SMALL) == 2
    assert ("--resume: the run in " in (err := capsys.readouterr().err)
            and "holds 2 trial sets; resume it with --trial-sets 2 or more" in err), err
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == files


def test_an_out_inside_an_earlier_run_is_refused(tmp_path, capsys):
    """--out runs/x/sets put a run's config.json and summary.json among run x's result files:
    x could no longer be pooled. Refused before anything changes."""
    out, _ = _run(tmp_path, ["exp1", "--steps", "20", "--no-figures"] + SMALL)
    files = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    assert main(["exp1", "--steps", "20", "--no-figures", "--out", str(out / "sets")] + SMALL) == 2
    assert (f"--out {str(out / 'sets')!r} is inside the run folder {str(out)!r}"
            in capsys.readouterr().err)
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == files
    assert sorted(p.name for p in (out / "sets").iterdir()) == ["random.json", "set00.json"]


def test_an_out_that_cannot_be_a_folder_is_named(tmp_path, capsys):
    (tmp_path / "afile").write_text("kept")
    assert main(["exp1", "--steps", "20", "--out", str(tmp_path / "afile")] + SMALL) == 2
    assert "afile' is a file, not a folder" in capsys.readouterr().err
    assert main(["exp1", "--steps", "20", "--out", str(tmp_path / "afile" / "x")] + SMALL) == 2
    assert "cannot make the folder" in capsys.readouterr().err
    assert (tmp_path / "afile").read_text() == "kept"


@pytest.mark.parametrize("content, message", [
    ("{cut", "is not readable JSON"),
    ('{"key": "set00"}', "lacks block_behaviours, block_arrivals"),
    ('{"key": "set07", "block_behaviours": [3], "block_arrivals": [1], '
     '"final_behaviours": 3, "final_arrivals": 1}', "is not the result of 'set00'"),
])
def test_resume_names_a_damaged_result_file_and_keeps_the_run(tmp_path, capsys, content,
                                                             message):
    """A damaged sets/*.json is named (not silently re-run over, not a traceback), and the
    run's summary and records stay as they were."""
    out, _ = _run(tmp_path, ["exp1", "--steps", "120", "--no-figures"] + SMALL)
    (out / "sets" / "set00.json").write_text(content)
    before = {p: p.read_bytes() for p in (out / "summary.json", out / "records" / "set00.csv.gz")}
    code = main(["exp1", "--steps", "120", "--no-figures", "--resume", "--out", str(out)] + SMALL)
    assert code == 2
    err = capsys.readouterr().err
    assert "--resume: finished trial set" in err and "set00.json" in err and message in err
    assert all(p.read_bytes() == b for p, b in before.items())


def test_from_names_a_damaged_pre_training_result(tmp_path, capsys):
    out, _ = _run(tmp_path, ["exp2-sensor", "--steps", "50", "--levels", "20", "--no-figures",
                             "--set", "pretrain_steps=100"] + SMALL)
    (out / "base" / "sets" / "set00.json").write_text('{"key": "set00", "block_arrivals": []}')
    argv = ["exp2-sensor", "--steps", "50", "--levels", "20", "--no-figures", "--from",
            str(out / "base"), "--out", str(tmp_path / "again")] + SMALL
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "--from: pre-training result of set00.npz" in err
    assert "set00.json' lacks block_behaviours, final_behaviours, final_arrivals" in err
    assert not (tmp_path / "again" / "summary.json").exists()


def test_grid_from_an_exp1_run_and_a_damaged_one(tmp_path, capsys):
    out, s1 = _run(tmp_path, ["exp1", "--steps", "120", "--no-figures"] + SMALL)
    grid = ["grid", "--steps", "100", "--no-figures", "--from", str(out)] + SMALL
    assert main(grid + ["--out", str(tmp_path / "g")]) == 0
    g = json.loads((tmp_path / "g" / "summary.json").read_text())
    assert g["stns"]["final_behaviours_to_goal"] == s1["final_behaviours_to_goal"]
    # an exp1 run is no baseline for grids on another world (the 8-D grids of exp3)
    assert main(grid + ["--set", "world.preset=exp3", "--out", str(tmp_path / "g3")]) == 2
    assert "its STNS runs are on world {'preset': 'exp1'" in capsys.readouterr().err
    assert not (tmp_path / "g3" / "summary.json").exists()
    # its block counts are per 100 steps: read as 50-step blocks the STNS curve would be wrong
    assert main(grid + ["--set", "block_size=50", "--out", str(tmp_path / "g50")]) == 2
    assert "its STNS runs count blocks of 100 steps, this grid run of 50" in capsys.readouterr().err
    assert not (tmp_path / "g50" / "summary.json").exists()
    # the grids' trial sets take their worlds from the root seed: another one compares other rooms
    assert main(grid + ["--seed", "1", "--out", str(tmp_path / "gs1")]) == 2
    assert "its STNS runs are of root seed 0, this grid run of 1" in capsys.readouterr().err
    assert not (tmp_path / "gs1" / "summary.json").exists()
    drawn = [a for a in grid if a != "--no-figures"] + ["--seed", "1", "--out", str(tmp_path / "gf")]
    assert main(drawn) == 2 and "root seed 0" in capsys.readouterr().err
    assert not (tmp_path / "gf" / "figures").exists()  # a refused run draws nothing
    (out / "sets" / "set00.json").write_text('{"key": "set00"}')
    assert main(grid + ["--out", str(tmp_path / "g2")]) == 2
    assert "STNS trial-set result: " in capsys.readouterr().err
    assert not (tmp_path / "g2" / "summary.json").exists()
