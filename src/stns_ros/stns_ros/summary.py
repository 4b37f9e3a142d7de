"""A run's figures and plots from its bag alone (used by stns_bringup and stns_replay)."""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from stns_ros import topics as T
from stns_ros.bag import mcap_file, read_messages
from stns_ros.conversion import m_to_u, quaternion_yaw, stamp_ns
from stns_ros.errors import StnsRosError

BLOCK_SIZE = 100


@dataclass
class RunData:
    """The decoded content of a run's bag."""

    config: dict[str, Any] = field(default_factory=dict)
    frames: dict[int, dict[str, Any]] = field(default_factory=dict)  # stamp -> goal/ranges/reward
    cmds: dict[int, tuple[float, float]] = field(default_factory=dict)  # stamp -> (v m/s, w)
    odom: list[tuple[int, float, float, float]] = field(default_factory=list)  # t, x u, y u, yaw
    steps: list[dict[str, Any]] = field(default_factory=list)
    faults: list[dict[str, Any]] = field(default_factory=list)
    counts: dict[str, int] = field(default_factory=dict)
    situations_final: int | None = None


def load_run(bag: str | os.PathLike[str]) -> RunData:
    from geometry_msgs.msg import PointStamped, TwistStamped, Vector3Stamped
    from nav_msgs.msg import Odometry
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import LaserScan
    from std_msgs.msg import String
    from visualization_msgs.msg import Marker, MarkerArray

    run = RunData()
    try:  # topics registered but silent count as 0
        from stns_ros.bag import read_metadata

        for t in read_metadata(bag)["topics_with_message_count"]:
            run.counts[t["topic_metadata"]["name"]] = 0
    except (StnsRosError, KeyError, TypeError, OSError):
        pass
    for m in read_messages(bag):
        run.counts[m.topic] = run.counts.get(m.topic, 0) + 1
        if m.topic == T.GOAL:
            msg = deserialize_message(m.data, PointStamped)
            run.frames.setdefault(stamp_ns(msg.header.stamp), {})["goal"] = (
                msg.point.x, msg.point.y)
        elif m.topic == T.RANGES:
            msg = deserialize_message(m.data, LaserScan)
            run.frames.setdefault(stamp_ns(msg.header.stamp), {})["ranges"] = list(msg.ranges)
        elif m.topic == T.REWARD:
            msg = deserialize_message(m.data, Vector3Stamped)
            run.frames.setdefault(stamp_ns(msg.header.stamp), {})["reward"] = (
                msg.vector.x, msg.vector.y > 0.5, int(msg.vector.z))
        elif m.topic == T.CMD_VEL:
            msg = deserialize_message(m.data, TwistStamped)
            if msg.header.frame_id != "watchdog":
                run.cmds.setdefault(stamp_ns(msg.header.stamp),
                                    (msg.twist.linear.x, msg.twist.angular.z))
        elif m.topic == T.ODOM:
            msg = deserialize_message(m.data, Odometry)
            q = msg.pose.pose.orientation
            run.odom.append((stamp_ns(msg.header.stamp), m_to_u(msg.pose.pose.position.x),
                             m_to_u(msg.pose.pose.position.y),
                             quaternion_yaw(q.x, q.y, q.z, q.w)))
        elif m.topic == T.STEPS:
            run.steps.append(_json_object(bag, m, deserialize_message(m.data, String).data))
            if not isinstance(run.steps[-1].get("index"), int):
                raise StnsRosError(f"bag {str(bag)!r}: the {m.topic} message at "
                                   f"{m.log_time} ns has no integer \"index\"")
        elif m.topic == T.FAULT_EVENTS:
            run.faults.append(_json_object(bag, m, deserialize_message(m.data, String).data))
        elif m.topic == T.RUN_CONFIG and not run.config:
            text = deserialize_message(m.data, String).data
            run.config = _json_object(bag, m, text) if text else {}
        elif m.topic == T.SITUATIONS:
            msg = deserialize_message(m.data, MarkerArray)
            run.situations_final = sum(
                1 for mk in msg.markers if mk.action == Marker.ADD and mk.type == Marker.CYLINDER)
    run.steps.sort(key=lambda d: d["index"])
    for i, d in enumerate(run.steps):
        d.setdefault("run_step", i)
    return run


def _json_object(bag: str | os.PathLike[str], m: Any, text: str) -> dict[str, Any]:
    """The JSON object a std_msgs/String message of the run carries; anything else names the
    bag, the topic and the message's time."""
    try:
        value = json.loads(text)
    except json.JSONDecodeError as e:
        value = e
    if not isinstance(value, dict):
        raise StnsRosError(f"bag {str(bag)!r}: the {m.topic} message at {m.log_time} ns is not "
                           f"a JSON object ({value}): {text[:60]!r}")
    return value


def _ticks(run: RunData) -> int:
    """world.step calls: every frame but the first, and but the new-trial frames that follow
    an answered goal arrival."""
    stamps = sorted(run.frames)
    resets = sum(1 for t in stamps[:-1] if run.frames[t].get("reward", (0, False))[1])
    return max(0, len(stamps) - 1 - resets)


def summarize(run: RunData, bag: str | os.PathLike[str] | None = None) -> dict[str, Any]:
    cfg = run.config
    steps = run.steps
    behaviour_steps = len(steps)
    per_trial: dict[int, int] = {}
    arrivals: list[tuple[int, int]] = []  # (record index, trial)
    for r in steps:
        if r.get("arrival"):
            arrivals.append((r["run_step"], r["trial"]))
        else:
            per_trial[r["trial"]] = per_trial.get(r["trial"], 0) + 1
    blocks: list[float | None] = []
    for b in range(math.ceil(behaviour_steps / BLOCK_SIZE)):
        lo, hi = b * BLOCK_SIZE, (b + 1) * BLOCK_SIZE
        done = [per_trial.get(trial, 0) for idx, trial in arrivals if lo <= idx < hi]
        blocks.append(sum(done) / len(done) if done else None)
    finals = [v for v in blocks[-3:] if v is not None]

    def rate(kind: str) -> float | None:
        planned = [r for r in steps if r.get("planned") and r.get("kind") == kind
                   and r.get("success") is not None]
        return sum(1 for r in planned if r["success"]) / len(planned) if planned else None

    out: dict[str, Any] = {
        "experiment": "ros:" + str(cfg.get("run", {}).get("name", "run")),
        "seed": cfg.get("run", {}).get("seed"),
        "world_seed": cfg.get("world", {}).get("seed"),
        "agent_seed": cfg.get("learner", {}).get("seed"),
        "mode": cfg.get("run", {}).get("mode"),
        "trial_sets": 1,
        "steps": behaviour_steps,
        "frames": len(run.frames),
        "ticks": _ticks(run),
        "arrivals": len(arrivals),
        "block_size": BLOCK_SIZE,
        "behaviours_to_goal_by_block": blocks,
        "final_behaviours_to_goal": sum(finals) / len(finals) if finals else None,
        "success_rate_r": rate("R"),
        "success_rate_t": rate("T"),
        "situations_final": run.situations_final,
        "faults": run.faults,
        "topic_counts": dict(sorted(run.counts.items())),
    }
    if bag is not None:
        size = mcap_file(bag).stat().st_size
        out["bag"] = str(bag)
        out["bag_bytes"] = size
        out["bag_bytes_per_1000_steps"] = round(size * 1000 / behaviour_steps) if behaviour_steps else None
    return out


def write_plots(run: RunData, summary: dict[str, Any], out_dir: str | os.PathLike[str]) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    blocks = summary["behaviours_to_goal_by_block"]
    fig, ax = plt.subplots(figsize=(7, 4))
    xs = [(i + 0.5) * BLOCK_SIZE for i, v in enumerate(blocks) if v is not None]
    ys = [v for v in blocks if v is not None]
    ax.plot(xs, ys, marker="o", ms=3, label="behaviour steps per goal (block mean)")
    for f in run.faults:
        if f.get("applied") and f.get("kind") != "ramp":
            ax.axvline(f["step"], color="tab:red", ls="--", lw=1)
            ax.text(f["step"], max(ys or [1.0]), " " + ", ".join(
                f"{k}={v:g}" for k, v in f["values"].items()), color="tab:red", fontsize=7,
                va="top", rotation=90)
    ax.set_xlabel("behaviour step")
    ax.set_ylabel("behaviour steps to goal")
    ax.set_title(f"{summary['experiment']}: learning curve (from the bag)")
    ax.grid(alpha=0.3)
    if ax.get_legend_handles_labels()[0]:  # a bag without steps or odometry has none
        ax.legend(loc="upper right", fontsize=8)
    p = out / "learning_curve.png"
    fig.tight_layout()
    fig.savefig(p, dpi=110)
    plt.close(fig)
    paths.append(p)

    fig, ax = plt.subplots(figsize=(5, 5))
    room = float(run.config.get("world", {}).get("overrides", {}).get("room_size", 100.0))
    ax.add_patch(plt.Rectangle((0, 0), room, room, fill=False, lw=2))
    if run.odom:
        n = len(run.odom)
        for part, color, alpha, label in ((run.odom[max(0, n - 600):], "tab:blue", 1.0,
                                           "last 600 ticks"),
                                          (run.odom[:600], "tab:gray", 0.6, "first 600 ticks")):
            xs, ys = _break_jumps(part)
            ax.plot(xs, ys, lw=0.8, color=color, alpha=alpha, label=label)
    ax.set_xlim(-5, room + 5)
    ax.set_ylim(-5, room + 5)
    ax.set_aspect("equal")
    ax.set_xlabel("x (u = 1/16 m)")
    ax.set_ylabel("y (u)")
    ax.set_title("rover trajectory (odometry; gaps = re-placed)")
    if ax.get_legend_handles_labels()[0]:  # a bag without steps or odometry has none
        ax.legend(loc="upper right", fontsize=8)
    p = out / "trajectory.png"
    fig.tight_layout()
    fig.savefig(p, dpi=110)
    plt.close(fig)
    paths.append(p)
    return paths


def _break_jumps(odom: list, max_step: float = 4.0) -> tuple[list, list]:
    """x, y lists with a gap (NaN) wherever the rover was placed rather than driven
    (a new trial or a post-collision re-placement)."""
    xs, ys = [], []
    prev = None
    for _, x, y, _ in odom:
        if prev is not None and math.hypot(x - prev[0], y - prev[1]) > max_step:
            xs.append(float("nan"))
            ys.append(float("nan"))
        xs.append(x)
        ys.append(y)
        prev = (x, y)
    return xs, ys


def format_summary(s: dict[str, Any]) -> str:
    def f(v: Any) -> str:
        return "n/a" if v is None else (f"{v:.3f}" if isinstance(v, float) else str(v))

    lines = [
        f"run {s['experiment']} seed={f(s.get('seed'))} mode={f(s.get('mode'))}",
        f"  behaviour steps {s['steps']}, control ticks {s['ticks']} ({s['frames']} frames), "
        f"goal arrivals {s['arrivals']}",
        f"  final behaviour steps to goal {f(s['final_behaviours_to_goal'])}, "
        f"success R {f(s['success_rate_r'])}, T {f(s['success_rate_t'])}, "
        f"situations {f(s['situations_final'])}",
    ]
    for ev in s.get("faults", []):
        lines.append(f"  fault at step {ev.get('step')}: {ev.get('kind')} {ev.get('values')}"
                     + ("" if ev.get("applied") else f" REFUSED: {ev.get('reason')}"))
    if "ticks_per_second" in s:
        lines.append(f"  {f(s['ticks_per_second'])} ticks/s, "
                     f"{f(s['behaviour_steps_per_second'])} behaviour steps/s, "
                     f"{f(s['wall_seconds'])} s wall")
    if "bag_bytes" in s:
        lines.append(f"  bag {s['bag_bytes']} bytes ({f(s['bag_bytes_per_1000_steps'])} per 1000 steps)")
    return "\n".join(lines)


def require_bag(bag: str | os.PathLike[str]) -> Path:
    p = Path(bag)
    if not p.exists():
        raise StnsRosError(f"no bag at {str(p)!r}")
    return p
