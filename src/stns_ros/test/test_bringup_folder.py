"""The bring-up's run folder: an earlier run's folder is moved aside, never deleted, and a
saved learner the new run starts from inside it is followed there."""

import json
import os

import pytest
from stns_ros.bringup import RUN_MARK, Bringup
from stns_ros.errors import StnsRosError
from stns_ros.run_config import parse_run_config

from stns_core import StnsAgent, StnsConfig


def _earlier_run(folder, mtime=1796600000):
    folder.mkdir()
    (folder / RUN_MARK).write_text("earlier run\n")
    os.utime(folder / RUN_MARK, (mtime, mtime))
    state = folder / "learner_state"
    StnsAgent(StnsConfig.preset("exp1"), obs_dim=2, n_behaviours=4).save(state)
    return state


def _kept_as(folder, mtime=1796600000):
    import time

    return folder.with_name(f"{folder.name}.{time.strftime('%Y%m%d-%H%M%S', time.localtime(mtime))}")


def test_an_earlier_run_folder_is_kept_beside_the_new_one(tmp_path, capsys):
    state = _earlier_run(tmp_path / "run")
    saved = state.read_bytes()
    cfg = parse_run_config({"run": {"steps": 10}}, "", tmp_path)
    Bringup(cfg, tmp_path / "run").prepare()
    kept = _kept_as(tmp_path / "run")
    assert (kept / "learner_state").read_bytes() == saved and (kept / RUN_MARK).exists()
    assert (tmp_path / "run" / "run_config.json").exists()
    assert not (tmp_path / "run" / "learner_state").exists()
    assert capsys.readouterr().err == (
        f"stns_bringup: the earlier run in {str(tmp_path / 'run')!r} is kept as {str(kept)!r}\n")

    _earlier_run(tmp_path / "again")  # the same start time twice: a second name, not a loss
    _kept_as(tmp_path / "again").mkdir()
    Bringup(parse_run_config({"run": {"steps": 10}}, "", tmp_path), tmp_path / "again").prepare()
    assert (tmp_path / (_kept_as(tmp_path / "again").name + "-1") / "learner_state").exists()


def test_a_learner_inside_the_earlier_run_is_followed_where_it_is_kept(tmp_path):
    state = _earlier_run(tmp_path / "run")
    saved = state.read_bytes()
    cfg = parse_run_config({"run": {"steps": 10}, "learner": {"state_in": str(state)}}, "",
                           tmp_path)
    params = Bringup(cfg, tmp_path / "run").prepare()
    moved = _kept_as(tmp_path / "run").resolve() / "learner_state"
    assert moved.read_bytes() == saved
    recorded = json.loads((tmp_path / "run" / "run_config.json").read_text())
    assert recorded["learner"]["state_in"] == str(moved)
    assert str(moved) in params.read_text()  # what the agent node is given to load


def test_an_out_that_is_not_a_run_folder_is_left_alone(tmp_path):
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("kept")
    cfg = parse_run_config({"run": {"steps": 10}}, "", tmp_path)
    with pytest.raises(StnsRosError, match=r"mine' exists and is not an stns run folder"):
        Bringup(cfg, tmp_path / "mine").prepare()
    assert os.listdir(tmp_path / "mine") == ["notes.txt"]


def test_an_out_that_cannot_be_made_is_named(tmp_path):
    (tmp_path / "afile").write_text("kept")
    cfg = parse_run_config({"run": {"steps": 10}}, "", tmp_path)
    with pytest.raises(StnsRosError, match=r"afile/run': cannot make the run folder"):
        Bringup(cfg, tmp_path / "afile" / "run").prepare()
    assert (tmp_path / "afile").read_text() == "kept"


def test_replaced_tuning_values_are_warned_of_on_stderr(tmp_path, capsys):
    import yaml

    nodes = tmp_path / "nodes.yaml"
    nodes.write_text(yaml.safe_dump({"stns_agent": {"ros__parameters": {"learner_preset": "exp3"}}}))
    cfg = parse_run_config({"run": {"steps": 10}, "nodes": str(nodes)}, "", tmp_path)
    params = yaml.safe_load(Bringup(cfg, tmp_path / "run").prepare().read_text())
    assert params["stns_agent"]["ros__parameters"]["learner_preset"] == "exp1"
    assert capsys.readouterr().err == (
        f"stns_bringup: warning: {nodes}: stns_agent.learner_preset = 'exp3' is replaced by "
        "the run's 'exp1' (set it in learner.preset)\n")


def test_a_run_without_recording_still_names_its_folder(tmp_path, capsys):
    from stns_ros.bringup import finish

    cfg = parse_run_config({"run": {"steps": 10}, "recording": {"enabled": False}}, "", tmp_path)
    assert finish(cfg, tmp_path / "run", 0, quiet=True) == 0
    out, err = capsys.readouterr()
    assert err == "stns_bringup: recording is disabled: no bag, no summary\n"
    assert out.splitlines()[0] == f"run folder: {tmp_path / 'run'}"
