"""The bring-up's run folder: an earlier run's folder is replaced, but never with the saved
learner the new run starts from inside it."""

import pytest
from stns_ros.bringup import RUN_MARK, Bringup
from stns_ros.errors import StnsRosError
from stns_ros.run_config import parse_run_config

from stns_core import StnsAgent, StnsConfig


def _earlier_run(folder):
    folder.mkdir()
    (folder / RUN_MARK).write_text("earlier run\n")
    state = folder / "learner_state"
    StnsAgent(StnsConfig.preset("exp1"), obs_dim=2, n_behaviours=4).save(state)
    return state


def test_a_learner_inside_the_folder_to_replace_is_kept(tmp_path):
    state = _earlier_run(tmp_path / "run")
    saved = state.read_bytes()
    cfg = parse_run_config({"run": {"steps": 10}, "learner": {"state_in": str(state)}}, "",
                           tmp_path)
    with pytest.raises(StnsRosError, match=r"learner.state_in .*learner_state' lies inside "
                                           r"--out .*run', which this run replaces"):
        Bringup(cfg, tmp_path / "run").prepare()
    assert state.read_bytes() == saved and (tmp_path / "run" / RUN_MARK).exists()


def test_an_earlier_run_folder_is_replaced(tmp_path):
    state = _earlier_run(tmp_path / "run")
    cfg = parse_run_config({"run": {"steps": 10}, "learner": {"state_in": str(state)}}, "",
                           tmp_path)
    params = Bringup(cfg, tmp_path / "other").prepare()  # a learner from elsewhere is fine
    assert params.exists() and state.exists()
    cfg = parse_run_config({"run": {"steps": 10}}, "", tmp_path)
    Bringup(cfg, tmp_path / "run").prepare()
    assert not state.exists() and (tmp_path / "run" / "run_config.json").exists()


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
