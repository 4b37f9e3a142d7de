"""In-process rclpy: parameter validation of the nodes and the recorder on a few messages."""

import json

import pytest
from rclpy.parameter import Parameter


@pytest.fixture
def sim(rclpy_context):
    from stns_ros.sim_node import RoverSimNode

    node = RoverSimNode()
    yield node
    node.close()
    node.destroy_node()


def test_fault_parameters_are_validated_with_a_reason(sim):
    res = sim.set_parameters([Parameter("left_wheel_gain", value=0.0)])[0]
    assert not res.successful and "left_wheel_gain must be in (0, 2], got 0.0" in res.reason
    res = sim.set_parameters([Parameter("goal_sensor_rotation_deg", value=500.0)])[0]
    assert not res.successful and "goal_sensor_rotation_deg" in res.reason
    assert sim.world.faults["goal_sensor_rotation_deg"] == 0.0
    res = sim.set_parameters([Parameter("goal_sensor_rotation_deg", value=15.0)])[0]
    assert res.successful
    assert sim.world.faults["goal_sensor_rotation_deg"] == 15.0
    res = sim.set_parameters([Parameter("goal_sensor_noise_std_m", value=0.125)])[0]
    assert res.successful and sim.world.faults["goal_sensor_noise_std"] == 2.0  # u
    res = sim.set_parameters([Parameter("mode", value="free_running")])[0]
    assert not res.successful  # read-only


def test_a_non_finite_command_stops_the_rover_instead_of_ending_the_simulator(sim):
    import math

    from geometry_msgs.msg import TwistStamped
    from rclpy.serialization import serialize_message
    from stns_ros.conversion import set_stamp

    def answer(v: float, w: float) -> None:  # the lockstep answer to the current frame
        msg = TwistStamped()
        set_stamp(msg.header.stamp, sim.frame * sim.tick_ns)
        msg.twist.linear.x, msg.twist.angular.z = v, w
        sim._on_cmd(serialize_message(msg))

    before = sim.world.pose
    answer(float("nan"), 0.5)
    assert sim.frame == 1 and sim.cmd == (0.0, 0.0)
    moved = lambda: math.dist(sim.world.pose[:2], before[:2])  # noqa: E731
    assert moved() < 0.01  # stopped (the physics settles by a few thousandths of a unit)
    answer(0.3, float("inf"))
    assert sim.frame == 2 and sim.cmd == (0.0, 0.0)
    answer(0.3, 0.0)  # a good command drives again
    assert sim.frame == 3 and sim.cmd[0] > 0 and moved() > 0.1


def test_bad_start_parameters_are_refused(rclpy_context):
    from stns_ros.errors import StnsRosError
    from stns_ros.sim_node import RoverSimNode

    with pytest.raises(StnsRosError, match="world_overrides is not JSON"):
        RoverSimNode(parameter_overrides=[Parameter("world_overrides", value="{oops")])
    with pytest.raises(StnsRosError, match="world: .*room_size"):
        RoverSimNode(parameter_overrides=[Parameter("world_overrides", value='{"room_size": -3}')])


def test_an_unknown_record_topic_is_refused_before_the_bag_is_made(rclpy_context, tmp_path):
    from stns_ros.errors import StnsRosError
    from stns_ros.sim_node import RoverSimNode

    with pytest.raises(StnsRosError, match="record_topics: no type known for '/nope'"):
        RoverSimNode(parameter_overrides=[Parameter("record_path", value=str(tmp_path / "bag")),
                                          Parameter("record_topics", value=["/nope"])])
    assert not (tmp_path / "bag").exists()


def test_agent_state_out_is_checked_at_start_and_the_learner_kept_at_shutdown(
        rclpy_context, tmp_path):
    import os
    import shutil
    import tempfile

    from stns_ros.agent_node import StnsAgentNode
    from stns_ros.errors import StnsRosError

    from stns_core import StnsAgent

    with pytest.raises(StnsRosError, match=r"state_out: folder '.*nowhere' of .* does not exist"):
        StnsAgentNode(parameter_overrides=[
            Parameter("state_out", value=str(tmp_path / "nowhere" / "s.npz"))])
    for name in ("state_out", "stats_out"):  # a folder, not a file to write: every save fails
        with pytest.raises(StnsRosError, match=f"{name}: '{tmp_path}' is a folder"):
            StnsAgentNode(parameter_overrides=[Parameter(name, value=str(tmp_path))])
    (tmp_path / "gone").mkdir()
    node = StnsAgentNode(parameter_overrides=[
        Parameter("state_out", value=str(tmp_path / "gone" / "s.npz"))])
    shutil.rmtree(tmp_path / "gone")  # the folder goes while the node runs
    spare = os.path.join(tempfile.gettempdir(), f"stns_learner_{os.getpid()}.npz")
    try:
        node.close()
        assert StnsAgent.load(spare).obs_dim == node.obs_dim  # saved elsewhere, not lost
    finally:
        node.destroy_node()
        if os.path.exists(spare):
            os.unlink(spare)


def test_agent_parameters_have_descriptors(rclpy_context):
    from stns_ros.agent_node import StnsAgentNode

    node = StnsAgentNode(parameter_overrides=[Parameter("gamma", value=0.5)])
    try:
        assert node.driver.agent.config.gamma == 0.5
        d = node.describe_parameter("gamma")
        assert d.floating_point_range[0].to_value == 1.0 and d.read_only
        res = node.set_parameters([Parameter("watchdog_timeout", value=-1.0)])[0]
        assert not res.successful
    finally:
        node.close()
        node.destroy_node()


@pytest.mark.parametrize("msgtype, message", [
    ("nope/msg/X", "unknown message type 'nope/msg/X'"),
    ("std_msgs/msg/Nope", "unknown message type 'std_msgs/msg/Nope'"),
])
def test_recorder_refuses_an_unknown_type_before_making_the_bag(rclpy_context, tmp_path,
                                                               msgtype, message):
    # a half-made bag directory would make the corrected command fail: "exists already"
    from stns_ros.errors import StnsRosError
    from stns_ros.recorder_node import RecorderNode

    with pytest.raises(StnsRosError, match=f"types: /x={msgtype}: {message}"):
        RecorderNode(parameter_overrides=[
            Parameter("output", value=str(tmp_path / "bag")), Parameter("topics", value=["/x"]),
            Parameter("types", value=[f"/x={msgtype}"])])
    assert not (tmp_path / "bag").exists()


def test_recorder_records_raw_messages(rclpy_context, tmp_path):
    import rclpy
    from std_msgs.msg import String
    from stns_ros.bag import decode, read_messages
    from stns_ros.recording import RECORD_QOS, TopicRecorder

    node = rclpy.create_node("rec_test")
    rec = TopicRecorder(node, str(tmp_path / "bag"), log_time=lambda: 42)
    rec.subscribe(["/fault_injector/events"])
    pub = node.create_publisher(String, "/fault_injector/events", RECORD_QOS)
    ex0 = rclpy.executors.SingleThreadedExecutor()
    ex0.add_node(node)
    for _ in range(200):  # discovery, up to 10 s on a loaded machine
        if pub.get_subscription_count() > 0:
            break
        ex0.spin_once(timeout_sec=0.05)
    ex0.remove_node(node)
    for i in range(3):
        pub.publish(String(data=json.dumps({"i": i})))
    ex = rclpy.executors.SingleThreadedExecutor()
    ex.add_node(node)
    for _ in range(100):
        ex.spin_once(timeout_sec=0.05)
        if rec.bag.counts["/fault_injector/events"] == 3:
            break
    rec.close()
    node.destroy_node()
    got = [json.loads(decode(m).data)["i"] for m in read_messages(tmp_path / "bag")]
    assert got == [0, 1, 2]


def test_agent_answers_a_frame_and_its_watchdog_stops_the_rover(rclpy_context):
    import rclpy
    from geometry_msgs.msg import PointStamped, TwistStamped, Vector3Stamped
    from stns_ros.agent_node import StnsAgentNode
    from stns_ros.sim_node import FRAME_QOS

    agent = StnsAgentNode(parameter_overrides=[Parameter("watchdog_timeout", value=0.1)])
    probe = rclpy.create_node("probe")
    got = []
    probe.create_subscription(TwistStamped, "/cmd_vel", got.append, FRAME_QOS)
    ex = rclpy.executors.SingleThreadedExecutor()
    ex.add_node(agent)
    ex.add_node(probe)
    try:
        _wait_for_subscriber(ex, agent.pub_cmd)
        goal = PointStamped()
        goal.header.stamp.sec = 3
        goal.point.x, goal.point.y = 1.0, -0.5
        reward = Vector3Stamped()
        reward.header.stamp.sec = 3
        _tick(agent, 3)
        agent._on_goal(goal)
        assert agent.frames == 0  # waits for the reward of the same stamp
        agent._on_reward(reward)
        assert agent.frames == 1
        for _ in range(40):
            ex.spin_once(timeout_sec=0.05)
            if len(got) >= 2:
                break
        answer, stop = got[0], got[-1]
        assert answer.header.stamp.sec == 3 and answer.header.frame_id == "base_link"
        assert (answer.twist.linear.x, answer.twist.angular.z) != (0.0, 0.0)
        assert stop.header.frame_id == "watchdog"
        assert (stop.twist.linear.x, stop.twist.angular.z) == (0.0, 0.0)
    finally:
        agent.close()
        agent.destroy_node()
        probe.destroy_node()


def test_agent_rejects_a_frame_with_nan_and_stops_the_rover(rclpy_context):
    import rclpy
    from geometry_msgs.msg import TwistStamped
    from stns_ros.agent_node import StnsAgentNode
    from stns_ros.sim_node import FRAME_QOS

    agent = StnsAgentNode()
    probe = rclpy.create_node("probe")
    got = []
    probe.create_subscription(TwistStamped, "/cmd_vel", got.append, FRAME_QOS)
    ex = rclpy.executors.SingleThreadedExecutor()
    ex.add_node(agent)
    ex.add_node(probe)
    try:
        _wait_for_subscriber(ex, agent.pub_cmd)

        def frame(sec: int, x: float) -> None:
            goal, reward = _frame_msgs(sec, x)
            _tick(agent, sec)
            agent._on_goal(goal)
            agent._on_reward(reward)

        frame(3, float("nan"))
        assert agent.frames == 0 and agent.rejected_frames == 1
        assert agent.driver.behaviour_steps == 0
        frame(4, 1.0)  # the next good frame is learned from as usual
        assert agent.frames == 1 and agent.rejected_frames == 1
        for _ in range(40):
            ex.spin_once(timeout_sec=0.05)
            if len(got) >= 2:
                break
        stop, answer = got[0], got[1]
        assert stop.header.frame_id == "invalid_input" and stop.header.stamp.sec == 3
        assert (stop.twist.linear.x, stop.twist.angular.z) == (0.0, 0.0)
        assert answer.header.stamp.sec == 4
        assert (answer.twist.linear.x, answer.twist.angular.z) != (0.0, 0.0)
    finally:
        agent.close()
        agent.destroy_node()
        probe.destroy_node()


def _tick(agent, sec: int) -> None:
    """The simulator's /clock for the frame of second `sec` (it comes before the frame)."""
    from rosgraph_msgs.msg import Clock

    msg = Clock()
    msg.clock.sec = sec
    agent._on_clock(msg)


def _wait_for_subscriber(ex, publisher) -> None:
    for _ in range(200):  # discovery, up to 10 s on a loaded machine
        if publisher.get_subscription_count() > 0:
            return
        ex.spin_once(timeout_sec=0.05)


def test_agent_checkpoints_the_learner_while_it_runs(rclpy_context, tmp_path):
    """A killed agent keeps what it learned up to its last checkpoint."""
    from stns_ros.agent_node import StnsAgentNode

    from stns_core import StnsAgent

    state = tmp_path / "learner_state"
    agent = StnsAgentNode(parameter_overrides=[
        Parameter("state_out", value=str(state)), Parameter("checkpoint_every", value=2)])
    try:
        sec = 0
        while agent.run_steps < 2 and sec < 100:
            sec += 1
            goal, reward = _frame_msgs(sec)
            if sec % 5 == 0:  # a goal arrival ends the behaviour step
                reward.vector.x, reward.vector.y = 1.0, 1.0
            _tick(agent, sec)
            agent._on_goal(goal)
            agent._on_reward(reward)
            if agent.run_steps < 2:
                assert not state.exists()  # no checkpoint before the second behaviour step
        assert agent.run_steps >= 2 and state.exists()
        assert StnsAgent.load(state).behaviour_steps == agent.run_steps
    finally:
        agent.destroy_node()  # no close(): as if killed, the checkpoint is all there is


def _frame_msgs(sec: int, x: float = 1.0, ranges: int | None = None):
    """goal, reward (and a LaserScan of `ranges` values) stamped at second `sec`."""
    from geometry_msgs.msg import PointStamped, Vector3Stamped
    from sensor_msgs.msg import LaserScan

    goal = PointStamped()
    goal.header.stamp.sec = sec
    goal.point.x, goal.point.y = x, -0.5
    reward = Vector3Stamped()
    reward.header.stamp.sec = sec
    if ranges is None:
        return goal, reward
    scan = LaserScan()
    scan.header.stamp.sec = sec
    scan.ranges = [1.0] * ranges
    return goal, reward, scan


def test_agent_rejects_a_scan_with_the_wrong_number_of_ranges(rclpy_context):
    from stns_ros.agent_node import StnsAgentNode

    agent = StnsAgentNode(parameter_overrides=[
        Parameter("learner_preset", value="exp3"), Parameter("world_preset", value="exp3")])
    try:
        assert agent.obs_dim == 8
        for sec, n in ((3, 3), (4, 6)):
            goal, reward, scan = _frame_msgs(sec, ranges=n)
            _tick(agent, sec)
            agent._on_goal(goal)
            agent._on_ranges(scan)
            agent._on_reward(reward)
        # the three-range frame is refused and the node goes on; the next one is learned from
        assert agent.rejected_frames == 1 and agent.frames == 1
    finally:
        agent.close()
        agent.destroy_node()


def test_agent_holds_a_frame_until_its_clock_and_drops_one_far_ahead(rclpy_context):
    """A frame stamped far in the future (a second publisher, a replayed bag) must not be
    learned from: every real frame after it would look old and a lockstep run would stall."""
    from stns_ros.agent_node import StnsAgentNode

    agent = StnsAgentNode()
    try:
        _tick(agent, 3)
        goal, reward = _frame_msgs(103)  # 1000 ticks ahead of /clock
        agent._on_goal(goal)
        agent._on_reward(reward)
        assert agent.frames == 0 and agent.refused_stamps == 2
        goal, reward = _frame_msgs(3)
        agent._on_goal(goal)
        agent._on_reward(reward)
        assert agent.frames == 1  # the real frame still is the next one
        goal, reward = _frame_msgs(4)  # its /clock is still on the way: held
        agent._on_goal(goal)
        agent._on_reward(reward)
        assert agent.frames == 1 and agent.refused_stamps == 2
        _tick(agent, 4)
        assert agent.frames == 2  # learned from when the clock reached it
    finally:
        agent.close()
        agent.destroy_node()


def test_tuning_parameters_set_while_running_take_effect(rclpy_context, sim):
    from stns_ros.agent_node import StnsAgentNode

    agent = StnsAgentNode()
    try:
        for name, value in (("progress_every", 7), ("explain_every", 3), ("markers_every", 5),
                            ("checkpoint_every", 9), ("watchdog_timeout", 2.0)):
            assert agent.set_parameters([Parameter(name, value=value)])[0].successful
            assert agent.params[name] == value
        assert agent._watchdog_timer.timer_period_ns == 1_000_000_000  # half the timeout
    finally:
        agent.close()
        agent.destroy_node()
    assert sim.publish_ranges
    assert sim.set_parameters([Parameter("publish_ranges", value=False)])[0].successful
    assert not sim.publish_ranges
    assert sim.set_parameters([Parameter("resend_period", value=0.5)])[0].successful
    assert sim._resend_timer.timer_period_ns == 500_000_000


def test_fault_injector_refuses_wall_time(rclpy_context):
    from stns_ros.errors import StnsRosError
    from stns_ros.fault_injector_node import FaultInjectorNode

    with pytest.raises(StnsRosError, match="use_sim_time must be true.*got use_sim_time false"):
        FaultInjectorNode()
    node = FaultInjectorNode(parameter_overrides=[Parameter("use_sim_time", value=True)])
    try:
        res = node.set_parameters([Parameter("use_sim_time", value=False)])[0]
        assert not res.successful and "got False" in res.reason
        assert node.get_parameter("use_sim_time").value is True
    finally:
        node.destroy_node()


def test_rclpy_refusals_name_the_parameter_and_the_value(sim):
    from rclpy.exceptions import ParameterNotDeclaredException

    res = sim.set_parameters([Parameter("left_wheel_gain", value="fast")])[0]
    assert not res.successful
    assert res.reason == ("Wrong parameter type: left_wheel_gain must be a number with a "
                          "decimal point, got 'fast'")
    res = sim.set_parameters([Parameter("seed", value=5)])[0]
    assert not res.successful
    assert res.reason.startswith("seed is read-only") and "(got 5)" in res.reason
    with pytest.raises(ParameterNotDeclaredException, match=r"left_wheel_gian \(known: .*"
                                                            r"left_wheel_gain"):
        sim.set_parameters([Parameter("left_wheel_gian", value=0.9)])
    assert sim.world.faults["left_wheel_gain"] == 1.0  # nothing applied


def test_a_start_parameter_of_the_wrong_type_is_still_refused(rclpy_context):
    from rclpy.exceptions import InvalidParameterTypeException
    from stns_ros.sim_node import RoverSimNode

    with pytest.raises(InvalidParameterTypeException):
        RoverSimNode(parameter_overrides=[Parameter("seed", value="three")])


def test_the_simulator_stepping_after_ctrl_c_does_not_raise(rclpy_context):
    """An answer handled while SIGINT shuts the context used to end in a FATAL traceback."""
    import rclpy
    from stns_ros.sim_node import RoverSimNode

    node = RoverSimNode()
    try:
        rclpy.shutdown()
        node._advance()  # publishing on the shut context: the frame is dropped quietly
        assert node.frame == 1
    finally:
        node.close()
        node.destroy_node()
