"""Where the behaviours of a span of steps go, per goal arrival.

    python -m stns_experiments.breakdown RUN [RUN ...] [--span A:B ...]
                                         [--level 10deg] [--mode relearn|scratch]

An analysis of the per-step records (docs/RESULTS-LOG.md cites it for Exp. 1's steps 1201-1700
and Exp. 2's first steps after a fault). Every behaviour step is counted by where it started
(the margin, an R-situation or a T-situation) and how it was chosen: *planned* (a plan's
first behaviour, or the next one of a plan going on) or *unplanned* (random, a try); of the
planned ones, those that *missed* their target (the goal, or the situation they aimed at) are
counted apart. Counts are pooled over the trial sets of the runs given and divided by the goal
arrivals in the span, so a span's row adds up to its behaviours per arrival, the figure of
the learning curve, and rows of two spans show what the extra behaviours of the earlier one
were. Steps ``A < step <= B``; Exp. 2 runs count from the fault, for one fault ``--level`` and
one learner ``--mode`` (relearning after pre-training, or from scratch).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from stns_experiments import metrics as M
from stns_experiments.config import ExperimentError
from stns_experiments.report import print_or_fail
from stns_experiments.structure import check_together, positive_int, read_tables, run_params

KINDS = (("0", "margin"), ("R", "R"), ("T", "T"))
ANALYSABLE = ("exp1", "exp3", "exp2-sensor", "exp2-actuator")
MODES = ("relearn", "scratch")
#: Spans when none is given: the first 2000 steps in four, and the final window.
DEFAULT_EARLY = (0, 500, 1000, 1500, 2000)


def counts(tables: list[dict[str, np.ndarray]], start: int, end: int) -> dict[str, int]:
    """Arrivals, behaviours, and per start kind the planned, missed and unplanned behaviours
    over steps ``start < step <= end``, summed over the tables."""
    out = {"arrivals": 0, "behaviours": 0}
    for kind, _ in KINDS:
        for what in ("planned", "missed", "unplanned"):
            out[f"{kind}_{what}"] = 0
    for t in tables:
        span = M.in_span(t, start, end)
        out["arrivals"] += int(np.count_nonzero(span & t["arrival"]))
        beh = span & ~t["arrival"]
        out["behaviours"] += int(np.count_nonzero(beh))
        for kind, _ in KINDS:
            k = beh & (t["kind"] == kind)
            planned = k & t["planned"]
            out[f"{kind}_planned"] += int(np.count_nonzero(planned))
            out[f"{kind}_missed"] += int(np.count_nonzero(planned & (t["success"] == 0)))
            out[f"{kind}_unplanned"] += int(np.count_nonzero(k & ~t["planned"]))
    return out


def per_arrival(c: dict[str, int]) -> dict[str, float | None]:
    """``counts`` divided by the arrivals (None without an arrival); arrivals kept as is."""
    a = c["arrivals"]
    return {k: (v if k == "arrivals" else (v / a if a else None)) for k, v in c.items()}


def parse_span(text: str) -> tuple[int, int]:
    """'A:B' -> (A, B) with 0 <= A < B."""
    parts = text.split(":")
    try:
        if len(parts) != 2:
            raise ValueError
        a, b = int(parts[0]), int(parts[1])
    except ValueError:
        raise ExperimentError(f"a span is A:B in behaviour steps, got {text!r}") from None
    if not 0 <= a < b:
        raise ExperimentError(f"a span A:B needs 0 <= A < B, got {text!r}")
    return a, b


def load(folder: Path, level: str | None, mode: str) -> tuple[list[dict[str, np.ndarray]], int,
                                                               int]:
    """The record tables of a run folder (Exp. 2: of one level and mode), its steps and final
    window."""
    p = run_params(folder, ANALYSABLE, "has no per-step records to break down")
    exp = p["experiment"]
    steps = positive_int(folder, p, "steps")
    fw = positive_int(folder, p, "final_window", 1000)
    if str(exp).startswith("exp2"):
        if level is None:
            raise ExperimentError(f"{str(folder)!r} is an {exp} run: name the fault with "
                                  f"--level (one of the record files' first part, e.g. 10deg)")
        return read_tables(folder, f"{level}-{mode}-*.csv*"), steps, fw
    if level is not None:
        raise ExperimentError(f"--level is for Exp. 2 runs; {str(folder)!r} is an {exp} run")
    return read_tables(folder, "set*.csv*"), steps, fw


def default_spans(steps: int, final_window: int) -> list[tuple[int, int]]:
    edges = [e for e in DEFAULT_EARLY if e < steps] + [min(DEFAULT_EARLY[-1], steps)]
    spans = [(a, b) for a, b in zip(edges, edges[1:], strict=False) if a < b]
    last = (max(0, steps - final_window), steps)
    return spans + ([last] if last not in spans else [])


def _cell(v: float | None) -> str:
    return "-" if v is None else f"{v:.3f}"


def describe(folders: list[Path], spans: list[tuple[int, int]] | None, level: str | None,
             mode: str) -> str:
    """The printed table over the trial sets of ``folders`` taken together."""
    check_together(folders, ANALYSABLE, "has no per-step records to break down")
    tables: list[dict[str, np.ndarray]] = []
    shapes = set()
    for f in folders:
        ts, steps, fw = load(f, level, mode)
        tables += ts
        shapes.add((steps, fw))
    if spans is None:
        if len(shapes) > 1:
            raise ExperimentError(f"the runs have different lengths or final windows "
                                  f"{sorted(shapes)}: give the spans with --span")
        spans = default_spans(*shapes.pop())
    what = f"{level}, {mode}, " if level else ""
    lines = [f"{len(tables)} trial sets ({what}{', '.join(str(f) for f in folders)}); "
             f"behaviours per goal arrival by where they started; planned (missed its target) "
             f"/ unplanned", "",
             "| steps | arrivals | behaviours per arrival | "
             + " | ".join(f"{name}: planned (missed) | {name}: unplanned" for _, name in KINDS)
             + " |",
             "|" + "---|" * (3 + 2 * len(KINDS))]
    for a, b in spans:
        r = per_arrival(counts(tables, a, b))
        cells = [f"{a + 1}-{b}", str(r["arrivals"]), _cell(r["behaviours"])]
        for kind, _ in KINDS:
            cells += [f"{_cell(r[f'{kind}_planned'])} ({_cell(r[f'{kind}_missed'])})",
                      _cell(r[f"{kind}_unplanned"])]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m stns_experiments.breakdown",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", type=Path, help="run folders with per-step records")
    ap.add_argument("--span", action="append", metavar="A:B",
                    help="steps A < step <= B (repeatable; default: steps 1-500, 501-1000, "
                         "1001-1500, 1501-2000 and the final window)")
    ap.add_argument("--level", help="Exp. 2: the fault, as in the record files (e.g. 10deg)")
    ap.add_argument("--mode", choices=MODES, default="relearn",
                    help="Exp. 2: the relearning or the from-scratch learners")
    args = ap.parse_args(argv)

    def text() -> str:
        spans = [parse_span(s) for s in args.span] if args.span else None
        return describe(args.runs, spans, args.level, args.mode)

    return print_or_fail(text)


if __name__ == "__main__":
    sys.exit(main())
