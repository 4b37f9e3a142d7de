"""How many of a converged learner's goal arrivals a fault takes away before it learns anything.

    python -m stns_experiments.fault_reach RUN [RUN ...] [--rotations 10 15 ...]
                                           [--wheel-slower 5 10 ...] [--window 1000]
                                           [--sample N] [--seed K]

Exp. 2 applies its fault to the learner that 10000 steps of Exp. 1 made. Until that learner
changes a situation, it does from a goal-sensor reading what it did from that reading before.
This analysis measures, in rover_sim's pybullet world, how many of those drives still arrive.
Each drive arrival of the last ``window`` steps of an Exp. 1 trial set, or of an Exp. 2
run's pre-training (its ``base`` folder) - a forward or backward behaviour step that reached
the goal - is driven again from the same reading:
the rover is placed so that the sensor, with the fault on, reads the input the record holds
(the goal at its true place in the rover's frame, the sensor rotation undone), and the same
action runs until a reward (the goal, or a wall collision) or ``|x| / tick length + 20``
ticks. The share that arrives is what the pre-fault situations keep of their arrivals at the
fault. Without a fault the share is the replay's own check: the learner's stops aside, it is
the share of recorded arrivals the replay repeats.

The goal is put 15 u from two walls of the room, the rover on the diagonal away from it, so
that a drive of up to 100 u runs clear of the walls until it passes the goal. A straight
drive at a goal read straight ahead under a heading error theta passes it at
``d sin(theta)``, so from beyond ``r / sin(theta)`` (28.8 u at 10 degrees, r = 5) it
misses; that bound is printed beside the measured share.
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from stns_experiments.config import ExperimentError
from stns_experiments.report import print_or_fail
from stns_experiments.structure import check_together, positive_int, read_tables, run_params

ANALYSABLE = ("exp1", "exp2-sensor", "exp2-actuator")
#: Behaviour ids of the two drives (rover_sim.Action.FORWARD, BACKWARD).
DRIVES = (0, 1)
#: Where the replay puts the goal (u), and the direction from it to the rover.
GOAL_AT = (15.0, 15.0)
_AWAY = (math.sqrt(0.5), math.sqrt(0.5))
#: Longest drive replayed (u); `max_distance` lowers it in a smaller room.
MAX_DISTANCE = 100.0
EXTRA_TICKS = 20


@dataclass(frozen=True)
class Fault:
    """One fault of Exp. 2: a goal-sensor rotation (degrees, ccw) or a left-wheel gain."""

    rotation_deg: float = 0.0
    left_wheel_gain: float = 1.0

    @property
    def label(self) -> str:
        if self.rotation_deg:
            return f"sensor {self.rotation_deg:g} deg"
        if self.left_wheel_gain != 1.0:
            return f"left wheel {100.0 * (1.0 - self.left_wheel_gain):.3g} % slower"
        return "no fault"


def drive_arrivals(table: dict[str, np.ndarray], window: int) -> tuple[np.ndarray, np.ndarray]:
    """The inputs (n, 2: the goal sensor's x, y) and behaviour ids of the drive steps among the
    last ``window`` steps of a record table that reached the goal."""
    steps = table["step"]
    last = int(steps.max()) if len(steps) else 0
    # a goal arrival is a record of its own, right after the behaviour that reached the goal
    arrives = np.append(table["arrival"][1:], False)
    keep = (steps > last - window) & arrives & np.isin(table["behaviour"], DRIVES)
    return table["x"][keep, :2].astype(np.float64), table["behaviour"][keep].astype(np.int64)


def placement(x: np.ndarray, rotation_deg: float) -> tuple[float, float, float]:
    """The rover pose (u, u, rad) at which a goal at `GOAL_AT`, read by a sensor rotated by
    ``rotation_deg`` ccw, reads ``x`` (rover frame: x forward, y left)."""
    a = -math.radians(rotation_deg)
    tx = math.cos(a) * x[0] - math.sin(a) * x[1]
    ty = math.sin(a) * x[0] + math.cos(a) * x[1]
    d = math.hypot(tx, ty)
    px, py = GOAL_AT[0] + d * _AWAY[0], GOAL_AT[1] + d * _AWAY[1]
    # the goal lies at world angle atan2(-AWAY) from the rover and at atan2(ty, tx) in its frame
    heading = math.atan2(-_AWAY[1], -_AWAY[0]) - math.atan2(ty, tx)
    return px, py, heading


def replay(world, x: np.ndarray, behaviour: int, fault: Fault) -> bool:
    """Drive ``behaviour`` from reading ``x`` under ``fault`` in ``world`` (a rover_sim
    RoverWorld); True when it reaches the goal. The fault stays set on the world."""
    world.set_fault("goal_sensor_rotation_deg", fault.rotation_deg)
    world.set_fault("left_wheel_gain", fault.left_wheel_gain)
    obs, _ = world.reset(options={"goal": GOAL_AT, "pose": placement(x, fault.rotation_deg)})
    if not np.allclose(obs[:2], x, atol=1e-6):
        raise ExperimentError(f"replay of reading {x.tolist()} under {fault.label}: the placed "
                              f"rover reads {obs[:2].tolist()}")
    tick = world.config.forward_speed * world.config.tick_seconds
    max_ticks = int(math.hypot(*x) / tick) + EXTRA_TICKS
    out = world.run_behaviour(int(behaviour), stop=None, max_ticks=max_ticks)
    return bool(out.terminated)


def miss_distance(rotation_deg: float, goal_radius: float) -> float | None:
    """Distance from which a straight drive at a goal read dead ahead passes it by."""
    s = abs(math.sin(math.radians(rotation_deg)))
    return None if s < 1e-12 else goal_radius / s


def kept_shares(inputs: np.ndarray, behaviours: np.ndarray, dist: np.ndarray,
                faults: list[Fault], world_config) -> list[dict]:
    """For each fault: the drives replayed, those that arrived, and the share kept
    (``dist``: each input's distance to the goal, for the share beyond the miss distance)."""
    import rover_sim

    n = len(inputs)
    rows = []
    with rover_sim.RoverWorld(world_config, seed=0) as world:
        for fault in faults:
            arrived = sum(replay(world, x, b, fault) for x, b in zip(inputs, behaviours,
                                                                       strict=True))
            far = miss_distance(fault.rotation_deg, world_config.goal_radius)
            rows.append({"fault": fault.label, "drives": n, "arrived": arrived,
                         "kept": arrived / n if n else math.nan,
                         "miss_distance": far,
                         "beyond_miss_distance": None if far is None else
                         float(np.mean(dist > far))})
    return rows


def _records_folder(folder: Path, params: dict) -> Path:
    """Where a run keeps the records of its pre-fault learners: an Exp. 2 run in its
    pre-training folder (``base``, or the one its ``--from`` named)."""
    if params["experiment"] == "exp1":
        return folder
    return Path(params["from"]) if params.get("from") else folder / "base"


def _replay_world(folder: Path, params: dict):
    """The run's world, refused where a replayed drive could fail for another reason than the
    fault: an obstacle on its way, a noisy goal sensor, a room too small for the placement."""
    from stns_experiments.experiments import world_config

    w = params.get("world")
    if not (isinstance(w, dict) and isinstance(w.get("preset"), str)
            and isinstance(w.get("overrides"), dict)):
        raise ExperimentError(f"{str(folder)!r}: config.json params.world must be a mapping "
                              f"with a preset name and overrides, got {w!r}")
    cfg = world_config(params)
    if cfg.obstacles:
        raise ExperimentError(f"{str(folder)!r}: its world has {len(cfg.obstacles)} "
                              "obstacle(s); the replay needs the clear room of Exp. 1")
    if cfg.goal_sensor_noise_std:
        raise ExperimentError(f"{str(folder)!r}: its goal sensor has noise (std "
                              f"{cfg.goal_sensor_noise_std!r}); the replay cannot reproduce "
                              "a recorded reading through it")
    if max_distance(cfg) <= cfg.goal_radius:
        raise ExperimentError(f"{str(folder)!r}: its room ({cfg.room_size!r} u) is too small "
                              "for the replay's placement")
    return cfg


def max_distance(cfg) -> float:
    """The longest drive the placement keeps clear of the walls in ``cfg``'s room (u): the
    rover, placed on the diagonal, stays its half-diagonal from the far walls; at most
    `MAX_DISTANCE`."""
    half_diagonal = math.hypot(cfg.rover_length, cfg.rover_width) / 2.0
    room_left = cfg.room_size - GOAL_AT[0] - half_diagonal
    return min(MAX_DISTANCE, math.sqrt(2.0) * room_left)


def describe(folders: list[Path], faults: list[Fault], window: int, sample: int | None,
             seed: int) -> str:
    """The printed shares of the drive arrivals of ``folders`` kept under each fault."""
    check_together(folders, ANALYSABLE, "has no fault-reach analysis")
    xs, bs, config = [], [], None
    read: dict[Path, Path] = {}
    for folder in folders:
        params = run_params(folder, ANALYSABLE, "has no fault-reach analysis")
        final = positive_int(folder, params, "final_window", 1000)
        where = _records_folder(folder, params)
        if where.resolve() in read:
            raise ExperimentError(f"{str(folder)!r} and {str(read[where.resolve()])!r} share "
                                  f"the pre-training {str(where)!r}: its learners would count "
                                  "twice")
        read[where.resolve()] = folder
        cfg = _replay_world(folder, params)
        if config is not None and cfg != config:
            raise ExperimentError(f"{str(folder)!r}: its world differs from the first run's; "
                                  "analyse runs of one world together")
        config = cfg
        for t in read_tables(where, "set*.csv*"):
            x, b = drive_arrivals(t, window or final)
            xs.append(x)
            bs.append(b)
    inputs, behaviours = np.concatenate(xs), np.concatenate(bs)
    total = len(inputs)
    dist = np.hypot(inputs[:, 0], inputs[:, 1])
    keep = dist <= max_distance(config)
    inputs, behaviours, dist = inputs[keep], behaviours[keep], dist[keep]
    sampled = sample is not None and sample < len(inputs)
    if sampled:
        pick = np.sort(np.random.default_rng(seed).choice(len(inputs), sample, replace=False))
        inputs, behaviours, dist = inputs[pick], behaviours[pick], dist[pick]
    if not len(inputs):
        raise ExperimentError("no drive arrivals in the window of the runs given")
    far = int((~keep).sum())
    lines = [f"{total} drive arrivals in the last {window or 'final_window'} steps of "
             f"{', '.join(str(f) for f in folders)}; replayed: {len(inputs)}"
             + (f" ({far} starting beyond {max_distance(config):.1f} u left out)" if far else "")
             + (f" (sampled, seed {seed})" if sampled else "")
             + f"; start distance median {np.median(dist):.1f} u, quartiles "
             f"{np.quantile(dist, 0.25):.1f} / {np.quantile(dist, 0.75):.1f}"]
    for row in kept_shares(inputs, behaviours, dist, faults, config):
        line = (f"{row['fault']}: {row['arrived']} of {row['drives']} arrive "
                f"({100.0 * row['kept']:.1f} %)")
        if row["miss_distance"] is not None:
            line += (f"; {100.0 * row['beyond_miss_distance']:.1f} % start beyond "
                     f"r / sin(theta) = {row['miss_distance']:.1f} u")
        lines.append(line)
    return "\n".join(lines) + "\n"


def parse_faults(rotations: list[float], slower: list[float]) -> list[Fault]:
    """The faults to replay, the healthy rover first."""
    faults = [Fault()]
    for r in rotations:
        if not math.isfinite(r) or not -180.0 <= r <= 180.0 or r == 0.0:
            raise ExperimentError(f"--rotations: {r!r} is not a rotation in [-180, 0) or "
                                  "(0, 180] degrees")
        faults.append(Fault(rotation_deg=float(r)))
    for p in slower:
        if not math.isfinite(p) or not 0.0 < p < 100.0:
            raise ExperimentError(f"--wheel-slower: {p!r} is not a percentage in (0, 100)")
        faults.append(Fault(left_wheel_gain=1.0 - p / 100.0))
    return faults


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m stns_experiments.fault_reach",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", type=Path, help="Exp. 1 or Exp. 2 run folders")
    ap.add_argument("--rotations", nargs="*", type=float, default=[10.0, 15.0, 20.0, 25.0],
                    help="goal-sensor rotations to replay, degrees ccw")
    ap.add_argument("--wheel-slower", nargs="*", type=float, default=[5.0, 10.0, 15.0],
                    help="left wheel slower by these percentages")
    ap.add_argument("--window", type=int, default=0,
                    help="last steps of each set to take (0: the run's final_window)")
    ap.add_argument("--sample", type=int, default=None,
                    help="replay this many drive arrivals, drawn at random")
    ap.add_argument("--seed", type=int, default=0, help="seed of --sample's draw")
    args = ap.parse_args(argv)
    if args.window < 0:
        ap.error(f"--window must be >= 0, got {args.window}")
    if args.sample is not None and args.sample < 1:
        ap.error(f"--sample must be >= 1, got {args.sample}")
    if args.seed < 0:
        ap.error(f"--seed must be >= 0, got {args.seed}")
    return print_or_fail(lambda: describe(args.runs, parse_faults(args.rotations,
                                                                  args.wheel_slower),
                                          args.window, args.sample, args.seed))


if __name__ == "__main__":
    sys.exit(main())
