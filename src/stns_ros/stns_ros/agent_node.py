"""stns_agent_node: the STNS learner as a ROS 2 node.

Assembles one observation per frame (the /rover/goal, /rover/obstacle_ranges when the input
has them, and /rover/reward messages of one stamp), steps the agent exactly as the headless
loop does (`AgentDriver`), answers with /cmd_vel stamped with the frame's time, and
publishes the explanation: /stns/steps (each finished StepRecord, JSON), /stns/situation
(current situation), /stns/plan (master plan, JSON) and /stns/situations (MarkerArray of
the situation shapes in goal-sensor space). A frame re-sent by the simulator gets the same
cached answer. A steady-clock watchdog publishes a zero command (frame_id "watchdog") when
frames stop coming. The learner state is saved on shutdown (``state_out``) and can be
loaded at start (``state_in``). With ``max_behaviour_steps`` set the node exits when the
agent has made that many behaviour steps.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import tempfile
import time

import numpy as np
from geometry_msgs.msg import PointStamped, TwistStamped, Vector3Stamped
from rclpy.clock import Clock, ClockType
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.serialization import serialize_message
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import LaserScan
from std_msgs.msg import Int32, String
from visualization_msgs.msg import Marker, MarkerArray

from stns_ros import topics as T
from stns_ros.conversion import UNIT_M, m_to_u, set_stamp, stamp_ns, tick_ns
from stns_ros.driver import AgentDriver, action_velocities, dumps, make_agent, record_to_dict
from stns_ros.errors import StnsRosError
from stns_ros.params import (
    MAX_STEPS,
    TUNING,
    NamedRefusals,
    check_choice,
    declare,
    declare_tuning,
    result,
)
from stns_ros.runtime import run_node
from stns_ros.sim_node import FRAME_QOS

EXPLAIN_QOS = 100
# A frame stamped ahead of /clock is held until the clock reaches it (the two topics of one
# frame can arrive in either order); one stamped further ahead than this is not from the
# simulator (a second publisher, a replayed bag) and is refused: learning from it would make
# every real frame after it look old and stall a lockstep run.
MAX_AHEAD_NS = 1_000_000_000
MAX_HELD = 64  # pending frames kept; the oldest are dropped first
# Lowest values of StnsConfig's integer fields (stns_core validates them too); others are >= 1.
INT_LOWEST = {"seed": 0, "target_lookahead_ticks": 0, "max_behaviour_ticks": 0, "history_size": 2}


def learner_fields() -> list[dataclasses.Field]:
    from stns_core import StnsConfig

    return list(dataclasses.fields(StnsConfig))


class StnsAgentNode(NamedRefusals, Node):
    def __init__(self, **kwargs) -> None:
        super().__init__("stns_agent", **kwargs)
        from stns_core import StnsConfig

        p = {}
        p["learner_preset"] = declare(self, "learner_preset", "exp1",
                                      "stns_core StnsConfig preset.", read_only=True,
                                      choices=("exp1", "exp3"))
        reason = check_choice("learner_preset", p["learner_preset"], ("exp1", "exp3"))
        if reason:
            raise StnsRosError(reason)
        preset = StnsConfig.preset(p["learner_preset"]).to_dict()
        for f in learner_fields():
            default = preset[f.name]
            rng = None
            if f.name in ("gamma", "p_min"):
                rng = (0.0, 1.0)
            elif isinstance(default, int) and not isinstance(default, bool):
                lowest = min(INT_LOWEST.get(f.name, 1), default)  # fields added later
                rng = (lowest, 2**32 - 1 if f.name == "seed" else 10**9)
            p[f.name] = declare(self, f.name, default,
                                f"StnsConfig.{f.name} (stns_core; preset value by default).",
                                range=rng, read_only=True)
        p["world_preset"] = declare(self, "world_preset", "exp1",
                                    "rover_sim preset (action speeds, input size).",
                                    read_only=True, choices=("exp1", "exp3"))
        p["world_overrides"] = declare(self, "world_overrides", "{}",
                                       "JSON WorldConfig overrides (as the simulator's).",
                                       read_only=True)
        p["max_behaviour_steps"] = declare(
            self, "max_behaviour_steps", 0, "Exit after this many behaviour steps (0 = never).",
            range=(0, MAX_STEPS), read_only=True)
        p["state_in"] = declare(self, "state_in", "", "Saved learner to start from ('' = new).",
                                read_only=True)
        p["state_out"] = declare(self, "state_out", "", "Save the learner here on shutdown.",
                                 read_only=True)
        for name in TUNING["stns_agent"]:
            p[name] = declare_tuning(self, "stns_agent", name)
        p["stats_out"] = declare(
            self, "stats_out", "", "Write wall time and rates of the run here as JSON ('' = off).",
            read_only=True)
        p["wait_for_recorder"] = declare(
            self, "wait_for_recorder", False,
            "Answer no frame before /stns/steps has a subscriber (the recorder).", read_only=True)
        self.params = p
        for name in ("state_out", "stats_out"):  # found out at shutdown, the learner would be lost
            folder = os.path.dirname(os.path.abspath(p[name])) if p[name] else ""
            if folder and not (os.path.isdir(folder) and os.access(folder, os.W_OK)):
                raise StnsRosError(f"{name}: folder {folder!r} of {p[name]!r} does not exist "
                                   "or is not writable")
            if p[name] and os.path.isdir(p[name]):
                raise StnsRosError(f"{name}: {p[name]!r} is a folder; give the file to write "
                                   "(e.g. a path inside it)")
        self.add_on_set_parameters_callback(self._validate)
        learner = {f.name: p[f.name] for f in learner_fields()}
        try:
            overrides = json.loads(p["world_overrides"])
        except json.JSONDecodeError as e:
            raise StnsRosError(f"world_overrides is not JSON: {e}") from None
        from rover_sim import WorldConfig

        world = WorldConfig.preset(p["world_preset"], **overrides)
        self.obs_dim = world.observation_dim
        self._max_ahead_ns = max(MAX_AHEAD_NS, tick_ns(world.tick_seconds))
        from stns_core import StnsError

        try:
            agent = make_agent(learner, self.obs_dim, p["state_in"])
        except (StnsError, OSError) as e:
            raise StnsRosError(f"learner: {e}") from None
        self.driver = AgentDriver(agent, action_velocities(p["world_preset"], overrides))
        self.max_steps = int(p["max_behaviour_steps"])
        self.start_steps = self.driver.behaviour_steps  # > 0 for a saved learner
        self.done = False

        self.pub_cmd = self.create_publisher(TwistStamped, T.CMD_VEL, FRAME_QOS)
        self.pub_steps = self.create_publisher(String, T.STEPS, EXPLAIN_QOS)
        self.pub_situation = self.create_publisher(Int32, T.SITUATION, EXPLAIN_QOS)
        self.pub_plan = self.create_publisher(String, T.PLAN, EXPLAIN_QOS)
        self.pub_markers = self.create_publisher(MarkerArray, T.SITUATIONS, EXPLAIN_QOS)
        self.create_subscription(ClockMsg, T.CLOCK, self._on_clock, FRAME_QOS)
        self.create_subscription(PointStamped, T.GOAL, self._on_goal, FRAME_QOS)
        self.create_subscription(Vector3Stamped, T.REWARD, self._on_reward, FRAME_QOS)
        if self.obs_dim == 8:
            self.create_subscription(LaserScan, T.RANGES, self._on_ranges, FRAME_QOS)

        self._pending: dict[int, dict] = {}
        self._last_t = -1
        self._clock_ns = -1  # latest /clock of the simulator
        self._last_answer: bytes | None = None
        self._cmd = TwistStamped()
        self._cmd.header.frame_id = "base_link"
        self._last_plan = None
        self._since_explain = 0
        self._since_markers = 0
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._steady = steady
        self._last_frame_wall = steady.now()
        self._stopped = False
        self._t_first = None
        self._t_done = None
        self.frames = 0
        self.rejected_frames = 0  # frames with a non-finite or missing reading: not learned from
        self.refused_stamps = 0  # messages stamped too far ahead of /clock: dropped
        self.ticks = 0
        self._watchdog_timer = self.create_timer(p["watchdog_timeout"] / 2.0, self._watchdog,
                                                 clock=steady)
        self.add_post_set_parameters_callback(self._applied)
        self.get_logger().info(
            f"stns_agent ready: learner {p['learner_preset']} seed={p['seed']} "
            f"obs_dim={self.obs_dim} steps={self.max_steps or 'unlimited'}"
            + (f" from {p['state_in']}" if p["state_in"] else ""))

    def _validate(self, params: list[Parameter]):
        for prm in params:
            if prm.name == "watchdog_timeout" and not (
                isinstance(prm.value, float) and 0.05 <= prm.value <= 60.0
            ):
                return result(f"watchdog_timeout must be in [0.05, 60] s, got {prm.value!r}")
        return result(None)

    def _applied(self, params: list[Parameter]) -> None:
        """Tuning parameters take effect at once (the others are read-only)."""
        for prm in params:
            if prm.name in TUNING["stns_agent"]:
                self.params[prm.name] = prm.value
                if prm.name == "watchdog_timeout":
                    self._watchdog_timer.cancel()
                    self.destroy_timer(self._watchdog_timer)
                    self._watchdog_timer = self.create_timer(prm.value / 2.0, self._watchdog,
                                                             clock=self._steady)
                self.get_logger().info(f"{prm.name} = {prm.value!r}")

    # ---------------------------------------------------------------- frames
    def _slot(self, t: int) -> dict | None:
        if t <= self._last_t:
            if t == self._last_t and self._last_answer is not None:
                self.pub_cmd.publish(self._last_answer)  # the sim re-sent a frame we answered
            return None
        if t > self._clock_ns + self._max_ahead_ns:
            self.refused_stamps += 1
            self.get_logger().error(
                f"message stamped {t} ns is {(t - self._clock_ns) / 1e9:.3f} s ahead of /clock "
                f"({self._clock_ns} ns): not from the simulator's current frame; dropped",
                throttle_duration_sec=5.0)
            return None
        if t not in self._pending and len(self._pending) >= MAX_HELD:
            del self._pending[min(self._pending)]
        return self._pending.setdefault(t, {})

    def _on_clock(self, msg: ClockMsg) -> None:
        t = stamp_ns(msg.clock)
        if t <= self._clock_ns:
            return
        self._clock_ns = t
        for held in sorted(k for k in self._pending if k <= t):
            slot = self._pending.get(held)
            if slot is not None:
                self._try(held, slot)

    def _on_goal(self, msg: PointStamped) -> None:
        t = stamp_ns(msg.header.stamp)
        slot = self._slot(t)
        if slot is not None:
            slot["goal"] = (msg.point.x, msg.point.y)
            self._try(t, slot)

    def _on_ranges(self, msg: LaserScan) -> None:
        t = stamp_ns(msg.header.stamp)
        slot = self._slot(t)
        if slot is not None:
            slot["ranges"] = list(msg.ranges)
            self._try(t, slot)

    def _on_reward(self, msg: Vector3Stamped) -> None:
        t = stamp_ns(msg.header.stamp)
        slot = self._slot(t)
        if slot is not None:
            slot["reward"] = (msg.vector.x, msg.vector.y > 0.5)
            self._try(t, slot)

    def _try(self, t: int, slot: dict) -> None:
        if "goal" not in slot or "reward" not in slot:
            return
        if self.obs_dim == 8 and "ranges" not in slot:
            return
        if self.done or t > self._clock_ns:  # held until /clock reaches the frame
            return
        if self.params["wait_for_recorder"] and self.pub_steps.get_subscription_count() == 0:
            return  # the simulator re-sends the frame; nothing is lost
        del self._pending[t]
        for old in [k for k in self._pending if k < t]:
            del self._pending[old]
        gx, gy = slot["goal"]
        obs = [m_to_u(gx), m_to_u(gy)]
        if self.obs_dim == 8:
            if len(slot["ranges"]) != self.obs_dim - 2:
                self._reject_frame(t, f"{T.RANGES} has {len(slot['ranges'])} ranges, "
                                      f"expected {self.obs_dim - 2}")
                return
            obs.extend(m_to_u(r) for r in slot["ranges"])
        reward, terminated = slot["reward"]
        bad = [(name, val) for name, val in zip(self._obs_names(), obs, strict=True)
               if not math.isfinite(val)]
        if not math.isfinite(reward):
            bad.append(("reward", reward))
        if bad:
            what = ", ".join(f"{name}={val!r}" for name, val in bad)
            self._reject_frame(t, f"non-finite reading {what}")
            return
        self._last_frame_wall = self._steady.now()
        if self._t_first is None:
            self._t_first = time.monotonic()
        self.frames += 1
        self._stopped = False
        action, (v, w), records = self.driver.on_frame(np.asarray(obs, dtype=np.float64),
                                                       reward, terminated)
        self._last_t = t
        if action is not None:
            self.ticks += 1
        if records:
            self._explain(records, t)
            every = self.params["progress_every"]
            if self.run_steps // every != (self.run_steps - len(records)) // every:
                self.get_logger().info(
                    f"progress {self.run_steps}/{self.max_steps or '-'} "
                    f"behaviour steps, {self.frames} frames")
            every = self.params["checkpoint_every"]
            if (every and self.params["state_out"]
                    and self.run_steps // every != (self.run_steps - len(records)) // every):
                self._checkpoint()
        c = self._cmd
        set_stamp(c.header.stamp, t)
        c.twist.linear.x = v
        c.twist.angular.z = w
        self._last_answer = serialize_message(c)
        self.pub_cmd.publish(self._last_answer)  # the last one too, as the headless loop
        if self.max_steps and self.run_steps >= self.max_steps:
            self.done = True
            self._t_done = time.monotonic()
            self.get_logger().info(f"{self.driver.behaviour_steps} behaviour steps: done")

    def _obs_names(self) -> list[str]:
        names = ["goal.x", "goal.y"]
        return names + [f"ranges[{i}]" for i in range(self.obs_dim - 2)]

    def _reject_frame(self, t: int, why: str) -> None:
        """A frame with NaN/inf or a wrong number of ranges never reaches the learner; the
        rover stops for that tick."""
        self.rejected_frames += 1
        self.get_logger().error(
            f"frame at stamp {t} ns rejected: {why}; rover stopped, nothing learned from it")
        stop = TwistStamped()
        stop.header.frame_id = "invalid_input"
        set_stamp(stop.header.stamp, t)
        self.pub_cmd.publish(stop)

    @property
    def run_steps(self) -> int:
        """Behaviour steps made in this run (a saved learner starts with some)."""
        return self.driver.behaviour_steps - self.start_steps

    def _watchdog(self) -> None:
        if self._stopped or self._last_t < 0:
            return
        age = (self._steady.now() - self._last_frame_wall).nanoseconds / 1e9
        if age > self.params["watchdog_timeout"]:
            stop = TwistStamped()
            stop.header.frame_id = "watchdog"
            set_stamp(stop.header.stamp, self._last_t)
            self.pub_cmd.publish(stop)
            self._stopped = True
            if not self.done:
                self.get_logger().warn(f"no observation for {age:.2f} s: rover stopped")

    # ---------------------------------------------------------------- explanation
    def _explain(self, records: list, t: int) -> None:
        for rec in records:
            d = record_to_dict(rec)
            d["stamp_ns"] = t
            d["run_step"] = rec.index - self.start_steps  # 0-based within this run
            self.pub_steps.publish(String(data=dumps(d)))
        n = len(records)
        self._since_explain += n
        self._since_markers += n
        if self._since_explain >= self.params["explain_every"]:
            self._since_explain = 0
            info = self._safe_explain()
            if "current_situation" in info:
                self.pub_situation.publish(Int32(data=int(info["current_situation"])))
            plan = info.get("master_plan")
            if plan != self._last_plan:
                self._last_plan = plan
                self.pub_plan.publish(String(data=dumps(
                    {"stamp_ns": t, "step": self.driver.behaviour_steps, "plan": plan,
                     "plan_utility": info.get("plan_utility")})))
        if self._since_markers >= self.params["markers_every"]:
            self._since_markers = 0
            self.pub_markers.publish(situation_markers(self._safe_explain(), t))

    def _safe_explain(self) -> dict:
        try:
            return self.driver.agent.explain(fresh_utilities=False)
        except Exception as e:  # noqa: BLE001 - explanation must never stop the rover
            self.get_logger().warn(f"explain() failed: {e}", throttle_duration_sec=10.0)
            return {}

    def close(self) -> None:
        if self.context.ok():  # finished normally: let the recorder take the last messages
            self.pub_steps.wait_for_all_acked(Duration(seconds=1))
        stats = self.params["stats_out"]
        if stats and self._t_first is not None:
            wall = (self._t_done or time.monotonic()) - self._t_first
            with open(stats, "w") as f:
                json.dump({
                    "wall_seconds": round(wall, 3),
                    "agent_frames": self.frames,
                    "agent_ticks": self.ticks,
                    "agent_behaviour_steps": self.run_steps,
                    "frames_per_second": round(self.frames / wall, 1) if wall > 0 else None,
                    "ticks_per_second": round(self.ticks / wall, 1) if wall > 0 else None,
                    "behaviour_steps_per_second":
                        round(self.run_steps / wall, 1) if wall > 0 else None,
                }, f)
        out = self.params["state_out"]
        if out:
            try:
                self.driver.agent.save(out)
            except OSError as e:  # the disk filled or the folder went: keep the learner anyway
                spare = os.path.join(tempfile.gettempdir(), f"stns_learner_{os.getpid()}.npz")
                self.get_logger().error(f"cannot save the learner to {out}: {e}; saving to {spare}")
                out = spare
                self.driver.agent.save(out)
            self.get_logger().info(f"learner saved to {out}")


    def _checkpoint(self) -> None:
        """Save the learner to state_out now (atomically: a kill mid-save keeps the last one).
        A failing disk is logged, not fatal: the save on shutdown tries again."""
        try:
            self.driver.agent.save(self.params["state_out"])
        except OSError as e:
            self.get_logger().warning(f"checkpoint to {self.params['state_out']} failed: {e}")


def situation_markers(info: dict, t: int) -> MarkerArray:
    """Situations as ellipses (mean and 2-sigma of their goal-sensor inputs, metres) with labels."""
    arr = MarkerArray()
    clear = Marker()
    clear.action = Marker.DELETEALL
    arr.markers.append(clear)
    for i, s in enumerate(info.get("situations", []) or []):
        if not isinstance(s, dict):
            continue
        mean = s.get("mean")
        if mean is None or len(mean) < 2:
            continue
        cov = s.get("cov")
        sx = sy = 2.0
        yaw = 0.0
        if cov is not None:
            c = np.asarray(cov, dtype=float)[:2, :2]
            vals, vecs = np.linalg.eigh(c)
            sx, sy = (2.0 * math.sqrt(max(v, 1e-9)) for v in vals)
            yaw = math.atan2(vecs[1, 0], vecs[0, 0])
        kind = str(s.get("kind", ""))
        color = {"R": (0.1, 0.8, 0.2), "T": (0.2, 0.4, 1.0)}.get(kind, (0.6, 0.6, 0.6))
        for j, mtype in enumerate((Marker.CYLINDER, Marker.TEXT_VIEW_FACING)):
            m = Marker()
            m.header.frame_id = "base_link"
            set_stamp(m.header.stamp, t)
            m.ns = "stns_situations" if j == 0 else "stns_labels"
            m.id = i
            m.type = mtype
            m.action = Marker.ADD
            m.pose.position.x = float(mean[0]) * UNIT_M
            m.pose.position.y = float(mean[1]) * UNIT_M
            m.pose.orientation.z = math.sin(yaw / 2.0)
            m.pose.orientation.w = math.cos(yaw / 2.0)
            if j == 0:
                m.scale.x = 2.0 * sx * UNIT_M
                m.scale.y = 2.0 * sy * UNIT_M
                m.scale.z = 0.01
                m.color.a = 0.35
            else:
                m.scale.z = 0.25
                m.text = f"{s.get('id', i)}{kind}"
                m.color.a = 1.0
            m.color.r, m.color.g, m.color.b = color
            arr.markers.append(m)
    return arr


def _unfinished(node: StnsAgentNode) -> str | None:
    if not node.max_steps:
        return None  # an unlimited run ends by being stopped
    return f"{node.run_steps} of {node.max_steps} behaviour steps made"


def main(args=None) -> None:
    run_node("stns_agent_node", StnsAgentNode, args, done=lambda node: node.done,
             unfinished=_unfinished)


if __name__ == "__main__":
    main()
