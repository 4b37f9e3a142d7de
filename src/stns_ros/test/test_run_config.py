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
    params, notes = node_parameters(cfg, tmp_path, "{}")
    assert notes == []  # config/nodes.yaml holds only tuning values
    assert params["rover_sim"]["seed"] == cfg["world"]["seed"]
    assert params["stns_agent"]["seed"] == cfg["learner"]["seed"]
    assert params["stns_agent"]["use_sim_time"] is True
    assert params["rover_sim"]["record_path"] == str(tmp_path / "bag")


BASE = {"run": {"steps": 10}, "faults": None}


@pytest.mark.parametrize("patch, match", [
    ({"run": {"steps": -5}}, r"run.steps must be an integer in \[1, 1000000000\], got -5"),
    # the agent's max_behaviour_steps refused it only once the nodes ran, in a fresh run folder
    ({"run": {"steps": 2_000_000_000}},
     r"run.steps must be an integer in \[1, 1000000000\], got 2000000000"),
    ({"run": {"mode": "fast"}}, r"run.mode must be one of lockstep, free_running, got 'fast'"),
    ({"run": {"real_time_factor": 0}}, r"run.real_time_factor must be in \[0.01, 100\], got 0"),
    ({"world": {"preset": "exp9"}}, r"world.preset must be one of exp1, exp3, got 'exp9'"),
    ({"world": {"faults": {"left_wheel_gain": 7}}}, r"world.faults.left_wheel_gain: left_wheel_gain must be in"),
    ({"world": {"overrides": {"room_size": -1}}}, r"world.overrides: .*room_size"),
    ({"learner": {"overrides": {"gamma": 2.0}}}, r"learner.overrides: .*gamma"),
    ({"learner": {"state_in": "nowhere.npz"}}, r"learner.state_in: no saved learner at"),
    # learner.seed replaced it, silently
    ({"learner": {"overrides": {"seed": 5}}},
     r"learner.overrides.seed is not used: the learner's seed is learner.seed \(by default "
     r"from run.seed\); set that instead, got 5"),
    ({"recording": {"compression": "gzip"}}, r"recording.compression must be one of zstd, lz4, none, got 'gzip'"),
    ({"recording": False}, r"recording must be a mapping, got False"),
    ({"run": {"name": "../elsewhere"}}, r"run.name must be a plain folder name .*got '../elsewhere'"),
    ({"run": {"name": ""}}, r"run.name must be a plain folder name .*got ''"),
    ({"faults": ""}, r"faults must be a scenario file, an inline scenario or null, got ''"),
    ({"nodes": ""}, r"nodes must be the path of a ROS parameter file, got ''"),
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
    with pytest.raises(StnsRosError, match=r"run.yaml: not valid YAML: expected ',' or '}', "
                                           r"but got '<stream end>' at line 2, column 1$"):
        load_run_config(p)
    nodes = tmp_path / "nodes.yaml"
    nodes.write_text("rover_sim: [\n")
    p.write_text(f"nodes: {nodes}\n")
    with pytest.raises(StnsRosError, match=r"nodes.yaml: not valid YAML: .* at line 2, column 1$"):
        load_run_config(p)
    p.write_text("run: {steps: 3}\nrun: {steps: 5}\n")  # PyYAML would keep the last
    with pytest.raises(StnsRosError, match=r"run.yaml: not valid YAML: key 'run' is given twice "
                                           r"at line 2, column 1$"):
        load_run_config(p)
    p.write_text(yaml.safe_dump({"run": {"steps": "many"}}))
    with pytest.raises(StnsRosError, match=r"run.yaml: run.steps must be an integer in .*, got 'many'"):
        load_run_config(p)


def test_a_file_that_is_not_text_is_named(tmp_path):
    """A UTF-16 or binary file as run config, scenario or tuning file: one line naming it."""
    binary = tmp_path / "bin.yaml"
    binary.write_bytes(b"\xff\xfe\x00run: {}\n")
    p = tmp_path / "run.yaml"
    with pytest.raises(StnsRosError, match=r"run config '.*bin.yaml' is not UTF-8 text: byte "
                                           r"0xff at offset 0$"):
        load_run_config(binary)
    for key, what in (("faults", "fault scenario"), ("nodes", "node parameter file")):
        p.write_text(f"{key}: {binary}\n")
        with pytest.raises(StnsRosError, match=rf"{what} '.*bin.yaml' is not UTF-8 text"):
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


def test_a_saved_learner_refuses_overrides_it_would_not_use(tmp_path):
    from stns_core import StnsAgent, StnsConfig

    saved = tmp_path / "exp1.npz"
    StnsAgent(StnsConfig.preset("exp1", seed=7), obs_dim=2, n_behaviours=4).save(saved)
    gamma = StnsConfig.preset("exp1").gamma
    same = parse_run_config({**BASE, "learner": {"state_in": str(saved), "seed": 7,
                                                 "overrides": {"gamma": gamma}}}, "", tmp_path)
    params, _ = node_parameters(same, tmp_path, "{}")
    assert params["stns_agent"]["seed"] == 7  # the saved learner's own settings go to the agent
    with pytest.raises(StnsRosError, match=r"learner.state_in .* these differ: "
                                           r"learner.overrides.gamma = 0.5 \(saved: "):
        parse_run_config({**BASE, "learner": {"state_in": str(saved),
                                              "overrides": {"gamma": 0.5}}}, "", tmp_path)
    with pytest.raises(StnsRosError, match=r"learner.seed = 8 \(saved: 7\)"):
        parse_run_config({**BASE, "learner": {"state_in": str(saved), "seed": 8}}, "", tmp_path)


def _nodes_file(tmp_path, params: dict) -> dict:
    p = tmp_path / "nodes.yaml"
    p.write_text(yaml.safe_dump({n: {"ros__parameters": v} for n, v in params.items()}))
    return {**BASE, "nodes": str(p)}


@pytest.mark.parametrize("params, match", [
    ({"rover_sim2": {"resend_period": 0.5}}, r"nodes.yaml: unknown node 'rover_sim2'"),
    ({"stns_agent": {"watchdog_timeot": 1.0}},
     r"nodes.yaml: stns_agent: unknown parameter 'watchdog_timeot'; known: .*watchdog_timeout"),
    ({"stns_agent": {"watchdog_timeout": 0}},
     r"stns_agent.watchdog_timeout must be in \[0.05, 60\], got 0.0"),
    ({"stns_agent": {"watchdog_timeout": float("nan")}},
     r"stns_agent.watchdog_timeout must be a finite number, got nan"),
    ({"stns_agent": {"explain_every": "often"}},
     r"stns_agent.explain_every must be an integer, got 'often'"),
    ({"rover_sim": {"publish_ranges": 1}}, r"rover_sim.publish_ranges must be true or false"),
    ({"rover_sim": {"record_topics": "/stns/plan"}},
     r"rover_sim.record_topics must be a list of strings"),
    ({"rover_sim": {"record_topics": ["/stns/plan", "/nope"]}},  # the simulator died of it
     r"rover_sim.record_topics: no type known for '/nope'; known: .*/stns/steps"),
])
def test_a_bad_tuning_file_is_refused_naming_node_parameter_and_value(tmp_path, params, match):
    with pytest.raises(StnsRosError, match=match):
        parse_run_config(_nodes_file(tmp_path, params), "", tmp_path)


def test_tuning_values_reach_the_nodes_and_run_values_win_with_a_note(tmp_path):
    from stns_core import StnsConfig

    data = _nodes_file(tmp_path, {"rover_sim": {"resend_period": 1, "seed": 5},
                                  "stns_agent": {"gamma": 0.5, "progress_every": 20,
                                                 "use_sim_time": True}})
    cfg = parse_run_config(data, "", tmp_path)
    params, notes = node_parameters(cfg, tmp_path, "{}")
    sim = params["rover_sim"]
    assert sim["resend_period"] == 1.0 and isinstance(sim["resend_period"], float)
    assert params["stns_agent"]["progress_every"] == 20
    assert sim["seed"] == cfg["world"]["seed"] != 5
    assert params["stns_agent"]["gamma"] == StnsConfig.preset("exp1").gamma != 0.5
    assert len(notes) == 2  # use_sim_time: true is what the run sets: no note
    assert "rover_sim.seed = 5 is replaced by the run's" in notes[0]
    assert "(set it in world.seed / run.seed)" in notes[0]
    assert "stns_agent.gamma = 0.5 is replaced" in notes[1]
    assert "(set it in learner.overrides.gamma)" in notes[1]


def test_fault_events_after_the_last_step_are_named(tmp_path):
    from stns_ros.run_config import unreached_faults

    events = [{"at_step": 3, "set": {"left_wheel_gain": 0.9}},
              {"at_step": 10, "set": {"left_wheel_gain": 0.8}},
              {"at_time": 99.0, "clear": True}]
    cfg = parse_run_config({**BASE, "faults": {"faults": events}}, "", tmp_path)
    (text,) = unreached_faults(cfg)
    assert text.startswith("faults[1] at_step 10 does not come before the end of the run "
                           "(10 behaviour steps)")
    cfg["run"]["steps"] = 11
    assert unreached_faults(cfg) == []


def test_bringup_steps_beyond_what_the_agent_takes_are_refused_before_the_run(tmp_path, capsys):
    from stns_ros.bringup import main

    p = tmp_path / "run.yaml"
    p.write_text("run: {steps: 3}\nfaults: null\n")
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as e:
        main(["--config", str(p), "--steps", "2000000000", "--out", str(out)])
    assert "--steps must be in [1, 1000000000], got 2000000000" in str(e.value.code)
    assert not out.exists()
