import pytest
import yaml
from stns_ros.errors import StnsRosError
from stns_ros.faults import ScenarioClock, load_scenario, parse_scenario, ramp_points


def test_repo_scenarios_are_valid(repo_config):
    for path in sorted(repo_config.glob("faults_*.yaml")):
        scenario = load_scenario(path)
        assert scenario.faults, path


def test_round_trip_through_plain_data():
    s = parse_scenario({"name": "x", "faults": [
        {"at_step": 10, "set": {"goal_sensor_rotation_deg": 15}},
        {"at_time": 2.5, "ramp": {"left_wheel_gain": 0.9}, "duration": 1.0, "increments": 4},
        {"at_step": 20, "clear": True},
    ]})
    assert parse_scenario(s.to_dict()) == s
    assert s.faults[2].values["left_wheel_gain"] == 1.0


@pytest.mark.parametrize("entry, match", [
    ({"at_step": 1, "set": {"goal_sensor_rotation_deg": 500}},
     r"faults\[0\]\.set\.goal_sensor_rotation_deg: goal_sensor_rotation_deg must be in \[-180, 180\], got 500"),
    ({"at_step": 1, "set": {"left_wheel_gain": 0.0}}, r"left_wheel_gain must be in \(0, 2\], got 0.0"),
    ({"at_step": 1, "set": {"wheel": 1.0}}, r"unknown fault parameter 'wheel'"),
    ({"set": {"left_wheel_gain": 0.9}}, r"needs exactly one of at_step, at_time"),
    ({"at_step": 1, "at_time": 2.0, "clear": True}, r"needs exactly one of at_step, at_time"),
    ({"at_step": -1, "clear": True}, r"at_step must be an integer >= 0, got -1"),
    ({"at_step": 1, "set": {"left_wheel_gain": 0.9}, "clear": True}, r"exactly one of set, ramp, clear"),
    ({"at_step": 1, "ramp": {"left_wheel_gain": 0.9}}, r"a ramp needs duration"),
    ({"at_step": 1, "ramp": {"left_wheel_gain": 0.9}, "duration": -1}, r"duration must be > 0"),
    ({"at_step": 1, "set": {"left_wheel_gain": "fast"}}, r"must be a number, got 'fast'"),
    ({"at_step": 1, "clear": True, "typo": 1}, r"unknown key\(s\) \['typo'\]"),
    # a list of 10^9 ramp points would exhaust the injector's memory when the fault fires
    ({"at_step": 1, "ramp": {"left_wheel_gain": 0.9}, "duration": 10, "increments": 10**9},
     r"increments must be an integer in \[1, 10000\], got 1000000000"),
])
def test_bad_entries_are_refused_with_the_key(entry, match):
    with pytest.raises(StnsRosError, match=match):
        parse_scenario({"faults": [entry]})


def test_bad_yaml_file_is_refused(tmp_path):
    p = tmp_path / "bad.yaml"
    p.write_text("faults: [at_step: 1, set: {")
    with pytest.raises(StnsRosError, match="not valid YAML"):
        load_scenario(p)
    with pytest.raises(StnsRosError, match="cannot read fault scenario"):
        load_scenario(tmp_path / "missing.yaml")
    p.write_text(yaml.safe_dump({"faults": [{"at_step": 1, "set": {"left_wheel_gain": 3}}]}))
    with pytest.raises(StnsRosError, match=r"bad.yaml: faults\[0\]\.set\.left_wheel_gain"):
        load_scenario(p)


def test_clock_fires_each_event_once():
    s = parse_scenario({"faults": [{"at_step": 5, "clear": True},
                                   {"at_time": 1.0, "set": {"left_wheel_gain": 0.5}}]})
    c = ScenarioClock(s)
    assert c.due(4, 0.5) == []
    assert [e.index for e in c.due(5, 0.5)] == [0]
    assert [e.index for e in c.due(6, 1.0)] == [1]
    assert c.due(100, 100.0) == [] and c.finished


def test_ramp_points_are_linear():
    s = parse_scenario({"faults": [{"at_time": 0, "ramp": {"left_wheel_gain": 0.9},
                                    "duration": 2.0, "increments": 4}]})
    pts = ramp_points({"left_wheel_gain": 1.0}, s.faults[0], 10.0)
    assert [t for t, _ in pts] == [10.5, 11.0, 11.5, 12.0]
    assert pts[-1][1]["left_wheel_gain"] == pytest.approx(0.9)
