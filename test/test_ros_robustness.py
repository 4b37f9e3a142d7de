"""Stopping a run in the middle, a killed recorder, and bad input refused with clear messages."""

import os
import signal
import subprocess
import time
from pathlib import Path

import pytest
import yaml
from conftest import DOMAIN, command, run_config
from stns_ros.bag import decode, read_messages

from stns_ros import topics as T


def _start(config: Path, out: Path) -> subprocess.Popen:
    env = dict(os.environ, ROS_DOMAIN_ID=str(DOMAIN))
    return subprocess.Popen(
        command("stns_bringup", "stns_ros.bringup") + ["--config", str(config), "--out", str(out),
                                                       "--quiet"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)


def _wait_for_bag(out: Path, proc: subprocess.Popen, size: int = 150_000) -> None:
    mcap = out / "bag" / "bag.mcap"
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        assert proc.poll() is None, proc.communicate()
        if mcap.exists() and mcap.stat().st_size > size:
            return
        time.sleep(0.2)
    proc.kill()
    pytest.fail("the run recorded nothing in 120 s")


def _children(marker: str, module: str) -> list[int]:
    pids = []
    for p in Path("/proc").iterdir():
        if p.name.isdigit():
            try:
                cmd = (p / "cmdline").read_bytes().replace(b"\0", b" ").decode()
            except OSError:
                continue
            if marker in cmd and module in cmd:
                pids.append(int(p.name))
    return pids


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_stop_in_the_middle_leaves_a_closed_readable_bag(tmp_path, sig):
    out = tmp_path / "run"
    proc = _start(run_config(tmp_path, run={"name": "t", "seed": 5, "steps": 10**6}), out)
    _wait_for_bag(out, proc)
    proc.send_signal(sig)
    stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130, stdout + stderr
    assert (out / "bag" / "metadata.yaml").exists()
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    from rosbags.highlevel import AnyReader

    with AnyReader([out / "bag"]) as reader:
        n = sum(1 for _ in reader.messages())
    assert n > 1000
    with open(out / "bag" / "bag.mcap", "rb") as f:
        decoded = make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages()
        assert sum(1 for _ in decoded) == n
    assert (out / "summary.json").exists() and "behaviour steps" in stdout


def test_a_killed_recorder_leaves_a_readable_prefix(tmp_path):
    out = tmp_path / "run"
    proc = _start(run_config(tmp_path, run={"name": "t", "seed": 6, "steps": 10**6}), out)
    _wait_for_bag(out, proc)
    (pid,) = _children(str(out / "params.yaml"), "stns_ros.sim_node")
    os.kill(pid, signal.SIGKILL)
    stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 1 and "rover_sim stopped early" in stderr, stdout + stderr
    # the bring-up rewrote the readable prefix as a complete bag
    assert "the bag was cut short; recovered" in stderr
    assert (out / "bag" / "metadata.yaml").exists()
    msgs = list(read_messages(out / "bag"))
    goals = [decode(m) for m in msgs if m.topic == T.GOAL]
    assert len(goals) > 500
    stamps = [g.header.stamp.sec * 10**9 + g.header.stamp.nanosec for g in goals]
    assert stamps == sorted(stamps) and len(set(stamps)) == len(stamps)
    from rosbags.highlevel import AnyReader

    with AnyReader([out / "bag"]) as reader:
        assert sum(1 for _ in reader.messages()) == len(msgs)
    env = dict(os.environ, ROS_DOMAIN_ID=str(DOMAIN))
    res = subprocess.run(command("stns_replay", "stns_ros.replay") + [
        str(out / "bag"), "--no-publish", "--out", str(tmp_path / "replay")],
        capture_output=True, text=True, env=env, timeout=120)
    assert res.returncode == 0 and "behaviour steps" in res.stdout, res.stdout + res.stderr


def _bringup_error(tmp_path, text: str) -> str:
    cfg = tmp_path / "bad.yaml"
    cfg.write_text(text)
    env = dict(os.environ, ROS_DOMAIN_ID=str(DOMAIN))
    res = subprocess.run(command("stns_bringup", "stns_ros.bringup") + [
        "--config", str(cfg), "--out", str(tmp_path / "out")], capture_output=True, text=True,
        env=env, timeout=60)
    assert res.returncode != 0
    assert not (tmp_path / "out").exists()  # refused before anything started
    return res.stderr


def test_bad_run_configs_are_refused_before_the_run(tmp_path):
    err = _bringup_error(tmp_path, "run: {steps: 3\n")
    assert "bad.yaml: not valid YAML" in err
    err = _bringup_error(tmp_path, yaml.safe_dump({"run": {"steps": -1}}))
    assert "run.steps must be an integer in [1, 1000000000], got -1" in err
    (tmp_path / "f.yaml").write_text(yaml.safe_dump(
        {"faults": [{"at_step": 3, "set": {"goal_sensor_rotation_deg": 400}}]}))
    err = _bringup_error(tmp_path, yaml.safe_dump({"faults": "f.yaml"}))
    assert "f.yaml: faults[0].set.goal_sensor_rotation_deg: goal_sensor_rotation_deg must be in [-180, 180], got 400" in err


@pytest.mark.parametrize("exe, module, args, message", [
    ("rover_sim_node", "stns_ros.sim_node", ["-p", "left_wheel_gain:=5.0"],
     "left_wheel_gain out of range"),
    ("rover_sim_node", "stns_ros.sim_node", ["-p", "mode:=fast"],
     "mode must be one of lockstep, free_running, got 'fast'"),
    ("stns_agent_node", "stns_ros.agent_node", ["-p", "world_overrides:=notjson"],
     "world_overrides is not JSON"),
    ("fault_injector_node", "stns_ros.fault_injector_node", ["-p", "scenario:=/nonexistent.yaml"],
     "cannot read fault scenario '/nonexistent.yaml'"),
])
def test_nodes_refuse_bad_parameters(exe, module, args, message):
    env = dict(os.environ, ROS_DOMAIN_ID=str(DOMAIN))
    res = subprocess.run(command(exe, module) + ["--ros-args", *args], capture_output=True,
                         text=True, env=env, timeout=60)
    assert res.returncode != 0
    assert message in res.stderr, res.stderr


@pytest.mark.parametrize(("steps", "rc"), [(1000, 130), (0, 0)])
def test_an_agent_stopped_before_its_last_step_exits_non_zero(tmp_path, steps, rc):
    """Ctrl-C before max_behaviour_steps is not a finished run; an unlimited run ends so."""
    env = dict(os.environ, ROS_DOMAIN_ID=str(DOMAIN))
    log = tmp_path / "agent.log"
    with open(log, "w") as f:
        proc = subprocess.Popen(
            command("stns_agent_node", "stns_ros.agent_node")
            + ["--ros-args", "-p", f"max_behaviour_steps:={steps}"],
            stdout=f, stderr=subprocess.STDOUT, env=env)
        deadline = time.monotonic() + 60
        while "stns_agent ready" not in log.read_text() and time.monotonic() < deadline:
            assert proc.poll() is None, log.read_text()
            time.sleep(0.1)
        proc.send_signal(signal.SIGINT)
        assert proc.wait(30) == rc, log.read_text()
    text = log.read_text()
    if rc:
        assert "stns_agent_node: stopped before the end: 0 of 1000 behaviour steps made" in text
    else:
        assert "stopped before the end" not in text
