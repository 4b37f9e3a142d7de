"""stns_replay: --verify passes on a recorded run and fails on a tampered one; republishing."""

import os
import subprocess

from conftest import DOMAIN, command
from stns_ros.bag import BagWriter, read_messages, read_metadata

from stns_ros import topics as T


def replay(*args, timeout=120):
    env = dict(os.environ, ROS_DOMAIN_ID=str(DOMAIN))
    return subprocess.run(command("stns_replay", "stns_ros.replay") + [str(a) for a in args],
                          capture_output=True, text=True, timeout=timeout, env=env)


def test_verify_passes_on_the_recorded_run(plain_run, tmp_path):
    res = replay(plain_run / "bag", "--verify", "--out", tmp_path)
    assert res.returncode == 0, res.stdout + res.stderr
    assert "verify: OK: 150 behaviour steps" in res.stdout
    assert "behaviour steps 150" in res.stdout  # the summary, from the bag alone
    assert (tmp_path / "learning_curve.png").exists() and (tmp_path / "summary.json").exists()


def test_replay_keeps_the_run_folder_and_refuses_a_nan_rate(plain_run, tmp_path):
    before = {p.name: p.read_bytes() for p in plain_run.iterdir() if p.is_file()}
    assert "summary.json" in before
    for out in (plain_run, plain_run / "."):
        res = replay(plain_run / "bag", "--no-publish", "--out", out)
        assert res.returncode != 0 and "is a run folder" in res.stderr, res.stdout + res.stderr
    assert {p.name: p.read_bytes() for p in plain_run.iterdir() if p.is_file()} == before
    res = replay(plain_run / "bag", "--rate", "nan", "--out", tmp_path)
    assert res.returncode != 0 and "--rate must be a finite number >= 0, got nan" in res.stderr
    (tmp_path / "afile").write_text("kept")
    res = replay(plain_run / "bag", "--no-publish", "--out", tmp_path / "afile")
    assert res.returncode != 0 and "afile' is a file, not a folder" in res.stderr
    assert (tmp_path / "afile").read_text() == "kept"


def _tampered_copy(src, dst, which: int):
    """Copy the bag, with the `which`-th /cmd_vel turned the other way."""
    from geometry_msgs.msg import TwistStamped
    from rclpy.serialization import deserialize_message, serialize_message

    types = {t["topic_metadata"]["name"]: t["topic_metadata"]["type"]
             for t in read_metadata(src)["topics_with_message_count"]}
    n = 0
    with BagWriter(dst) as w:
        for topic, msgtype in types.items():
            w.add_topic(topic, msgtype)
        for m in read_messages(src):
            data = m.data
            if m.topic == T.CMD_VEL:
                if n == which:
                    msg = deserialize_message(data, TwistStamped)
                    msg.twist.angular.z = -msg.twist.angular.z if msg.twist.angular.z else 0.8726646259971648
                    msg.twist.linear.x = 0.0
                    data = serialize_message(msg)
                n += 1
            w.write(m.topic, data, m.log_time)


def test_verify_fails_on_a_tampered_bag(plain_run, tmp_path):
    _tampered_copy(plain_run / "bag", tmp_path / "tampered", which=500)
    res = replay(tmp_path / "tampered", "--verify", "--out", tmp_path / "out")
    assert res.returncode == 1, res.stdout + res.stderr
    assert "verify: FAILED: command at t=50.0 s differs" in res.stdout


def test_republish_as_fast_as_possible(plain_run, tmp_path):
    res = replay(plain_run / "bag", "--rate", "0", "--out", tmp_path)
    assert res.returncode == 0, res.stdout + res.stderr
    total = sum(read_metadata(plain_run / "bag")["message_count"] for _ in [0])
    assert f"republished {total} messages" in res.stdout


def test_exp3_run_with_the_range_sensor_verifies(tmp_path):
    """8-D input: the six float32 ranges cross the ROS boundary exactly."""
    from conftest import bringup, run_config

    cfg = run_config(tmp_path, run={"name": "e3", "seed": 2, "steps": 40},
                     world={"preset": "exp3"}, learner={"preset": "exp3"})
    res = bringup(cfg, tmp_path / "run")
    assert res.returncode == 0, res.stdout + res.stderr
    res = replay(tmp_path / "run" / "bag", "--verify", "--out", tmp_path / "replay")
    assert res.returncode == 0 and "verify: OK: 40 behaviour steps" in res.stdout, res.stdout


def test_a_run_continues_from_a_saved_learner_and_verifies(plain_run, tmp_path):
    """Exp. 2 style: the learner saved by a run goes on under a sensor fault."""
    import json

    from conftest import bringup, run_config
    from stns_ros.summary import load_run

    cfg = run_config(tmp_path, run={"name": "cont", "seed": 8, "steps": 30},
                     learner={"preset": "exp1", "state_in": str(plain_run / "learner_state")},
                     faults={"name": "rot", "faults": [
                         {"at_step": 0, "set": {"goal_sensor_rotation_deg": 25.0}}]})
    res = bringup(cfg, tmp_path / "run")
    assert res.returncode == 0, res.stdout + res.stderr
    run = load_run(tmp_path / "run" / "bag")
    assert [r["run_step"] for r in run.steps] == list(range(30))
    assert run.steps[0]["index"] >= 150  # the saved learner's steps go on
    assert json.loads((tmp_path / "run" / "summary.json").read_text())["steps"] == 30
    res = replay(tmp_path / "run" / "bag", "--verify", "--out", tmp_path / "replay")
    assert res.returncode == 0 and "verify: OK: 30 behaviour steps" in res.stdout, res.stdout


def test_standalone_recorder_records_and_closes_on_sigint(tmp_path):
    import json
    import signal
    import time

    import rclpy
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from std_msgs.msg import String

    env = dict(os.environ, ROS_DOMAIN_ID=str(DOMAIN))
    proc = subprocess.Popen(command("stns_recorder", "stns_ros.recorder_node") + [
        "--ros-args", "-p", f"output:={tmp_path / 'bag'}", "-p",
        "topics:=[/fault_injector/events]"], env=env, stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT, text=True)
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=DOMAIN)
    try:
        node = rclpy.create_node("probe_pub", context=context)
        pub = node.create_publisher(String, T.FAULT_EVENTS,
                                    QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
        deadline = time.monotonic() + 30
        while pub.get_subscription_count() == 0 and time.monotonic() < deadline:
            time.sleep(0.05)
        for i in range(5):
            pub.publish(String(data=json.dumps({"i": i})))
        assert pub.wait_for_all_acked(rclpy.duration.Duration(seconds=5))
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)
    proc.send_signal(signal.SIGINT)
    out, _ = proc.communicate(timeout=30)
    assert proc.returncode == 0, out
    from stns_ros.bag import decode

    got = [json.loads(decode(m).data)["i"] for m in read_messages(tmp_path / "bag")]
    assert got == [0, 1, 2, 3, 4]
    assert read_metadata(tmp_path / "bag")["message_count"] == 5
