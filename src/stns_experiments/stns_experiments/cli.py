"""``stns-experiment``: run one of the paper's experiments headless and write a report folder.

    stns-experiment <exp> [--trial-sets N] [--steps S] [--seed K] [--out DIR]
                          [--jobs J] [--config FILE] [--from DIR] [--set KEY=VALUE ...]

Parameters come from ``config/<exp>.yaml`` of the workspace (the paper's presets; built-in
defaults when the file is absent), then ``--config FILE``, then the options. Bad options or
parameter values exit with code 2 and a message naming the value.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import shlex
import signal
import sys
import threading
from pathlib import Path

from stns_experiments.config import EXPERIMENTS, ExperimentError, merge, nest, parse_set, resolve

log = logging.getLogger("stns_experiments")


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # exit code 2 with usage, never a traceback
        self.print_usage(sys.stderr)
        self.exit(2, f"{self.prog}: error: {message}\n")


def _positive_int(name: str):
    def conv(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be an integer, got {text!r}") from None
        if v < 1:
            raise argparse.ArgumentTypeError(f"{name} must be >= 1, got {text!r}")
        return v
    return conv


def _seed(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--seed must be an integer, got {text!r}") from None
    if v < 0:
        raise argparse.ArgumentTypeError(f"--seed must be >= 0, got {text!r}")
    return v


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="stns-experiment",
                description="Run an experiment of the STNS paper on rover_sim without ROS.")
    p.add_argument("experiment", choices=EXPERIMENTS, metavar="EXP",
                   help="one of: " + ", ".join(EXPERIMENTS))
    p.add_argument("--trial-sets", type=_positive_int("--trial-sets"), help="trial sets (independent learners)")
    p.add_argument("--steps", type=_positive_int("--steps"),
                   help="behaviour steps per trial set (Exp. 2: after the fault)")
    p.add_argument("--seed", type=_seed, help="root seed; trial set i uses SeedSequence([seed, stream]).spawn()[i]")
    p.add_argument("--out", type=Path, help="output folder (default runs/<exp>-seed<K>)")
    p.add_argument("--jobs", type=_positive_int("--jobs"), default=None,
                   help="parallel processes (default: all cores)")
    p.add_argument("--config", type=Path, help="YAML parameter file (default config/<exp>.yaml)")
    p.add_argument("--from", dest="from_dir", type=Path,
                   help="exp2: learner states of an exp1 run (DIR/states); grid: STNS results of an exp1 run")
    p.add_argument("--levels", type=float, nargs="+", help="exp2: fault levels (deg or %% slower)")
    p.add_argument("--set", dest="sets", action="append", default=[], metavar="KEY=VALUE",
                   help="override any parameter, e.g. --set agent.overrides.target_lookahead_ticks=2")
    p.add_argument("--resume", action="store_true",
                   help="reuse the trial sets already finished in --out (sets/*.json), run the rest")
    p.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    p.add_argument("--quiet", action="store_true", help="no progress line")
    return p


def _raise_interrupt(signum, frame) -> None:
    raise KeyboardInterrupt


def _stop_on_sigterm() -> None:
    """SIGTERM (``kill PID``) stops like Ctrl-C: finished trial sets are kept and summarised."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, _raise_interrupt)


def main(args: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if args is None else args)
    ns = build_parser().parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    try:
        overrides: dict = {}
        for item in ns.sets:
            overrides = merge(overrides, nest(*parse_set(item)))
        flags = {"trial_sets": ns.trial_sets, "steps": ns.steps, "seed": ns.seed,
                 "from": ns.from_dir, "levels": ns.levels, "figures": ns.no_figures or None}
        both = [k for k, v in flags.items() if v is not None and k in overrides]
        if both:  # one would silently win, and the other would not even be checked
            k = both[0]
            flag = "--no-figures" if k == "figures" else f"--{k.replace('_', '-')}"
            raise ExperimentError(f"{k} is given twice: --set {k}={overrides[k]!r} and {flag}; "
                                  "give one")
        for key, val in (("trial_sets", ns.trial_sets), ("steps", ns.steps), ("seed", ns.seed)):
            if val is not None:
                overrides[key] = val
        if ns.from_dir is not None:
            if ns.experiment not in ("exp2-sensor", "exp2-actuator", "grid"):
                raise ExperimentError(f"--from applies to exp2-sensor, exp2-actuator and grid, "
                                      f"not {ns.experiment}")
            if not ns.from_dir.is_dir():
                raise ExperimentError(f"--from: no such directory {str(ns.from_dir)!r}")
            overrides["from"] = str(ns.from_dir)
        if ns.levels is not None:
            if not ns.experiment.startswith("exp2"):
                raise ExperimentError(f"--levels applies to exp2 only, not {ns.experiment}")
            overrides["levels"] = [int(v) if float(v).is_integer() else v for v in ns.levels]
        if ns.no_figures:
            overrides["figures"] = False
        if ns.config is not None and not ns.config.is_file():
            raise ExperimentError(f"--config: no such file {str(ns.config)!r}")
        params = resolve(ns.experiment, ns.config, overrides=overrides)
        from stns_experiments.experiments import check_params
        check_params(params)
    except ExperimentError as e:
        sys.stderr.write(f"stns-experiment: error: {e}\n")
        return 2
    out = ns.out or Path("runs") / f"{ns.experiment}-seed{params['seed']}"
    jobs = ns.jobs or os.cpu_count() or 1
    command = "stns-experiment " + shlex.join(argv)
    from stns_experiments.run import RUNNERS, Run
    _stop_on_sigterm()
    try:
        run = Run(params, out, jobs, command, progress=not ns.quiet, resume=ns.resume)
        summary = RUNNERS[ns.experiment](run)
    except ExperimentError as e:
        sys.stderr.write(f"stns-experiment: error: {e}\n")
        return 2
    except KeyboardInterrupt:
        sys.stderr.write("stns-experiment: interrupted\n")
        return 130
    brief = {k: summary.get(k) for k in (
        "experiment", "trial_sets", "steps", "final_behaviours_to_goal", "convergence_step",
        "success_rate_r", "success_rate_t", "within_two_behaviours", "random_arrivals_per_100",
        "situations_final", "wall_seconds", "behaviour_steps_per_second")}
    sys.stdout.write(json.dumps(brief, indent=1, default=str) + "\n")
    sys.stdout.write(f"wrote {out / 'summary.json'}\n")
    if summary.get("errors"):
        sys.stderr.write(f"stns-experiment: {len(summary['errors'])} task(s) failed; see "
                         f"{out / 'summary.json'} (errors)\n")
        return 1
    return 130 if summary.get("interrupted") else 0


if __name__ == "__main__":
    sys.exit(main())
