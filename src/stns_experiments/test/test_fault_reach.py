"""The fault-reach analysis (stns_experiments.fault_reach): drives replayed in rover_sim's
pybullet world with known answers from the geometry, and its errors."""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest
from rover_sim.sensors import goal_sensor
from stns_experiments.agents import Record
from stns_experiments.config import ExperimentError

import rover_sim
from stns_experiments import fault_reach as F
from stns_experiments import records as R


@pytest.fixture(scope="module")
def world():
    with rover_sim.RoverWorld("exp1", seed=0) as w:
        yield w


@pytest.mark.parametrize("x", [(40.0, 0.0), (-20.0, 3.0), (5.0, -60.0), (-70.0, -30.0)])
@pytest.mark.parametrize("rotation", [0.0, 10.0, -25.0, 180.0])
def test_the_placed_rover_reads_the_recorded_input_through_the_faulty_sensor(x, rotation):
    pose = F.placement(np.array(x), rotation)
    assert goal_sensor(pose, F.GOAL_AT, rotation) == pytest.approx(x, abs=1e-9)
    # the rover stands in the room with its footprint clear of the walls
    assert 10.0 < pose[0] < 90.0 and 10.0 < pose[1] < 90.0


@pytest.mark.parametrize("x, behaviour, fault, arrives", [
    ((10.0, 0.0), 0, F.Fault(), True),
    ((-20.0, 0.0), 1, F.Fault(), True),
    ((60.0, 3.0), 0, F.Fault(), True),
    # a 10-degree error passes a goal read dead ahead at d sin(10 deg): 3.5 u at 20, 6.9 at 40
    ((20.0, 0.0), 0, F.Fault(rotation_deg=10.0), True),
    ((40.0, 0.0), 0, F.Fault(rotation_deg=10.0), False),
    ((-40.0, 0.0), 1, F.Fault(rotation_deg=-10.0), False),
    # read 10 degrees left of dead ahead through a 10-degree rotation, the goal is dead ahead
    ((40.0 * math.cos(math.radians(10)), 40.0 * math.sin(math.radians(10))), 0,
     F.Fault(rotation_deg=10.0), True),
    # 5 % slower left wheel: an arc of radius about 187 u, 2.4 u off after 30 u, 17 u after 80
    ((30.0, 0.0), 0, F.Fault(left_wheel_gain=0.95), True),
    ((80.0, 0.0), 0, F.Fault(left_wheel_gain=0.95), False),
    # a turn never moves the rover's centre onto the goal
    ((10.0, 0.0), 2, F.Fault(), False),
])
def test_replayed_drives_arrive_as_the_geometry_says(world, x, behaviour, fault, arrives):
    assert F.replay(world, np.array(x), behaviour, fault) is arrives


def _drive(i, b, x, trial=1):
    return Record(index=i, x=np.array(x), situation=1, kind="R", behaviour=b, target=None,
                  planned=True, reward=0.0, next_situation=0, success=None, ticks=3,
                  arrival=False, trial=trial)


def _arrival(i, trial=1):
    return Record(index=i, x=np.zeros(2), situation=-1, kind="0", behaviour=None, target=None,
                  planned=False, reward=0.0, next_situation=None, success=None, ticks=0,
                  arrival=True, trial=trial)


def _set_table():
    """Steps 1-8: a drive that arrives (too early for a 6-step window), a turn, a backward drive
    that arrives, a forward drive that does not, a turn that ends a trial's last step, a
    forward drive that arrives."""
    recs = [_drive(1, 0, (30.0, 0.0)), _arrival(2), _drive(3, 2, (5.0, 5.0), 2),
            _drive(4, 1, (-40.0, 2.0), 2), _arrival(5, 2), _drive(6, 0, (70.0, 0.0), 3),
            _drive(7, 0, (20.0, 1.0), 3), _arrival(8, 3)]
    return R.to_table(recs)


def test_drive_arrivals_are_the_drives_followed_by_an_arrival_in_the_window():
    x, b = F.drive_arrivals(_set_table(), window=6)
    assert b.tolist() == [1, 0]
    assert x.tolist() == [[-40.0, 2.0], [20.0, 1.0]]
    x, b = F.drive_arrivals(_set_table(), window=8)
    assert b.tolist() == [0, 1, 0]


def _run_folder(tmp_path, tables, experiment="exp1"):
    folder = tmp_path / "run"
    (folder / "records").mkdir(parents=True)
    (folder / "config.json").write_text(json.dumps({"params": {
        "experiment": experiment, "final_window": 6,
        "world": {"preset": "exp1", "overrides": {}}}}))
    for k, t in enumerate(tables):
        R.write_csv(t, folder / "records" / f"set{k:02d}.csv.gz")
    return folder


def test_command_prints_the_share_each_fault_keeps(tmp_path, capsys):
    folder = _run_folder(tmp_path, [_set_table()] * 2)
    assert F.main([str(folder), "--rotations", "10", "--wheel-slower", "5"]) == 0
    out = capsys.readouterr().out
    assert "4 drive arrivals in the last final_window steps" in out
    assert "no fault: 4 of 4 arrive (100.0 %)" in out
    # (-40, 2) lies beyond 28.8 u and misses at 10 degrees; (20, 1) is near enough
    assert "sensor 10 deg: 2 of 4 arrive (50.0 %); 50.0 % start beyond r / sin(theta) = 28.8 u" \
        in out
    assert "left wheel 5 % slower: 4 of 4 arrive (100.0 %)" in out


def test_bad_faults_runs_and_arguments_are_named(tmp_path, capsys):
    for rot, message in ((0.0, "0.0"), (math.nan, "nan"), (200.0, "200.0")):
        with pytest.raises(ExperimentError, match=f"--rotations: {message}"):
            F.parse_faults([rot], [])
    for p in (0.0, 100.0, -5.0):
        with pytest.raises(ExperimentError, match=f"--wheel-slower: {p!r}"):
            F.parse_faults([], [p])
    folder = _run_folder(tmp_path, [_set_table()], experiment="exp3")
    assert F.main([str(folder)]) == 2
    assert "'exp3' has no fault-reach analysis" in capsys.readouterr().err
    for args in (["--window", "-1"], ["--sample", "0"], ["--seed", "-2"]):
        with pytest.raises(SystemExit):
            F.main([str(folder), *args])


def test_an_exp2_run_is_read_from_its_pre_training_and_counted_once(tmp_path, capsys):
    base = _run_folder(tmp_path, [_set_table()]) / "base"
    base.mkdir()
    (tmp_path / "run" / "records").rename(base / "records")
    cfg = json.loads((tmp_path / "run" / "config.json").read_text())
    cfg["params"]["experiment"] = "exp2-sensor"
    (tmp_path / "run" / "config.json").write_text(json.dumps(cfg))
    assert F.main([str(tmp_path / "run"), "--rotations", "10", "--wheel-slower"]) == 0
    out = capsys.readouterr().out
    assert "2 drive arrivals" in out and "sensor 10 deg: 1 of 2 arrive (50.0 %)" in out
    # a second run relearning from the same pre-training (--from) would count it twice
    other = tmp_path / "other"
    other.mkdir()
    cfg["params"]["from"] = str(base)
    (other / "config.json").write_text(json.dumps(cfg))
    assert F.main([str(tmp_path / "run"), str(other)]) == 2
    assert "share the pre-training" in capsys.readouterr().err


@pytest.mark.parametrize("world, message", [
    (None, "params.world must be a mapping with a preset name and overrides, got None"),
    ({"preset": "exp3", "overrides": {}}, "obstacle"),
    ({"preset": "exp1", "overrides": {"goal_sensor_noise_std": 0.5}}, "noise \\(std 0.5\\)"),
    ({"preset": "exp1", "overrides": {"room_size": 20.0, "goal_region": 10.0,
                                      "rover_length": 8.0, "rover_width": 6.0}},
     "room \\(20.0 u\\) is too small"),
])
def test_a_world_the_replay_cannot_reproduce_is_refused(tmp_path, capsys, world, message):
    folder = _run_folder(tmp_path, [_set_table()])
    cfg = json.loads((folder / "config.json").read_text())
    cfg["params"]["world"] = world
    (folder / "config.json").write_text(json.dumps(cfg))
    assert F.main([str(folder)]) == 2
    assert re.search(message, capsys.readouterr().err)


def test_drives_too_long_for_the_room_are_left_out_and_counted(tmp_path, capsys):
    folder = _run_folder(tmp_path, [_set_table()])
    cfg = json.loads((folder / "config.json").read_text())
    # drives of up to 35.4 u: (-40, 2) is left out
    cfg["params"]["world"]["overrides"].update(room_size=50.0, goal_region=30.0)
    (folder / "config.json").write_text(json.dumps(cfg))
    assert F.main([str(folder), "--rotations", "--wheel-slower"]) == 0
    out = capsys.readouterr().out
    assert "replayed: 1 (1 starting beyond 35.4 u left out)" in out
    assert "no fault: 1 of 1 arrive (100.0 %)" in out
