import math

import numpy as np
import pytest
from stns_ros.conversion import (
    UNIT_M,
    m_to_u,
    quaternion_yaw,
    set_stamp,
    stamp_ns,
    tick_ns,
    u_to_m,
    yaw_quaternion,
)
from stns_ros.driver import action_velocities, record_to_dict, seeds_from_run_seed
from stns_ros.errors import StnsRosError


def test_unit_matches_rover_sim():
    import rover_sim

    assert UNIT_M == rover_sim.UNIT_M == 1 / 16


def test_u_m_round_trip_is_exact():
    rng = np.random.default_rng(0)
    values = np.concatenate([rng.uniform(-200, 200, 10000), rng.normal(0, 1e-3, 1000)])
    for u in values:
        assert m_to_u(u_to_m(u)) == u
    f32 = values.astype(np.float32)
    for u in f32:
        m = np.float32(u_to_m(float(u)))  # a LaserScan range is float32
        assert m_to_u(float(m)) == float(u)


def test_stamps_are_integer_nanoseconds():
    class Stamp:
        sec = 0
        nanosec = 0

    s = Stamp()
    t = 123_456 * tick_ns(0.1)
    set_stamp(s, t)
    assert (s.sec, s.nanosec) == (12345, 600_000_000)
    assert stamp_ns(s) == t
    assert tick_ns(0.1) == 100_000_000
    with pytest.raises(StnsRosError, match="tick_seconds"):
        tick_ns(0.0)


def test_yaw_quaternion_round_trip():
    for th in np.linspace(-3.1, 3.1, 13):
        assert math.isclose(quaternion_yaw(*yaw_quaternion(th)), th, abs_tol=1e-12)


def test_action_velocities_are_the_worlds():
    from rover_sim import Action, RoverWorld

    for preset in ("exp1", "exp3"):
        with RoverWorld(preset, seed=0) as world:
            assert action_velocities(preset) == [world.action_velocity(a) for a in Action]


def test_seeds_match_the_headless_experiments():
    runner = pytest.importorskip("stns_experiments.runner")
    for seed in (0, 7, 12345):
        s = runner.set_seeds(seed, 1)[0]
        assert seeds_from_run_seed(seed) == (s["world_seed"], s["agent_seed"])


def test_step_record_to_plain_data():
    from stns_core import StepRecord

    rec = StepRecord(index=3, x=np.array([1.5, -2.0]), situation=2, kind="T", behaviour=1,
                     target=4, planned=True, reward=-1.0, next_situation=4, success=True,
                     ticks=7, arrival=False, trial=0)
    d = record_to_dict(rec)
    assert d["x"] == [1.5, -2.0] and d["behaviour"] == 1 and d["success"] is True
