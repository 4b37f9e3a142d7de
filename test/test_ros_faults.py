"""The fault injector's change shows in the simulator's behaviour and in the bag."""

import itertools
import json
import math

import numpy as np
import pytest
from stns_ros.summary import load_run


def _implied_goals(run, rotation_deg, stamps):
    """Per frame of `stamps`: the goal position in the room that the goal reading implies, if
    the sensor were rotated by `rotation_deg` (u). Constant within a trial iff the guess is
    right."""
    poses = {t: (x, y, yaw) for t, x, y, yaw in run.odom}
    out = {}
    c, s = math.cos(math.radians(-rotation_deg)), math.sin(math.radians(-rotation_deg))
    for t in stamps:
        f = run.frames[t]
        gx, gy = (v / 0.0625 for v in f["goal"])
        rx, ry = c * gx - s * gy, s * gx + c * gy  # undo the sensor rotation
        x, y, yaw = poses[t]
        out[t] = (x + math.cos(yaw) * rx - math.sin(yaw) * ry,
                  y + math.sin(yaw) * rx + math.cos(yaw) * ry, f["reward"][2])
    return out


def _consistent(goals, ts):
    pairs = [(a, b) for a, b in itertools.pairwise(ts) if goals[a][2] == goals[b][2]]  # same trial
    dev = [math.dist(goals[a][:2], goals[b][:2]) for a, b in pairs]
    return max(dev) < 1e-6 if dev else None, len(pairs)


def test_rotation_fault_is_applied_seen_and_recorded(fault_run):
    run = load_run(fault_run / "bag")
    (event,) = run.faults
    assert event["applied"] and event["values"] == {"goal_sensor_rotation_deg": 90.0}
    assert event["step"] >= 60
    summary = json.loads((fault_run / "summary.json").read_text())
    assert summary["faults"] == run.faults
    assert summary["topic_counts"]["/parameter_events"] >= 1  # the simulator's own report

    # The trigger: behaviour step 60 finished at this frame; the injector reports after.
    t_trigger = next(r["stamp_ns"] for r in run.steps if r["index"] == 59)
    t_event = event["stamp_ns"]
    frames = sorted(run.frames)
    # The recorder stops at shutdown, possibly between the messages of the last frame.
    incomplete = [t for t in frames if {"goal", "reward"} - set(run.frames[t])]
    assert incomplete in ([], frames[-1:])
    frames = [t for t in frames if t not in incomplete]
    before = [t for t in frames if t <= t_trigger]
    after = [t for t in frames if t > t_event]
    healthy, rotated = _implied_goals(run, 0.0, frames), _implied_goals(run, 90.0, frames)
    ok, n = _consistent(healthy, before)
    assert ok and n > 100  # before: the reading points at a fixed goal
    ok, n = _consistent(rotated, after)
    assert ok and n > 100  # after: it does so only when turned back by 90 degrees
    bad, _ = _consistent(healthy, after)
    assert bad is False
    assert np.isfinite(t_event)


def test_free_running_run_with_a_timed_wheel_ramp(tmp_path):
    """Free-running at 20x real time; a ramp triggered by sim time reaches the simulator."""
    from conftest import bringup, run_config

    cfg = run_config(tmp_path, run={"name": "free", "seed": 4, "steps": 40,
                                    "mode": "free_running", "real_time_factor": 20.0},
                     faults={"name": "ramp", "faults": [
                         {"at_time": 5.0, "ramp": {"left_wheel_gain": 0.8}, "duration": 2.0,
                          "increments": 4}]})
    res = bringup(cfg, tmp_path / "run")
    assert res.returncode == 0, res.stdout + res.stderr
    run = load_run(tmp_path / "run" / "bag")
    gains = [ev["values"]["left_wheel_gain"] for ev in run.faults if ev["applied"]]
    assert gains == [0.95, 0.9, 0.85, 0.8] or gains == pytest.approx([0.95, 0.9, 0.85, 0.8])
    assert all(ev["stamp_ns"] >= 5.0e9 for ev in run.faults)
    assert run.counts["/parameter_events"] >= 4
    assert len(run.steps) == 40
