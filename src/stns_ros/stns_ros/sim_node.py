"""rover_sim_node: the pybullet rover world as a ROS 2 node.

Publishes /clock, /rover/goal, /rover/obstacle_ranges, /rover/reward, /rover/odom; takes
/cmd_vel. Lockstep mode: frame k (an observation) is published, the world advances only
when the /cmd_vel stamped with frame k's time arrives (an answer to a terminated frame
resets the world instead: a new trial), then frame k + 1 is published; unanswered frames
are re-sent (not re-recorded) so that discovery races cannot stall the loop.
Free-running mode: a wall timer steps the world with the latest command at
``tick_seconds / real_time_factor``. Frame k is stamped ``k * tick_seconds`` (a trial reset
is a frame of its own). Faults are parameters, validated before they reach the world.
"""

from __future__ import annotations

import json
import math

from geometry_msgs.msg import PointStamped, TwistStamped, Vector3Stamped
from nav_msgs.msg import Odometry
from rclpy._rclpy_pybind11 import RCLError
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message, serialize_message
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import LaserScan
from std_msgs.msg import String

from stns_ros import topics as T
from stns_ros.conversion import UNIT_M, m_to_u, set_stamp, stamp_ns, tick_ns, yaw_quaternion
from stns_ros.errors import StnsRosError
from stns_ros.params import (
    FAULT_PARAMS,
    NamedRefusals,
    check_choice,
    check_fault,
    check_tuning,
    declare,
    declare_tuning,
    result,
)
from stns_ros.recording import LATCHED_QOS, TopicRecorder
from stns_ros.runtime import run_node

MODES = ("lockstep", "free_running")
FRAME_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)


class RoverSimNode(NamedRefusals, Node):
    def __init__(self, **kwargs) -> None:
        super().__init__("rover_sim", **kwargs)
        from rover_sim import RoverSimError, RoverWorld, WorldConfig

        p = {}
        p["world_preset"] = declare(self, "world_preset", "exp1", "rover_sim task preset.",
                                    read_only=True, choices=("exp1", "exp3"))
        p["world_overrides"] = declare(
            self, "world_overrides", "{}",
            "JSON object of WorldConfig field overrides (lengths in u).", read_only=True)
        p["seed"] = declare(self, "seed", 0, "Seed of the world's Generator.",
                            range=(0, 2**32 - 1), read_only=True)
        p["mode"] = declare(self, "mode", "lockstep", "Stepping mode.", choices=MODES,
                            read_only=True)
        p["real_time_factor"] = declare(
            self, "real_time_factor", 1.0, "Free-running: sim seconds per wall second.",
            range=(0.01, 100.0))
        for name in ("publish_ranges", "resend_period", "record_topics"):
            p[name] = declare_tuning(self, "rover_sim", name)
        _, reason = check_tuning("rover_sim", "record_topics", p["record_topics"])
        if reason:  # before the bag is made: a KeyError in the recorder would leave half of it
            raise StnsRosError(reason)
        p["record_path"] = declare(
            self, "record_path", "", "rosbag2 directory to record the run into ('' = off).",
            read_only=True)
        p["record_compression"] = declare(self, "record_compression", "zstd",
                                          "MCAP chunk compression.",
                                          choices=("zstd", "lz4", "none"), read_only=True)
        p["record_chunk_size"] = declare(self, "record_chunk_size", 262144,
                                         "MCAP chunk size, bytes.", range=(1024, 2**26),
                                         read_only=True)
        p["run_config"] = declare(
            self, "run_config", "{}",
            "JSON of the whole run config; published latched on /stns/run_config and recorded.",
            read_only=True)
        for name, (lo, hi, _, text) in FAULT_PARAMS.items():
            default = 1.0 if name == "left_wheel_gain" else 0.0
            p[name] = declare(self, name, default, text, range=(lo, hi))
        for name, choices in (("world_preset", ("exp1", "exp3")), ("mode", MODES),
                              ("record_compression", ("zstd", "lz4", "none"))):
            reason = check_choice(name, p[name], choices)
            if reason:
                raise StnsRosError(reason)
        for name in FAULT_PARAMS:
            reason = check_fault(name, p[name])
            if reason:
                raise StnsRosError(reason)
        try:
            overrides = json.loads(p["world_overrides"])
        except json.JSONDecodeError as e:
            raise StnsRosError(f"world_overrides is not JSON: {e}") from None
        if not isinstance(overrides, dict):
            raise StnsRosError(f"world_overrides must be a JSON object, got {overrides!r}")
        self.params = p
        try:
            self.world = RoverWorld(WorldConfig.preset(p["world_preset"], **overrides),
                                    seed=p["seed"])
        except (RoverSimError, TypeError) as e:
            raise StnsRosError(f"world: {e}") from None
        self.tick_ns = tick_ns(self.world.config.tick_seconds)
        for name in FAULT_PARAMS:
            self._apply_fault(name, p[name])
        self.add_on_set_parameters_callback(self._validate)
        self.add_post_set_parameters_callback(self._applied)

        self.lockstep = p["mode"] == "lockstep"
        self.publish_ranges = bool(p["publish_ranges"]) or self.world.observation_dim == 8
        self.pub_clock = self.create_publisher(ClockMsg, T.CLOCK, FRAME_QOS)
        self.pub_goal = self.create_publisher(PointStamped, T.GOAL, FRAME_QOS)
        self.pub_ranges = self.create_publisher(LaserScan, T.RANGES, FRAME_QOS)
        self.pub_reward = self.create_publisher(Vector3Stamped, T.REWARD, FRAME_QOS)
        self.pub_odom = self.create_publisher(Odometry, T.ODOM, FRAME_QOS)
        self.pub_config = self.create_publisher(String, T.RUN_CONFIG, LATCHED_QOS)
        self.create_subscription(TwistStamped, T.CMD_VEL, self._on_cmd, FRAME_QOS, raw=True)

        self._msg_clock = ClockMsg()
        self._msg_goal = PointStamped()
        self._msg_goal.header.frame_id = "base_link"
        self._msg_scan = LaserScan()
        self._msg_scan.header.frame_id = "base_link"
        self._msg_scan.angle_min = -math.pi
        self._msg_scan.angle_max = math.pi * 2.0 / 3.0
        self._msg_scan.angle_increment = math.pi / 3.0
        self._msg_scan.range_min = 0.0
        self._msg_scan.range_max = float(self.world.config.max_range) * UNIT_M
        self._msg_scan.scan_time = float(self.world.config.tick_seconds)
        self._msg_reward = Vector3Stamped()
        self._msg_reward.header.frame_id = "base_link"
        self._msg_odom = Odometry()
        self._msg_odom.header.frame_id = "odom"
        self._msg_odom.child_frame_id = "base_link"

        self.recorder = None
        if p["record_path"]:
            self.recorder = TopicRecorder(
                self, p["record_path"], log_time=lambda: self.frame * self.tick_ns,
                compression=p["record_compression"], chunk_size=p["record_chunk_size"],
                custom_data={"stns_run_config": p["run_config"]},
            )
            for topic in T.SIM_TOPICS + (T.RUN_CONFIG,):
                self.recorder.add(topic)
            self.recorder.subscribe([t for t in p["record_topics"] if t not in T.SIM_TOPICS])
        config_msg = String(data=p["run_config"])
        self.pub_config.publish(config_msg)
        if self.recorder:
            self.recorder.write(T.RUN_CONFIG, serialize_message(config_msg), 0)

        self.frame = 0
        self.cmd = (0.0, 0.0)
        self._frame_data: list[tuple[object, bytes]] = []
        obs, info = self.world.reset()
        self._terminated = False
        self._publish_frame(obs, 0.0, False, info)
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        if self.lockstep:
            self._resend_timer = self.create_timer(p["resend_period"], self._resend, clock=steady)
        else:
            period = self.world.config.tick_seconds / p["real_time_factor"]
            self._step_timer = self.create_timer(period, self._free_tick, clock=steady)
        self.get_logger().info(
            f"rover_sim ready: {p['world_preset']} seed={p['seed']} mode={p['mode']} "
            f"tick={self.world.config.tick_seconds}s record={p['record_path'] or 'off'}")

    # ---------------------------------------------------------------- faults
    def _validate(self, params: list[Parameter]):
        for prm in params:
            if prm.name in FAULT_PARAMS:
                reason = check_fault(prm.name, prm.value)
                if reason:
                    return result(reason)
            elif prm.name == "real_time_factor" and not (
                isinstance(prm.value, float) and 0.01 <= prm.value <= 100.0
            ):
                return result(f"real_time_factor must be in [0.01, 100], got {prm.value!r}")
        return result(None)

    def _applied(self, params: list[Parameter]) -> None:
        for prm in params:
            if prm.name in FAULT_PARAMS:
                self._apply_fault(prm.name, prm.value)
                self.get_logger().info(f"fault {prm.name} = {prm.value} at frame {self.frame}")
            elif prm.name == "publish_ranges":
                self.publish_ranges = bool(prm.value) or self.world.observation_dim == 8
            elif prm.name == "resend_period":
                self.params["resend_period"] = prm.value
                if self.lockstep:
                    self._resend_timer.cancel()
                    self.destroy_timer(self._resend_timer)
                    self._resend_timer = self.create_timer(
                        prm.value, self._resend, clock=Clock(clock_type=ClockType.STEADY_TIME))
            elif prm.name == "real_time_factor" and not self.lockstep:
                self._step_timer.cancel()
                self._step_timer = self.create_timer(
                    self.world.config.tick_seconds / prm.value, self._free_tick,
                    clock=Clock(clock_type=ClockType.STEADY_TIME))

    def _apply_fault(self, name: str, value: float) -> None:
        if name.endswith("_std_m"):
            self.world.set_fault(name[:-2], m_to_u(value))
        else:
            self.world.set_fault(name, float(value))

    # ---------------------------------------------------------------- frames
    def _publish_frame(self, obs, reward: float, terminated: bool, info: dict) -> None:
        t = self.frame * self.tick_ns
        out: list[tuple[object, str, bytes]] = []
        set_stamp(self._msg_clock.clock, t)
        out.append((self.pub_clock, T.CLOCK, serialize_message(self._msg_clock)))
        g = self._msg_goal
        set_stamp(g.header.stamp, t)
        g.point.x = float(obs[0]) * UNIT_M
        g.point.y = float(obs[1]) * UNIT_M
        out.append((self.pub_goal, T.GOAL, serialize_message(g)))
        if self.publish_ranges:
            ranges = obs[2:8] if len(obs) == 8 else self.world.range_readings()
            s = self._msg_scan
            set_stamp(s.header.stamp, t)
            s.ranges = [float(r) * UNIT_M for r in ranges]
            out.append((self.pub_ranges, T.RANGES, serialize_message(s)))
        o = self._msg_odom
        set_stamp(o.header.stamp, t)
        x, y, th = info["pose"]
        o.pose.pose.position.x = float(x) * UNIT_M
        o.pose.pose.position.y = float(y) * UNIT_M
        qx, qy, qz, qw = yaw_quaternion(float(th))
        q = o.pose.pose.orientation
        q.x, q.y, q.z, q.w = qx, qy, qz, qw
        o.twist.twist.linear.x = self.cmd[0] * UNIT_M
        o.twist.twist.angular.z = self.cmd[1]
        out.append((self.pub_odom, T.ODOM, serialize_message(o)))
        r = self._msg_reward
        set_stamp(r.header.stamp, t)
        r.vector.x = float(reward)
        r.vector.y = 1.0 if terminated else 0.0
        r.vector.z = float(info["trial"])
        out.append((self.pub_reward, T.REWARD, serialize_message(r)))
        self._terminated = bool(terminated)
        self._frame_data = [(pub, data) for pub, _, data in out]
        try:
            for pub, _, data in out:
                pub.publish(data)
        except RCLError:
            if self.context.ok():
                raise
            return  # Ctrl-C shut the context while an answer was handled: the run is over
        if self.recorder:  # after publishing: the agent works meanwhile
            for _, topic, data in out:
                self.recorder.write(topic, data, t)

    def _resend(self) -> None:
        for pub, data in self._frame_data:
            pub.publish(data)

    def _advance(self) -> None:
        if self._terminated:
            obs, info = self.world.reset()
            reward, terminated = 0.0, False
            self.cmd = (0.0, 0.0)
        else:
            obs, reward, terminated, truncated, info = self.world.step_velocity(*self.cmd)
            if truncated and not terminated:  # as the headless loop: a new trial at once
                obs, info = self.world.reset()
                reward = 0.0
        self.frame += 1
        self._publish_frame(obs, reward, terminated, info)

    def _command(self, msg: TwistStamped) -> tuple[float, float]:
        """(v u/s, w rad/s) of a /cmd_vel; a non-finite one stops the rover (the world would
        refuse it and the node end), with a warning naming it."""
        v, w = msg.twist.linear.x, msg.twist.angular.z
        if math.isfinite(v) and math.isfinite(w):
            return m_to_u(v), float(w)
        self.get_logger().warn(f"/cmd_vel with linear.x={v!r}, angular.z={w!r}: not finite, "
                               "taken as a stop", throttle_duration_sec=5.0)
        return 0.0, 0.0

    def _on_cmd(self, data: bytes) -> None:
        msg = deserialize_message(data, TwistStamped)
        if msg.header.frame_id == "watchdog":
            if not self.lockstep:
                self.cmd = (0.0, 0.0)
            return
        t = stamp_ns(msg.header.stamp)
        current = self.frame * self.tick_ns
        if self.lockstep:
            if t != current:
                return  # a duplicate answer to a frame already advanced
            self.cmd = self._command(msg)
            if self.recorder:
                self.recorder.write(T.CMD_VEL, data, t)
            self._advance()
            self._resend_timer.reset()
        else:
            if self.recorder:
                self.recorder.write(T.CMD_VEL, data, current)
            self.cmd = self._command(msg)

    def _free_tick(self) -> None:
        self._advance()

    def close(self) -> None:
        if self.recorder:
            self.recorder.close()
        self.world.close()


def main(args=None) -> None:
    run_node("rover_sim_node", RoverSimNode, args)


if __name__ == "__main__":
    main()
