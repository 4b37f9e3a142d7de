"""Bad input raises RoverSimError naming the value."""

import pytest

from rover_sim import Action, Box, RoverSimError, RoverWorld, WorldConfig


@pytest.fixture(scope="module")
def world():
    w = RoverWorld("exp1", seed=0)
    w.reset()
    yield w
    w.close()


def test_root_exception_is_value_error():
    assert issubclass(RoverSimError, ValueError)


@pytest.mark.parametrize(
    ("v", "w", "match"),
    [
        (float("nan"), 0.0, "nan"),
        (0.0, float("inf"), "inf"),
        ("fast", 0.0, "'fast'"),
        (True, 0.0, "True"),
    ],
)
def test_non_finite_commands(world, v, w, match):
    with pytest.raises(RoverSimError, match=match):
        world.step_velocity(v, w)


@pytest.mark.parametrize("action", [4, -1, "left", 2.5, None])
def test_unknown_actions(world, action):
    with pytest.raises(RoverSimError, match="unknown action"):
        world.step(action)
    with pytest.raises(RoverSimError, match="unknown action"):
        world.run_behaviour(action)


def test_actions_enum():
    assert len(Action) == 4
    assert [int(a) for a in Action] == [0, 1, 2, 3]


@pytest.mark.parametrize("name", ["exp2", "", "EXP1"])
def test_unknown_task_names(name):
    with pytest.raises(RoverSimError, match=f"unknown task '{name}'"):
        WorldConfig.preset(name)
    with pytest.raises(RoverSimError, match=f"unknown task '{name}'"):
        RoverWorld(name)


@pytest.mark.parametrize("seed", [-1, 1.5, "7", True])
def test_bad_seeds(world, seed):
    """numpy's own errors ("expected non-negative integer") named neither seed nor value."""
    with pytest.raises(RoverSimError, match=f"seed must be a non-negative integer, got {seed!r}"):
        RoverWorld("exp1", seed=seed)
    with pytest.raises(RoverSimError, match=f"seed must be a non-negative integer, got {seed!r}"):
        world.reset(seed=seed)


def test_bench_refuses_a_negative_seed(capsys):
    from rover_sim.bench import main as bench_main

    with pytest.raises(SystemExit) as e:
        bench_main(["--seed", "-1", "--ticks", "5", "--steps", "1"])
    assert e.value.code == 2
    assert "--seed must be a non-negative integer, got -1" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("field", "value", "match"),
    [
        ("room_size", -100.0, "room_size must be positive, got -100.0"),
        ("rover_length", 0.0, "rover_length must be positive, got 0.0"),
        ("goal_radius", -5, "goal_radius must be positive, got -5"),
        ("tick_seconds", float("nan"), "tick_seconds must be finite, got nan"),
        ("physics_substeps", 0, "physics_substeps must be an integer >= 1, got 0"),
        ("post_collision", "bounce", "unknown post_collision rule 'bounce'"),
        ("command_response", "instant", "unknown command_response 'instant'"),
        ("left_wheel_gain", 2.5, r"left_wheel_gain must be in \(0, 2\], got 2.5"),
        ("left_wheel_gain", 0.0, r"left_wheel_gain must be in \(0, 2\], got 0.0"),
        ("goal_sensor_noise_std", -1.0, "goal_sensor_noise_std must be >= 0, got -1.0"),
        ("goal", (150.0, 50.0), r"goal must lie inside the room, got \(150.0, 50.0\)"),
        ("goal_region", 120.0, "goal_region must fit in the room"),
        ("start_clear_of_goal", "yes", "start_clear_of_goal must be true or false, got 'yes'"),
        # YAML's true or a quoted "20" is not a length: float() would make them 1.0 and 20.0
        ("forward_speed", True, "forward_speed must be a number, got True"),
        ("rotation_speed_deg", "50", "rotation_speed_deg must be a number, got '50'"),
        ("range_sensor_noise_std", False, "range_sensor_noise_std must be a number, got False"),
        ("goal", (50.0, "50"), "goal y must be a number, got '50'"),
    ],
)
def test_bad_config_values(field, value, match):
    with pytest.raises(RoverSimError, match=match):
        WorldConfig.preset("exp1", **{field: value})


@pytest.mark.parametrize(
    ("field", "value", "match"),
    [
        ("obstacles", [[50, 50]], r"obstacles\[0\] must be \[cx, cy, sx, sy\] in u, got \[50, 50\]"),
        ("obstacles", [[50, 50, 8, 8, 1]], r"obstacles\[0\] must be \[cx, cy, sx, sy\]"),
        ("obstacles", [5], r"obstacles\[0\] must be \[cx, cy, sx, sy\] in u, got 5"),
        ("obstacles", "abc", "obstacles must be a list of boxes, got 'abc'"),
        ("obstacles", 5, "obstacles must be a list of boxes, got 5"),
        ("goal", 5, r"goal must be \(x, y\), got 5"),
        ("goal", "ab", r"goal must be \(x, y\), got 'ab'"),
    ],
)
def test_obstacles_and_goal_of_the_wrong_shape_are_named(field, value, match):
    # from YAML or JSON (world.overrides): a TypeError of Box() or tuple() named neither
    with pytest.raises(RoverSimError, match=match):
        WorldConfig.preset("exp1", **{field: value})
    with pytest.raises(RoverSimError, match=match):
        WorldConfig.from_dict({**WorldConfig.preset("exp1").to_dict(), field: value})


def test_bad_boxes_and_unknown_fields():
    with pytest.raises(RoverSimError, match="Box sizes must be positive, got sx=-1"):
        Box(10.0, 10.0, -1.0, 5.0)
    with pytest.raises(RoverSimError, match="Box.cx must be a number, got '10'"):
        Box("10", 10.0, 5.0, 5.0)
    with pytest.raises(RoverSimError, match="unknown WorldConfig field"):
        WorldConfig.preset("exp1", wheel_size=3)
    with pytest.raises(RoverSimError, match="unknown WorldConfig field"):
        WorldConfig.preset("exp1").replace(colour="red")


@pytest.mark.parametrize(
    ("name", "value", "match"),
    [
        ("left_wheel_gain", 2.01, "got 2.01"),
        ("left_wheel_gain", -0.5, "got -0.5"),
        ("left_wheel_gain", float("nan"), "got nan"),
        ("goal_sensor_rotation_deg", float("inf"), "got inf"),
        ("range_sensor_noise_std", -0.1, "got -0.1"),
        ("right_wheel_gain", 1.0, "unknown fault 'right_wheel_gain'"),
        ("left_wheel_gain", True, "left_wheel_gain must be a number, got True"),
        ("goal_sensor_rotation_deg", "15", "goal_sensor_rotation_deg must be a number, got '15'"),
    ],
)
def test_bad_faults(world, name, value, match):
    before = world.faults
    with pytest.raises(RoverSimError, match=match):
        world.set_fault(name, value)
    assert world.faults == before


def test_bad_max_ticks(world):
    with pytest.raises(RoverSimError, match="max_ticks must be an integer >= 1, got 0"):
        world.run_behaviour(Action.FORWARD, max_ticks=0)


def test_config_is_frozen():
    cfg = WorldConfig.preset("exp1")
    with pytest.raises(AttributeError):
        cfg.room_size = 50.0


def test_step_before_reset():
    with RoverWorld("exp1", seed=0) as w, pytest.raises(RoverSimError, match="reset"):
        w.step(Action.FORWARD)
