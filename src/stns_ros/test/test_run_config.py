import copy

import pytest
import yaml
from stns_ros.errors import StnsRosError
from stns_ros.run_config import load_run_config, node_parameters, parse_run_config


def test_default_config_is_the_main_job(repo_config):
    cfg = load_run_config(repo_config / "default.yaml")
    assert cfg["world"]["preset"] == "exp1" and cfg["run"]["mode"] == "lockstep"
    assert cfg["learner"]["state_in"] == ""
    assert cfg["recording"]["enabled"]
    (event,) = cfg["faults"]["faults"]
    assert event["set"] == {"goal_sensor_rotation_deg": 15.0}
    assert 0 < event["at_step"] < cfg["run"]["steps"]


def test_node_parameters_carry_the_run(repo_config, tmp_path):
    cfg = load_run_config(repo_config / "default.yaml")
    params = node_parameters(cfg, tmp_path, "{}")
    assert params["rover_sim"]["seed"] == cfg["world"]["seed"]
    assert params["stns_agent"]["seed"] == cfg["learner"]["seed"]
    assert params["stns_agent"]["use_sim_time"] is True
    assert params["rover_sim"]["record_path"] == str(tmp_path / "bag")


BASE = {"run": {"steps": 10}, "faults": None}


@pytest.mark.parametrize("patch, match", [
    ({"run": {"steps": -5}}, r"run.steps must be an integer >= 1, got -5"),
    ({"run": {"mode": "fast"}}, r"run.mode must be one of lockstep, free_running, got 'fast'"),
    ({"run": {"real_time_factor": 0}}, r"run.real_time_factor must be in \[0.01, 100\], got 0"),
    ({"world": {"preset": "exp9"}}, r"world.preset must be one of exp1, exp3, got 'exp9'"),
    ({"world": {"faults": {"left_wheel_gain": 7}}}, r"world.faults.left_wheel_gain: left_wheel_gain must be in"),
    ({"world": {"overrides": {"room_size": -1}}}, r"world.overrides: .*room_size"),
    ({"learner": {"overrides": {"gamma": 2.0}}}, r"learner.overrides: .*gamma"),
    ({"learner": {"state_in": "nowhere.npz"}}, r"learner.state_in: no saved learner at"),
    ({"recording": {"compression": "gzip"}}, r"recording.compression must be one of zstd, lz4, none, got 'gzip'"),
    ({"recordings": {}}, r"unknown key\(s\) \['recordings'\]"),
    ({"run": {"stepz": 3}}, r"run: unknown key\(s\) \['stepz'\]"),
    ({"faults": {"faults": [{"at_step": 1, "set": {"goal_sensor_rotation_deg": 999}}]}},
     r"faults\[0\].set.goal_sensor_rotation_deg"),
])
def test_bad_values_are_refused_with_key_and_value(patch, match, tmp_path):
    data = copy.deepcopy(BASE)
    for k, v in patch.items():
        data[k] = {**data.get(k, {}), **v} if isinstance(v, dict) and isinstance(data.get(k), dict) else v
    with pytest.raises(StnsRosError, match=match):
        parse_run_config(data, "", tmp_path)


def test_bad_yaml_names_the_file(tmp_path):
    p = tmp_path / "run.yaml"
    p.write_text("run: {steps: 3\n")
    with pytest.raises(StnsRosError, match=r"run.yaml: not valid YAML"):
        load_run_config(p)
    p.write_text(yaml.safe_dump({"run": {"steps": "many"}}))
    with pytest.raises(StnsRosError, match=r"run.yaml: run.steps must be an integer >= 1, got 'many'"):
        load_run_config(p)


def test_a_saved_learner_is_read_and_its_dimension_checked_before_the_run(tmp_path):
    from stns_core import StnsAgent, StnsConfig

    two_d = tmp_path / "exp1.npz"
    StnsAgent(StnsConfig.preset("exp1"), obs_dim=2, n_behaviours=4).save(two_d)
    ok = parse_run_config({**BASE, "learner": {"state_in": str(two_d)}}, "", tmp_path)
    assert ok["learner"]["state_in"] == str(two_d)
    with pytest.raises(StnsRosError, match=r"learner.state_in: saved learner .*exp1.npz' takes "
                                           r"2-D observations .* this world gives 8-D"):
        parse_run_config({**BASE, "world": {"preset": "exp3"},
                          "learner": {"state_in": str(two_d)}}, "", tmp_path)
    cut = tmp_path / "cut.npz"
    cut.write_bytes(two_d.read_bytes()[:300])  # a copy that stopped part-way
    with pytest.raises(StnsRosError, match=r"learner.state_in: .*cut.npz: not a readable learner"):
        parse_run_config({**BASE, "learner": {"state_in": str(cut)}}, "", tmp_path)
    assert StnsAgent.load(two_d).obs_dim == 2  # the good file is untouched
