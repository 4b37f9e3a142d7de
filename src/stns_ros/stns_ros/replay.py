"""stns_replay BAG [--rate R] [--verify] [--out DIR]: replay, check and summarise a recorded run.

- Republishes the bag on its topics (``--rate 1`` = the recorded sim-time rate, ``--rate 0``
  = as fast as possible; ``--no-publish`` skips it) for Foxglove, RViz or other nodes.
- ``--verify``: a fresh agent built from the recorded run config (learner, seeds, saved
  state) is fed the recorded frames (observation, reward, terminated) in order; every
  answer must equal the recorded /cmd_vel bit for bit and every finished behaviour step the
  recorded /stns/steps record. Exit 0 with ``verify: OK`` or 1 with the first mismatch.
- Prints the run's summary and writes its plots, from the bag alone.
- A bag whose MCAP file lost its summary (cut short or truncated) fails ``--verify`` with
  how many of the recorded messages are readable; ``--recover`` first rewrites it as a
  complete bag, keeping the original file and metadata.yaml beside as ``<name>.orig``.
"""

from __future__ import annotations

import argparse
import json
import math
import signal
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from stns_ros.bag import Recovery, bag_dir, check_complete, mcap_file
from stns_ros.errors import StnsRosError
from stns_ros.summary import RunData, format_summary, load_run, require_bag, summarize, write_plots


class VerifyError(StnsRosError):
    """The recorded decisions differ from a fresh agent's."""


def _comparable(rec: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in rec.items() if k not in ("stamp_ns", "run_step")}


def _fresh_driver(cfg: dict[str, Any]) -> tuple[Any, int]:
    """The fresh agent (in its driver) and the input size of the recorded run config; a
    config or saved learner it cannot be built from is a VerifyError naming what is wrong."""
    from rover_sim import RoverSimError
    from stns_core import StnsConfig, StnsError
    from stns_ros.driver import AgentDriver, action_velocities, make_agent, observation_dim

    if not cfg:
        raise VerifyError("the bag holds no /stns/run_config: cannot rebuild the agent")
    for section in ("run", "world", "learner"):
        if not isinstance(cfg.get(section), dict):
            raise VerifyError(f"the recorded run config has no {section!r} mapping, got "
                              f"{cfg.get(section)!r}: cannot rebuild the agent")
    if cfg["run"].get("mode") != "lockstep":
        raise VerifyError("only lockstep runs can be verified (free-running may skip frames)")
    world, learner = cfg["world"], cfg["learner"]
    try:  # a hand-edited config: the libraries' messages name the field and the value
        lc = StnsConfig.preset(learner["preset"],
                               **{**learner["overrides"], "seed": learner["seed"]})
        dim = observation_dim(world["preset"], world["overrides"])
        velocities = action_velocities(world["preset"], world["overrides"])
        state_in = learner["state_in"]
    except (KeyError, TypeError, StnsError, RoverSimError) as e:
        raise VerifyError(f"the recorded run config cannot rebuild the agent: "
                          f"{type(e).__name__}: {e}") from None
    if state_in and not Path(state_in).exists():
        raise VerifyError(f"the run started from {state_in!r}, which is gone")
    try:
        agent = make_agent(lc.to_dict(), dim, state_in)
    except (StnsError, StnsRosError) as e:  # damaged or replaced since the run
        raise VerifyError(f"the run started from the saved learner {state_in!r}, which cannot "
                          f"be read now: {e}") from None
    return AgentDriver(agent, velocities), dim


def verify(run: RunData) -> str:
    """Re-run the recorded frames through a fresh agent; raise VerifyError at the first
    difference, return a one-line report when everything matches."""
    from stns_ros.conversion import m_to_u
    from stns_ros.driver import record_to_dict

    driver, dim = _fresh_driver(run.config)
    recorded = [_comparable(r) for r in run.steps]
    target = len(recorded)
    if target == 0:
        raise VerifyError("the bag holds no behaviour steps (/stns/steps)")
    made = 0
    compared_cmds = 0
    for t in sorted(run.frames):
        f = run.frames[t]
        if "goal" not in f or "reward" not in f or (dim == 8 and "ranges" not in f):
            raise VerifyError(f"frame at t={t} ns is incomplete in the bag: {sorted(f)}")
        obs = [m_to_u(f["goal"][0]), m_to_u(f["goal"][1])]
        if dim == 8:
            obs.extend(m_to_u(r) for r in f["ranges"])
        reward, terminated, _ = f["reward"]
        _, cmd, records = driver.on_frame(np.asarray(obs, dtype=np.float64), reward, terminated)
        for rec in records:
            mine = json.loads(json.dumps(record_to_dict(rec)))
            if made >= target:
                break
            if mine != recorded[made]:
                diff = {k: (recorded[made].get(k), mine.get(k)) for k in mine
                        if mine.get(k) != recorded[made].get(k)}
                raise VerifyError(
                    f"behaviour step {made} differs at t={t / 1e9:.1f} s "
                    f"(field: (recorded, fresh agent)): {diff}")
            made += 1
        if t in run.cmds:
            if run.cmds[t] != cmd:
                raise VerifyError(
                    f"command at t={t / 1e9:.1f} s differs: recorded (v={run.cmds[t][0]!r} m/s, "
                    f"w={run.cmds[t][1]!r} rad/s), fresh agent (v={cmd[0]!r}, w={cmd[1]!r})")
            compared_cmds += 1
        elif made < target:
            raise VerifyError(f"no recorded command answers the frame at t={t / 1e9:.1f} s")
        if made >= target:
            break
    if made < target:
        raise VerifyError(f"the bag has {target} behaviour steps, the frames gave only {made}")
    return (f"verify: OK: {made} behaviour steps and {compared_cmds} commands of "
            f"{len(run.frames)} frames identical to a fresh agent's")


def _raise_interrupt(signum, frame) -> None:
    raise KeyboardInterrupt


def republish(bag: Path, rate: float) -> int:
    """Publish every message of the bag on its topic, paced by the recorded log times.
    Ctrl-C and SIGTERM stop it alike, also during a pacing sleep."""
    import rclpy
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from rclpy.signals import SignalHandlerOptions

    from stns_ros import topics as T
    from stns_ros.bag import message_class, read_messages
    from stns_ros.recording import LATCHED_QOS

    # rclpy's own SIGTERM handler only invalidates the context: the replay would sleep on
    # and its next publish die with an RCLError traceback. SIGINT too, as rclpy did, even
    # where it was ignored (a background job)
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    previous = {sig: signal.signal(sig, _raise_interrupt) for sig in (signal.SIGINT, signal.SIGTERM)}
    node = rclpy.create_node("stns_replay")
    pubs: dict[str, Any] = {}
    qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
    n = 0
    try:
        messages = list(read_messages(bag))
        messages.sort(key=lambda m: m.log_time)
        for m in messages:
            if m.topic not in pubs:
                pubs[m.topic] = node.create_publisher(
                    message_class(m.msgtype), m.topic, LATCHED_QOS if m.topic == T.RUN_CONFIG else qos)
        time.sleep(0.5)  # discovery
        t0_bag = messages[0].log_time if messages else 0
        span = (messages[-1].log_time - t0_bag) / 1e9 if messages else 0.0
        sys.stderr.write(
            f"stns_replay: republishing {len(messages)} messages of {span:.0f} s sim time "
            + (f"over {span / rate:.0f} s (--rate {rate:g})" if rate > 0 else "as fast as possible")
            + "; Ctrl-C stops\n")
        t0 = time.monotonic()
        for m in messages:
            if rate > 0:
                delay = (m.log_time - t0_bag) / 1e9 / rate - (time.monotonic() - t0)
                if delay > 0:
                    time.sleep(delay)
            pubs[m.topic].publish(m.data)
            n += 1
    except KeyboardInterrupt:
        pass
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        node.destroy_node()
        rclpy.try_shutdown()
    return n


def resolve_bag(arg: str) -> tuple[Path, Path | None]:
    """(the bag to read, its rosbag2 directory or None for a bare .mcap file). The .mcap file
    of a bag directory is read as that directory, so its metadata.yaml is checked too."""
    bag = require_bag(arg)
    folder = bag_dir(bag)
    if folder is not None and bag.is_file() and mcap_file(folder).samefile(bag):
        bag = folder
    return bag, folder


def default_out(bag: Path, folder: Path | None) -> Path:
    """Beside the bag directory (also for its .mcap file), never inside it: <run>/replay for a
    bring-up run's bag/, else <name>.replay, so that bags kept side by side (bags/a, bags/b)
    do not write over each other's replay."""
    d = (folder or bag).resolve()
    return d.parent / ("replay" if d.name == "bag" else f"{d.name}.replay")


def _incomplete(bag: Path, counts: dict[str, int]) -> str | None:
    """Why the bag is not all there (`check_complete`), a damaged metadata.yaml included:
    that fails --verify too, but need not stop a replay of what is readable."""
    try:
        return check_complete(bag, counts)
    except StnsRosError as e:
        return str(e)


def recovery_report(bag: Path, r: Recovery) -> str:
    """One line saying what `recover` kept, of how much, and where the originals are."""
    kept = ", ".join(str(p) for p in r.originals)
    if not r.rewritten:
        return (f"recover: {bag} is complete ({r.kept} messages), left alone"
                + (f"; the originals of an earlier recovery stay as {kept}" if kept else ""))
    of = (f"of {r.recorded} recorded" if r.recorded is not None
          else "(no metadata.yaml: how many were recorded is unknown)")
    return f"recovered: {r.kept} messages {of} kept in {bag}; the originals are kept as {kept}"


def main(args=None) -> None:
    parser = argparse.ArgumentParser(prog="stns_replay", description=__doc__.splitlines()[0])
    parser.add_argument("bag", help="rosbag2 directory (or .mcap file) of a run")
    parser.add_argument("--rate", type=float, default=1.0,
                        help="replay speed relative to the recorded sim time (0 = as fast as possible)")
    parser.add_argument("--verify", action="store_true",
                        help="check a fresh agent makes the recorded decisions (no republishing)")
    parser.add_argument("--no-publish", action="store_true", help="do not republish")
    parser.add_argument("--recover", action="store_true",
                        help="first rewrite a bag cut short (killed recorder, truncated file) "
                        "into a complete one, keeping the original as <name>.orig")
    parser.add_argument("--out", help="folder for summary.json and plots (default beside the "
                        "bag directory: <run>/replay for a run's bag/, else <name>.replay)")
    ns = parser.parse_args(args)
    try:
        bag, folder = resolve_bag(ns.bag)
        if not math.isfinite(ns.rate) or ns.rate < 0:
            raise StnsRosError(f"--rate must be a finite number >= 0, got {ns.rate}")
        out = Path(ns.out) if ns.out else default_out(bag, folder)
        if folder is not None and out.resolve().is_relative_to(folder.resolve()):
            raise StnsRosError(f"--out {str(out)!r} is inside the bag directory {str(folder)!r}; "
                               "choose a folder outside it")
        if out.resolve() == bag.resolve().parent or (out / "run_config.json").exists():
            # the bring-up's own summary.json and plots are the run's record: keep them
            raise StnsRosError(
                f"--out {str(out)!r} is a run folder (it holds the bag or run_config.json); its "
                "summary.json and plots would be overwritten: choose another folder")
        if out.exists() and not out.is_dir():
            raise StnsRosError(f"--out {str(out)!r} is a file, not a folder")
        if ns.recover:
            from stns_ros.bag import recover

            print(recovery_report(bag, recover(bag)))
        run = load_run(bag)
        problem = _incomplete(bag, run.counts)
        if problem and ns.verify:
            raise VerifyError(problem)  # a part of the recording cannot be checked
        if problem:
            sys.stderr.write(f"stns_replay: warning: {problem}\n")
        summary = summarize(run, bag)
        try:
            out.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise StnsRosError(f"--out {str(out)!r}: cannot make the folder: {e.strerror}") from None
        (out / "summary.json").write_text(json.dumps(summary, indent=2, sort_keys=True))
        plots = write_plots(run, summary, out)
        print(format_summary(summary))
        for p in plots:
            print(f"  plot: {p}")
        if ns.verify:
            print(verify(run))
        elif not ns.no_publish:
            n = republish(bag, ns.rate)
            print(f"republished {n} messages")
    except VerifyError as e:
        print(f"verify: FAILED: {e}")
        sys.exit(1)
    except StnsRosError as e:
        sys.exit(f"stns_replay: error: {e}")


if __name__ == "__main__":
    main()
