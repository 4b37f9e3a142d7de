"""stns_bringup --config FILE [--steps S] [--out DIR]: one command for a whole ROS run.

Starts every node of the run as its own process (ros2 launch is not on PyPI; the launch file
launch/stns.launch.py does the same for ROS installs), waits until the agent has made the
run's behaviour steps, stops the nodes cleanly (SIGINT: the simulator closes the bag), and
writes the run folder: bag/ (rosbag2, MCAP), summary.json, PNG plots, params.yaml,
run_config.json, learner_state, logs/. Ctrl-C or SIGTERM stops the run early and still
leaves a closed bag and a summary of what was recorded.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

from stns_ros.errors import StnsRosError
from stns_ros.params import MAX_STEPS
from stns_ros.run_config import (
    load_run_config,
    node_parameters,
    unreached_faults,
    write_params_file,
)

RUN_MARK = ".stns_run"
STOP_TIMEOUT = 15.0


def _pdeathsig() -> None:
    """Children die with the bring-up even if it is killed (Linux)."""
    try:
        import ctypes

        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass


def warn(text: str) -> None:
    """A line on stderr about a setting that does not do what it seems to; the run goes on."""
    sys.stderr.write(f"stns_bringup: warning: {text}\n")


class Bringup:
    def __init__(self, cfg: dict, out: Path) -> None:
        self.cfg = cfg
        self.out = out
        self.procs: dict[str, subprocess.Popen] = {}
        self.logs: dict[str, object] = {}
        self.stop_requested = False

    def prepare(self) -> Path:
        out = self.out
        if out.exists():
            if not (out / RUN_MARK).exists():
                raise StnsRosError(
                    f"--out {str(out)!r} exists and is not an stns run folder; not overwriting")
            self._keep_earlier_run()
        try:
            (out / "logs").mkdir(parents=True)
        except OSError as e:
            raise StnsRosError(f"--out {str(out)!r}: cannot make the run folder: {e.strerror}") from None
        (out / RUN_MARK).write_text("stns_bringup run folder (moved aside by the next run here)\n")
        run_json = json.dumps(self.cfg, sort_keys=True)
        (out / "run_config.json").write_text(json.dumps(self.cfg, indent=2, sort_keys=True))
        params, notes = node_parameters(self.cfg, out.resolve(), run_json)
        for note in notes:
            warn(note)
        params["stns_agent"]["stats_out"] = str((out / "agent_stats.json").resolve())
        params["stns_agent"]["wait_for_recorder"] = bool(self.cfg["recording"]["enabled"])
        path = out / "params.yaml"
        write_params_file(params, path)
        return path

    def _keep_earlier_run(self) -> None:
        """Move the earlier bring-up run in --out aside, to ``<out>.<its start time>``: its bag
        and learner are a record (``make run`` twice must not lose the first). A
        ``learner.state_in`` inside it is followed to where it now lies."""
        out = self.out.absolute()  # a name to derive from, also for --out .
        stamp = time.strftime("%Y%m%d-%H%M%S", time.localtime((out / RUN_MARK).stat().st_mtime))
        kept = out.with_name(f"{out.name}.{stamp}")
        n = 1
        while kept.exists():
            kept, n = out.with_name(f"{out.name}.{stamp}-{n}"), n + 1
        state_in = self.cfg["learner"]["state_in"]
        where = Path(state_in).resolve() if state_in else None
        inside = where is not None and where.is_relative_to(out.resolve())
        rel = where.relative_to(out.resolve()) if inside else None
        try:
            out.rename(kept)
        except OSError as e:
            raise StnsRosError(f"--out {str(out)!r}: cannot move the earlier run aside to "
                               f"{str(kept)!r}: {e.strerror}") from None
        if rel is not None:
            self.cfg["learner"]["state_in"] = str(kept.resolve() / rel)
        sys.stderr.write(f"stns_bringup: the earlier run in {str(out)!r} is kept as "
                         f"{str(kept)!r}\n")

    def start(self, name: str, module: str, params: Path) -> None:
        log = open(self.out / "logs" / f"{name}.log", "w")  # noqa: SIM115 - closed in stop_all
        self.logs[name] = log
        self.procs[name] = subprocess.Popen(
            [sys.executable, "-m", f"stns_ros.{module}", "--ros-args", "--params-file", str(params)],
            stdout=log, stderr=subprocess.STDOUT, start_new_session=True, preexec_fn=_pdeathsig,
        )

    def stop(self, name: str) -> int | None:
        proc = self.procs.get(name)
        if proc is None:
            return None
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
            try:
                proc.wait(STOP_TIMEOUT)
            except subprocess.TimeoutExpired:
                proc.terminate()
                try:
                    proc.wait(5)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait()
        return proc.returncode

    def stop_all(self) -> None:
        for name in ("stns_agent", "fault_injector", "rover_sim"):
            self.stop(name)
        for log in self.logs.values():
            log.close()

    def exit_reason(self, name: str) -> str | None:
        """The last line a node wrote about why it ended ("stns_agent_node: ..."), if any."""
        try:
            lines = (self.out / "logs" / f"{name}.log").read_text(errors="replace").splitlines()
        except OSError:
            return None
        prefix = f"{name}_node: "
        found = [ln[len(prefix):] for ln in lines if ln.startswith(prefix)]
        return found[-1] if found else None

    def progress(self, total: int) -> str | None:
        try:
            text = (self.out / "logs" / "stns_agent.log").read_text(errors="replace")
        except OSError:
            return None
        found = re.findall(r"progress (\d+)/(\d+)", text)
        return f"{found[-1][0]}/{total} behaviour steps" if found else None


def run(cfg: dict, out: Path, quiet: bool = False) -> int:
    b = Bringup(cfg, out)
    params = b.prepare()

    def on_signal(signum, frame):  # noqa: ARG001
        b.stop_requested = True

    old = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    rc = 0
    t0 = time.monotonic()
    try:
        b.start("rover_sim", "sim_node", params)
        if cfg["faults"]["faults"]:
            b.start("fault_injector", "fault_injector_node", params)
        b.start("stns_agent", "agent_node", params)
        last_report = 0.0
        while not b.stop_requested:
            agent_rc = b.procs["stns_agent"].poll()
            if agent_rc is not None:
                if agent_rc != 0:
                    rc = 1
                    why = b.exit_reason("stns_agent")
                    sys.stderr.write(f"stns_bringup: stns_agent_node exited with {agent_rc}"
                                     + (f" ({why})" if why else "")
                                     + f"; see {out / 'logs' / 'stns_agent.log'}\n")
                    state = out / "learner_state"
                    if cfg["learner"]["save_state"] and state.exists():
                        sys.stderr.write(f"stns_bringup: its last checkpoint is kept: {state}\n")
                break
            dead = [n for n, p in b.procs.items() if p.poll() is not None]
            if dead:
                rc = 1
                sys.stderr.write(f"stns_bringup: {', '.join(dead)} stopped early; see "
                                 f"{out / 'logs'}\n")
                break
            now = time.monotonic()
            if not quiet and now - last_report > 5.0:
                last_report = now
                p = b.progress(cfg["run"]["steps"])
                if p:
                    sys.stderr.write(f"[stns_bringup] {p}, {now - t0:.0f} s\n")
            time.sleep(0.1)
        if b.stop_requested:
            sys.stderr.write("stns_bringup: stopping on request; the bag is being closed\n")
            rc = 130
        else:
            time.sleep(0.5)  # the last explanation messages reach the recorder
    finally:
        b.stop_all()
        for s, h in old.items():
            signal.signal(s, h)
    return finish(cfg, out, rc, quiet)


def finish(cfg: dict, out: Path, rc: int, quiet: bool) -> int:
    from stns_ros.summary import format_summary, load_run, summarize, write_plots

    bag = out / "bag"
    if not cfg["recording"]["enabled"] or not bag.exists():
        why = "recording is disabled" if not cfg["recording"]["enabled"] else "no bag was written"
        sys.stderr.write(f"stns_bringup: {why}: no bag, no summary\n")
        print(f"run folder: {out}")
        print(f"  logs:     {out / 'logs'}")
        if cfg["learner"]["save_state"] and (out / "learner_state").exists():
            print(f"  learner:  {out / 'learner_state'}")
        return rc or 0
    if not (bag / "metadata.yaml").exists():  # the recorder was killed: keep its prefix
        from stns_ros.bag import recover

        r = recover(bag)
        sys.stderr.write(f"stns_bringup: the bag was cut short; recovered {r.kept} messages "
                         f"(the file as recorded is kept as {r.originals[0]})\n")
    run_data = load_run(bag)
    summary = summarize(run_data, bag)
    stats_path = out / "agent_stats.json"
    if stats_path.exists():
        summary.update(json.loads(stats_path.read_text()))
    (out / "summary.json").write_text(json.dumps(summary, indent=2, sort_keys=True))
    plots = write_plots(run_data, summary, out)
    print(format_summary(summary))
    print(f"run folder: {out}")
    print(f"  bag:      {bag} (play: stns_replay {bag}; ros2 bag info {bag})")
    print(f"  summary:  {out / 'summary.json'}")
    for p in plots:
        print(f"  plot:     {p}")
    return rc


def main(args=None) -> None:
    parser = argparse.ArgumentParser(prog="stns_bringup", description=__doc__.splitlines()[0])
    parser.add_argument("--config", required=True, help="run config YAML (config/default.yaml)")
    parser.add_argument("--steps", type=int, help="behaviour steps (overrides run.steps)")
    parser.add_argument("--out", help="run folder (default runs/<run.name>)")
    parser.add_argument("--quiet", action="store_true", help="no progress lines")
    parser.add_argument("--headless", action="store_true",
                        help="run the same config without ROS (one process) and print its speed")
    ns = parser.parse_args(args)
    try:
        cfg = load_run_config(ns.config)
        if ns.steps is not None:
            if not 1 <= ns.steps <= MAX_STEPS:  # the agent refuses more, once the run started
                raise StnsRosError(f"--steps must be in [1, {MAX_STEPS}], got {ns.steps}")
            cfg["run"]["steps"] = ns.steps
        for text in unreached_faults(cfg):
            warn(text)
        if ns.headless:
            from stns_ros.headless import run_headless

            res = run_headless(cfg)
            print(f"headless {cfg['run']['name']}: {res['behaviour_steps']} behaviour steps, "
                  f"{res['ticks']} ticks in {res['wall_seconds']} s: "
                  f"{res['ticks_per_second']} ticks/s, "
                  f"{res['behaviour_steps_per_second']} behaviour steps/s")
            return
        out = Path(ns.out or os.path.join("runs", cfg["run"]["name"]))
        sys.exit(run(cfg, out, ns.quiet))
    except StnsRosError as e:
        sys.exit(f"stns_bringup: error: {e}")


if __name__ == "__main__":
    main()
