"""Faults, determinism, task presets, observation shapes, reset options, close."""

import math

import numpy as np
import pytest
from rover_sim.geometry import footprint_distance, penetration_depths

from rover_sim import UNIT_M, Action, RoverSimError, RoverWorld, WorldConfig


def _heading_change(world, ticks, action=Action.FORWARD):
    before = world.pose[2]
    for _ in range(ticks):
        world.step(action)
    return (world.pose[2] - before + math.pi) % (2 * math.pi) - math.pi


def test_unit_is_a_sixteenth_of_a_metre():
    assert UNIT_M == 1 / 16


def test_healthy_rover_drives_straight_at_2_u_per_tick(make_world):
    world = make_world()
    world.reset(options={"goal": (90.0, 90.0), "pose": (20.0, 20.0, 0.3)})
    for _ in range(3):
        world.step(Action.FORWARD)
    x0, y0, _ = world.pose
    assert abs(_heading_change(world, 10)) < math.radians(0.2)
    x1, y1, th = world.pose
    assert math.hypot(x1 - x0, y1 - y0) == pytest.approx(20.0, rel=0.02)
    assert math.atan2(y1 - y0, x1 - x0) == pytest.approx(0.3, abs=0.01)


def test_left_wheel_gain_makes_forward_curve_left(make_world):
    world = make_world()
    world.reset(options={"goal": (90.0, 90.0), "pose": (20.0, 50.0, 0.0)})
    world.set_fault("left_wheel_gain", 0.85)
    assert world.faults["left_wheel_gain"] == 0.85
    turn = _heading_change(world, 10)
    # v_l = 0.85 v: w = 0.15 v / track = 0.15 * 1.25 m/s / 0.6 m = 0.3125 rad/s -> 1 s
    assert turn == pytest.approx(0.3125, rel=0.15)
    world.set_fault("left_wheel_gain", 1.0)
    world.step(Action.FORWARD)
    assert abs(_heading_change(world, 10)) < math.radians(0.2)


def test_goal_sensor_rotation_rotates_the_reading(make_world):
    world = make_world()
    obs0, _ = world.reset(options={"goal": (70.0, 60.0), "pose": (30.0, 40.0, 0.4)})
    world.set_fault("goal_sensor_rotation_deg", 15.0)
    obs1, _ = world.reset(options={"goal": (70.0, 60.0), "pose": (30.0, 40.0, 0.4)})
    assert np.linalg.norm(obs1) == pytest.approx(np.linalg.norm(obs0))
    ang = math.atan2(obs1[1], obs1[0]) - math.atan2(obs0[1], obs0[0])
    assert math.degrees(ang) == pytest.approx(15.0)
    # the true geometry: goal (40, 20) away, rover heading 0.4 rad
    dx, dy = 40.0, 20.0
    c, s = math.cos(-0.4), math.sin(-0.4)
    assert obs0 == pytest.approx([c * dx - s * dy, s * dx + c * dy])
    world.clear_faults()
    assert world.faults["goal_sensor_rotation_deg"] == 0.0


def test_sensor_noise_from_the_world_generator(make_world):
    a = make_world("exp3", seed=1, goal_sensor_noise_std=1.0, range_sensor_noise_std=2.0)
    b = make_world("exp3", seed=1, goal_sensor_noise_std=1.0, range_sensor_noise_std=2.0)
    clean = make_world("exp3", seed=1)
    opts = {"pose": (30.0, 40.0, 0.4)}
    oa, _ = a.reset(options=opts)
    ob, _ = b.reset(options=opts)
    oc, _ = clean.reset(options=opts)
    np.testing.assert_array_equal(oa, ob)
    assert np.all(oa != oc)
    assert np.all(np.abs(oa - oc) < 10.0)
    np.testing.assert_array_equal(oa[2:].astype(np.float32).astype(np.float64), oa[2:])
    clean.set_fault("range_sensor_noise_std", 0.5)
    o2, _ = clean.reset(options=opts)
    assert np.all(o2[:2] == oc[:2]) and np.any(o2[2:] != oc[2:])


def _trajectory(seed, n=400):
    world = RoverWorld("exp3", seed=seed)
    obs, _ = world.reset()
    cmds = np.random.default_rng(99).integers(0, 4, size=n // 8).repeat(8)
    out = [np.concatenate((obs, world.pose))]
    for a in cmds:
        obs, _, terminated, _, _ = world.step(int(a))
        out.append(np.concatenate((obs, world.pose)))
        if terminated:
            world.reset()
    world.close()
    return np.array(out)


def test_same_seed_same_trajectory():
    a, b, c = _trajectory(5), _trajectory(5), _trajectory(6)
    np.testing.assert_array_equal(a, b)
    assert a.shape == c.shape and not np.array_equal(a, c)


def test_reseeding_reset_repeats_the_trial(make_world):
    world = make_world()
    first = [world.reset(seed=11)[0]]
    first += [world.step(Action.FORWARD)[0] for _ in range(20)]
    second = [world.reset(seed=11)[0]]
    second += [world.step(Action.FORWARD)[0] for _ in range(20)]
    np.testing.assert_array_equal(np.array(first), np.array(second))


def test_exp1_trials_draw_goal_in_centre_and_start_outside_goal(make_world):
    world = make_world(seed=3)
    goals = []
    for _ in range(200):
        obs, info = world.reset()
        gx, gy = world.goal
        assert 14.0 <= gx <= 86.0 and 14.0 <= gy <= 86.0
        # the whole footprint is off the goal circle
        assert footprint_distance(world.pose, world.goal, 16.0, 12.0) > 5.0
        assert max(penetration_depths(world.pose, world.config)) == 0.0
        goals.append(world.goal)
    assert len(set(goals)) == 200
    # centre-only reading: the footprint may overlap the goal, the centre never
    near = make_world(seed=3, start_clear_of_goal=False)
    overlaps = 0
    for _ in range(300):
        obs, _ = near.reset()
        assert np.hypot(*obs) > 5.0
        overlaps += footprint_distance(near.pose, near.goal, 16.0, 12.0) <= 5.0
    assert overlaps > 0
    assert world.observation_dim == 2 and obs.shape == (2,) and obs.dtype == np.float64


def test_exp3_fixed_goal_and_8d_input(make_world):
    world = make_world("exp3", seed=3)
    for _ in range(20):
        obs, _ = world.reset()
        assert world.goal == (80.0, 50.0)
        assert obs.shape == (8,) and world.observation_dim == 8
        assert np.all(obs[2:] > 0.0) and np.all(obs[2:] < 142.0)
        assert max(penetration_depths(world.pose, world.config)) == 0.0


def test_reset_options_and_preset_overrides():
    cfg = WorldConfig.preset("exp1", tick_seconds=0.05, post_collision="stay")
    assert cfg.tick_seconds == 0.05 and cfg.post_collision == "stay"
    assert WorldConfig.from_dict(WorldConfig.preset("exp3").to_dict()) == WorldConfig.preset("exp3")
    with RoverWorld("exp1", seed=0) as world:
        obs, info = world.reset(options={"goal": (60.0, 50.0), "pose": (50.0, 50.0, 0.0)})
        assert world.goal == (60.0, 50.0)
        assert obs == pytest.approx([10.0, 0.0], abs=1e-6)
        with pytest.raises(RoverSimError, match="'start'"):
            world.reset(options={"start": (1, 2, 3)})
        with pytest.raises(RoverSimError, match="nan"):
            world.reset(options={"pose": (1.0, float("nan"), 0.0)})


def test_close_twice_and_use_after_close():
    world = RoverWorld("exp1", seed=0)
    world.reset()
    world.close()
    world.close()
    with pytest.raises(RoverSimError, match="closed"):
        world.step(Action.FORWARD)


@pytest.mark.parametrize("response,substeps", [("dynamic", 1), ("immediate", 4)])
def test_heading_after_a_rotation_follows_the_command_response(make_world, response, substeps):
    """A rotation's momentum carries into the next behaviour under "dynamic" (about 4.5 deg);
    "immediate" sets the new velocities at the command change, so the heading holds."""
    world = make_world(command_response=response, physics_substeps=substeps)
    world.reset(options={"goal": (90.0, 90.0), "pose": (50.0, 50.0, 0.0)})
    turned = _heading_change(world, 6, Action.CLOCKWISE)
    carried = _heading_change(world, 6, Action.FORWARD)
    if response == "immediate":
        assert turned == pytest.approx(math.radians(-30.0), abs=math.radians(0.1))
        assert abs(carried) < math.radians(0.5)
    else:
        assert turned > math.radians(-29.0)  # the turn starts with a lag
        assert carried < math.radians(-3.0)  # and runs on into the drive


def test_immediate_response_keeps_the_left_wheel_fault(make_world):
    world = make_world(command_response="immediate", physics_substeps=4)
    world.reset(options={"goal": (90.0, 90.0), "pose": (20.0, 50.0, 0.0)})
    world.set_fault("left_wheel_gain", 0.85)
    turn = _heading_change(world, 10)
    # ideal drive: w = (right - left) r / track = 0.15 * 1.25 m/s / 0.6 m = 0.3125 rad/s
    assert turn == pytest.approx(0.3125 * 1.0, rel=0.05)
