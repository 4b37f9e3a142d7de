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
