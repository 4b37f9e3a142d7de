"""The six range sectors see the wall in the right sector; the picture is a PNG."""

import math

import numpy as np
import pytest
from rover_sim.bench import main as bench_main
from rover_sim.calibrate import main as calibrate_main
from rover_sim.calibrate import random_policy_run
from rover_sim.render import render_topdown
from rover_sim.sensors import sector_bounds, sector_of_angle

from rover_sim import SECTOR_NAMES


def test_sector_layout():
    assert SECTOR_NAMES == ("front", "front-left", "rear-left", "rear", "rear-right", "front-right")
    assert sector_bounds(0) == pytest.approx((-math.pi / 6, math.pi / 6))
    assert sector_of_angle(0.0) == 0
    assert sector_of_angle(math.radians(60)) == 1
    assert sector_of_angle(math.radians(180)) == 3
    assert sector_of_angle(math.radians(-60)) == 5
    assert sector_of_angle(math.radians(-100)) == 4


@pytest.mark.parametrize("k", range(6))
def test_wall_seen_in_its_sector(make_world, k):
    world = make_world()
    # west wall 15 u away at bearing k * 60 deg in the rover frame
    heading = math.pi - math.radians(60 * k)
    world.reset(options={"goal": (80.0, 80.0), "pose": (15.0, 50.0, heading)})
    ranges = world.range_readings()
    assert int(np.argmin(ranges)) == k
    assert ranges[k] == pytest.approx(15.0, abs=1e-3)
    others = np.delete(ranges, k)
    assert np.all(others >= 15.0 / math.cos(math.radians(30)) - 1e-3)


def test_obstacle_seen_front_left_in_exp3(make_world):
    world = make_world("exp3")
    # obstacle x 51..59, y 38..62; rover at (40, 50) facing south: obstacle is to the left
    obs, _ = world.reset(options={"pose": (40.0, 50.0, -math.pi / 2)})
    ranges = obs[2:]
    assert ranges[1] == pytest.approx(11.0, abs=1e-3)  # perpendicular ray at +90 deg
    assert ranges[1] == ranges.min()
    assert ranges[4] == pytest.approx(40.0, abs=1e-3)  # west wall at -90 deg


def test_render_writes_png(make_world, tmp_path):
    world = make_world("exp3", seed=2)
    world.reset()
    out = world.run_behaviour(0, record=True)
    path = render_topdown(world, out.poses, tmp_path / "sub" / "t.png", show_sectors=True)
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 5000
    path2 = render_topdown(world.config, [(10, 10), (20, 20)], tmp_path / "c.png")
    assert path2.read_bytes()[:4] == b"\x89PNG"


def test_random_policy_run_counts_arrivals_as_steps(make_world):
    from rover_sim import WorldConfig

    r = random_policy_run(WorldConfig.preset("exp1"), seed=0, steps=300)
    assert r.steps in (300, 301) and r.arrivals > 0
    assert r.rate == pytest.approx(100.0 * r.arrivals / r.steps)
    assert r.collisions + r.over_rotations + r.arrivals >= r.steps - r.arrivals - 1


def test_command_lines_print_figures(capsys):
    assert calibrate_main(["--task", "exp1", "--seeds", "2", "--steps", "50"]) == 0
    text = capsys.readouterr().out
    assert "exp1" in text and "replace" in text and "2.04" in text
    assert bench_main(["--task", "exp3", "--ticks", "50", "--steps", "20"]) == 0
    text = capsys.readouterr().out
    assert "ticks/s" in text and "behaviour steps" in text and "steps/s" in text


@pytest.mark.parametrize("argv, message", [
    (["--seeds", "0"], "--seeds and --steps must be >= 1, got 0 and"),
    (["--max-ticks", "0"], "--max-ticks must be >= 1, got 0"),
    (["--first-seed", "-2"], "--first-seed must be in [0, 2**32 - seeds], got -2"),
    (["--set", "room_size=-1"], "room_size must be positive, got -1"),
])
def test_calibrate_names_a_bad_value(argv, message, capsys):
    with pytest.raises(SystemExit) as e:
        calibrate_main(["--task", "exp1", *argv])
    assert e.value.code == 2
    assert message in capsys.readouterr().err
