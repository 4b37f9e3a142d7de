"""Events and rewards: goal, collision (and the post-collision rules), over-rotation,
rotation next to a wall."""

import math

import numpy as np
import pytest
from rover_sim.geometry import penetration_depths

from rover_sim import Action, RoverSimError


def test_goal_arrival_gives_10_and_terminates(make_world):
    world = make_world()
    world.reset(options={"goal": (50.0, 50.0), "pose": (30.0, 50.0, 0.0)})
    for _i in range(30):
        obs, reward, terminated, truncated, info = world.step(Action.FORWARD)
        x, y, _ = info["pose"]
        dist = math.hypot(x - 50.0, y - 50.0)
        if terminated:
            break
        assert reward == 0.0 and info["events"] == []
        assert dist > 5.0
    assert terminated and not truncated
    assert reward == 10.0 and info["events"] == ["goal"]
    assert dist <= 5.0 and _i >= 6  # 15 u at 2 u/tick
    assert math.hypot(*obs) <= 5.0
    with pytest.raises(RoverSimError, match="reset"):
        world.step(Action.FORWARD)
    _, info = world.reset()
    assert info["trial"] == 1


def test_wall_collision_stay_stops_rover_and_penalises_each_push(make_world):
    world = make_world(post_collision="stay")
    world.reset(options={"goal": (80.0, 80.0), "pose": (20.0, 50.0, math.pi)})
    rewards, xs = [], []
    for _ in range(12):
        _, reward, _, _, info = world.step(Action.FORWARD)
        rewards.append(reward)
        xs.append(info["pose"][0])
    first = rewards.index(-1.0)
    assert all(r == 0.0 for r in rewards[:first])
    assert all(r == -1.0 for r in rewards[first:])  # every tick pushing into the wall
    assert min(xs) >= 8.0  # the footprint (half-length 8) never entered the wall
    assert xs[-1] == pytest.approx(xs[first])
    _, reward, _, _, info = world.step(Action.BACKWARD)
    assert reward == 0.0 and info["events"] == []
    assert info["pose"][0] > xs[-1]


def test_collision_replace_puts_rover_at_free_random_pose(make_world):
    world = make_world(post_collision="replace")
    world.reset(options={"goal": (80.0, 80.0), "pose": (12.0, 50.0, math.pi)})
    out = world.run_behaviour(Action.FORWARD)
    assert out.stopped_by == "reward" and out.reward == -1.0
    assert out.events == ("collision",) and out.ticks <= 3
    x, y, _ = world.pose
    assert (x, y) != pytest.approx((12.0, 50.0), abs=3.0)
    assert max(penetration_depths(world.pose, world.config)) == 0.0


def test_collision_back_off_moves_rover_back(make_world):
    world = make_world(post_collision="back_off", back_off_distance=4.0)
    world.reset(options={"goal": (80.0, 80.0), "pose": (9.0, 50.0, math.pi)})
    _, reward, _, _, info = world.step(Action.FORWARD)
    assert reward == -1.0 and info["events"] == ["collision"]
    assert info["pose"][0] == pytest.approx(13.0, abs=0.05)


def test_collision_undo_returns_to_where_the_motion_began(make_world):
    world = make_world(post_collision="undo")
    world.reset(options={"goal": (80.0, 80.0), "pose": (30.0, 50.0, math.pi)})
    world.run_behaviour(Action.CLOCKWISE, max_ticks=2)  # another motion first
    start = world.pose
    out = world.run_behaviour(Action.FORWARD)
    assert out.events == ("collision",) and out.ticks >= 5
    assert world.pose == pytest.approx(start, abs=1e-9)
    # a collision ends the segment: the next forward motion starts a new one from here
    out = world.run_behaviour(Action.FORWARD)
    assert out.events == ("collision",)
    assert world.pose == pytest.approx(start, abs=1e-9)


def test_obstacle_collision_is_minus_one(make_world):
    world = make_world("exp3", post_collision="stay")
    # obstacle spans x 51..59, y 38..62; drive east into it
    world.reset(options={"pose": (20.0, 50.0, 0.0)})
    out = world.run_behaviour(Action.FORWARD)
    assert out.events == ("collision",) and out.reward == -1.0 and out.ticks > 10
    assert 49.0 <= world.pose[0] + 8.0 <= 51.0 + 1e-6


def test_over_rotation_after_90_degrees(make_world):
    world = make_world()
    world.reset(options={"goal": (80.0, 80.0), "pose": (50.0, 50.0, 0.0)})
    turned = 0.0
    for action, sign in ((Action.COUNTER_CLOCKWISE, 1.0), (Action.CLOCKWISE, -1.0)):
        before = world.pose[2]
        for tick in range(1, 40):  # noqa: B007 - used after the loop
            _, reward, _, _, info = world.step(action)
            turned = sign * (info["pose"][2] - before)
            turned = (turned + math.pi) % (2 * math.pi) - math.pi
            if reward:
                break
            assert math.degrees(turned) <= 90.0 + 1e-9
        assert info["events"] == ["over_rotation"] and reward == -1.0
        assert 90.0 < math.degrees(turned) < 96.0
        assert 18 <= tick <= 20  # 5 degrees per tick
        world.step_velocity(0.0, 0.0)


def test_direction_change_resets_rotation_accumulator(make_world):
    world = make_world()
    world.reset(options={"goal": (80.0, 80.0), "pose": (50.0, 50.0, 0.0)})
    for action in (
        [Action.COUNTER_CLOCKWISE] * 15 + [Action.CLOCKWISE] * 15 + [Action.COUNTER_CLOCKWISE] * 15
    ):
        _, reward, _, _, _ = world.step(action)
        assert reward == 0.0
    # the same direction goes on accumulating: 75 degrees so far, the penalty comes soon
    out = world.run_behaviour(Action.COUNTER_CLOCKWISE)
    assert out.events == ("over_rotation",) and 3 <= out.ticks <= 5
    # the penalty restarts the accumulator: the next rotation gets a full 90 degrees
    out = world.run_behaviour(Action.COUNTER_CLOCKWISE)
    assert out.events == ("over_rotation",) and 18 <= out.ticks <= 19
    # so does a stop
    world.run_behaviour(Action.COUNTER_CLOCKWISE, max_ticks=10)
    world.step_velocity(0.0, 0.0)
    out = world.run_behaviour(Action.COUNTER_CLOCKWISE)
    assert out.events == ("over_rotation",) and 18 <= out.ticks <= 19


def test_rotation_next_to_wall_is_not_stopped(make_world):
    world = make_world(post_collision="stay")
    # long axis along y, 1 u from the west wall: any rotation sweeps a corner into it
    world.reset(options={"goal": (80.0, 80.0), "pose": (7.0, 50.0, math.pi / 2)})
    out = world.run_behaviour(Action.COUNTER_CLOCKWISE, record=True)
    assert out.events == ("over_rotation",)
    assert "collision" not in out.events
    x, y, th = world.pose
    assert math.degrees(th) == pytest.approx(180.0 + 5.0 * (out.ticks - 18), abs=6.0) or (
        math.degrees(th) < -170.0
    )
    assert (x, y) == pytest.approx((7.0, 50.0), abs=0.2)
    assert penetration_depths(world.pose, world.config)[0] > 0.0  # overlaps the west wall
    # facing west now: moving out of the overlap is free, moving back into it collides
    _, reward, _, _, info = world.step(Action.BACKWARD)
    assert reward == 0.0 and info["pose"][0] > 7.5
    x_out = info["pose"][0]
    _, reward, _, _, info = world.step(Action.FORWARD)
    assert reward == -1.0 and info["events"] == ["collision"]
    assert info["pose"][0] == pytest.approx(x_out)  # "stay": the wall stopped it


def test_run_behaviour_stop_predicate_and_max_ticks(make_world):
    world = make_world()
    world.reset(options={"goal": (80.0, 80.0), "pose": (50.0, 50.0, 0.0)})
    out = world.run_behaviour(Action.CLOCKWISE, stop=lambda obs: True)
    assert out.stopped_by == "stop" and out.ticks == 1 and out.reward == 0.0
    out = world.run_behaviour(Action.CLOCKWISE, max_ticks=3, record=True)
    assert out.stopped_by == "max_ticks" and out.ticks == 3 and len(out.poses) == 3
    out = world.run_behaviour(Action.CLOCKWISE)
    assert out.stopped_by == "reward" and out.events == ("over_rotation",)
    assert out.ticks == pytest.approx(15, abs=2)  # 90 degrees minus the 4 ticks above


def test_step_is_step_velocity_of_action_velocity(make_world):
    a = make_world(seed=4)
    b = make_world(seed=4)
    a.reset()
    b.reset()
    for action in [0, 0, 2, 2, 3, 1, 1, 0]:
        ra = a.step(action)
        rb = b.step_velocity(*b.action_velocity(action))
        np.testing.assert_array_equal(ra[0], rb[0])
        assert ra[1:4] == rb[1:4] and ra[4]["pose"] == rb[4]["pose"]
    v, w = a.action_velocity(Action.CLOCKWISE)
    assert v == 0.0 and w == pytest.approx(-math.radians(50.0))
    assert a.action_velocity(Action.FORWARD) == (20.0, 0.0)


def test_tick_and_sim_time_and_info(make_world):
    world = make_world(tick_seconds=0.05)
    obs, info = world.reset()
    assert set(info) >= {"events", "pose", "trial", "tick", "sim_time"}
    assert info["tick"] == 0 and info["trial"] == 0
    for _ in range(4):
        _, _, _, _, info = world.step(Action.CLOCKWISE)
    assert world.tick == 4 and info["tick"] == 4
    assert world.sim_time == pytest.approx(0.2)
    assert info["sim_time"] == pytest.approx(0.2)
    # a 0.05 s tick rotates half as far per tick
    assert world.action_velocity(Action.CLOCKWISE)[1] * 0.05 == pytest.approx(-math.radians(2.5))
