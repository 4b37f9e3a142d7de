"""When did each trial set find the situation structure it ends with?

    python -m stns_experiments.structure RUN [RUN ...] [--by 1200] [--span 300]

An analysis of the per-step records of Exp. 1 and Exp. 3 runs (docs/RESULTS-LOG.md, Exp. 1,
"what holds convergence back"). A planned behaviour started in a situation is given a
*start type*: the type of the situation and of what it aimed at, e.g. ``T2>R0`` (a
T-situation of clockwise turns toward an R-situation of forward drives) or ``R0>G`` (an
R-situation of forward drives toward the goal). A situation's type is its kind and the most
frequent behaviour of the latest 10 planned starts made in it (``?`` when none was, ``0``
for the margin). A trial set's *final structure* is the set of start types that make at least
``min_share`` of its planned starts in situations over its last ``final_window`` steps; its
*structure step* is the first step by which every one of them had been used at least once.

The command prints, over all trial sets of the runs given, the quantiles of the structure
step, which final type came last, and the pooled behaviours to goal over the ``span`` steps
after step ``by`` of the sets whose structure was complete by then against the others.
"""

from __future__ import annotations

import argparse
import csv
import sys
from collections import Counter, deque
from pathlib import Path

import numpy as np

from stns_experiments import metrics as M
from stns_experiments import records as R
from stns_experiments.config import ExperimentError
from stns_experiments.report import print_or_fail, read_json

GOAL_TARGET = -1  # records.to_table writes a goal target (None) as -1
ANALYSABLE = ("exp1", "exp3")
TYPE_WINDOW = 10  # planned starts that decide a situation's behaviour in its type


def _modal(recent: deque[int]) -> int:
    """The most frequent behaviour of ``recent``; a tie goes to the latest of them."""
    counts = Counter(recent)
    best = max(counts.values())
    return next(b for b in reversed(recent) if counts[b] == best)


def start_types(table: dict[str, np.ndarray], window: int = TYPE_WINDOW) -> list[str | None]:
    """Start type of every row (None for arrivals, unplanned behaviours and margin starts).

    A situation's type is its kind and the most frequent behaviour of its latest ``window``
    planned starts (so a rare other behaviour the planner picks there, or a T-situation
    recycled to a new behaviour, does not retype it at once)."""
    recent: dict[int, deque[int]] = {}
    kinds: dict[int, str] = {}
    out: list[str | None] = []
    for kind, b, sid, tgt, planned, arrival in zip(
            table["kind"], table["behaviour"], table["situation"], table["target"],
            table["planned"], table["arrival"], strict=True):
        if arrival or not planned or kind not in ("R", "T"):
            out.append(None)
            continue
        sid, tgt = int(sid), int(tgt)
        recent.setdefault(sid, deque(maxlen=window)).append(int(b))
        kinds[sid] = str(kind)
        if tgt == GOAL_TARGET:
            aim = "G"
        elif tgt == 0:
            aim = "0"
        elif tgt in recent:
            aim = f"{kinds[tgt]}{_modal(recent[tgt])}"
        else:
            aim = "?"
        out.append(f"{kind}{_modal(recent[sid])}>{aim}")
    return out


def final_structure(table: dict[str, np.ndarray], types: list[str | None], start: int,
                    min_share: float = 0.02) -> set[str]:
    """Start types making at least ``min_share`` of the typed rows after step ``start``."""
    counts = Counter(t for t, s in zip(types, table["step"], strict=True)
                     if t is not None and s > start)
    total = sum(counts.values())
    return {t for t, n in counts.items() if total and n >= min_share * total}


def first_uses(table: dict[str, np.ndarray], types: list[str | None], wanted: set[str]
               ) -> dict[str, int]:
    """Step of the first occurrence of each type in ``wanted`` (absent if it never occurs)."""
    first: dict[str, int] = {}
    for t, s in zip(types, table["step"], strict=True):
        if t in wanted and t not in first:
            first[t] = int(s)
    return first


def structure_step(first: dict[str, int], wanted: set[str]) -> tuple[int | None, str | None]:
    """(first step by which every type in ``wanted`` has occurred, the type that came last)
    from ``first_uses``; (None, None) when one never occurs or ``wanted`` is empty."""
    if not wanted or set(first) != wanted:
        return None, None
    last = max(first, key=lambda t: (first[t], t))
    return first[last], last


def analyse_set(table: dict[str, np.ndarray], final_window: int, min_share: float = 0.02
                ) -> dict:
    """Final structure, structure step and last type of one trial set's records, and the
    final R type used last of the R types ("late R") with the step of its first use."""
    n_steps = int(table["step"].max()) if len(table["step"]) else 0
    types = start_types(table)
    wanted = final_structure(table, types, n_steps - final_window, min_share)
    first = first_uses(table, types, wanted)
    step, last = structure_step(first, wanted)
    r_types = [t for t in first if t.startswith("R")]
    late_r = max(r_types, key=lambda t: (first[t], t)) if r_types else None
    return {"final_types": sorted(wanted), "structure_step": step, "last_type": last,
            "late_r": late_r, "late_r_step": first[late_r] if late_r else None}


def aims_at(start_type: str | None, r_type: str | None) -> bool:
    """Does a T start type aim at the situations of R type ``r_type`` (``T2>R0``, ``R0>G``)?"""
    return bool(start_type and r_type and start_type.startswith("T")
                and start_type.split(">")[1] == r_type.split(">")[0])


def split_levels(tables: list[dict[str, np.ndarray]], steps: list[int | None], by: int,
                 span: int) -> dict:
    """Pooled behaviours to goal over steps (by, by + span] of the sets complete by ``by``
    and of the others, with the number of sets in each group."""
    out = {}
    for name, keep in (("complete", lambda s: s is not None and s <= by),
                       ("incomplete", lambda s: s is None or s > by)):
        counts = [M.span_counts(t, by, by + span)
                  for t, s in zip(tables, steps, strict=True) if keep(s)]
        b, a = sum(c[0] for c in counts), sum(c[1] for c in counts)
        out[name] = {"sets": len(counts), "behaviours_to_goal": M.finite_or_none(
            M.ratio(b, a).item())}
    return out


def read_tables(folder: Path, pattern: str) -> list[dict[str, np.ndarray]]:
    """The record files ``records/<pattern>`` of a run folder, read; a clear error when there
    are none or one is not a readable record file."""
    files = sorted((Path(folder) / "records").glob(pattern))
    if not files:
        raise ExperimentError(f"{str(folder)!r}: no per-step records records/{pattern}")
    _check_every_set_recorded(Path(folder), pattern, files)
    tables = []
    for f in files:
        try:
            tables.append(R.read_csv(f))
        except (OSError, EOFError, ValueError, KeyError, IndexError, csv.Error) as e:
            raise ExperimentError(f"{str(f)!r}: not a readable record file: {e}") from None
    return tables


def _check_every_set_recorded(folder: Path, pattern: str, files: list[Path]) -> None:
    """A trial set with a result (sets/<key>.json) has its records/<key>.csv.gz too: the
    analysis of the others alone would print their figures as the run's."""
    recorded = {f.name.split(".")[0] for f in files}
    for result in sorted((folder / "sets").glob(pattern.replace(".csv*", ".json"))):
        if result.stem not in recorded:
            raise ExperimentError(
                f"{str(folder)!r}: records/{result.stem}.csv.gz is missing, but "
                f"sets/{result.stem}.json holds that trial set's result; without its records "
                "the figures would leave it out")


def run_params(folder: Path, analysable: tuple[str, ...], refusal: str) -> dict:
    """The recorded parameters of a run folder whose experiment is one of ``analysable``;
    otherwise a clear error, saying the experiment ``refusal`` (e.g. "has no structure
    analysis")."""
    folder = Path(folder)
    if not (folder / "config.json").is_file():
        raise ExperimentError(f"{str(folder)!r}: no config.json (not a run folder)")
    cfg = read_json(folder / "config.json", "run config")
    params = (cfg.get("params") if isinstance(cfg, dict) else None) or {}
    if params.get("experiment") not in analysable:
        raise ExperimentError(f"{str(folder)!r}: experiment {params.get('experiment')!r} "
                              f"{refusal} (only {', '.join(analysable)})")
    return params


def check_together(folders: list[Path], analysable: tuple[str, ...], refusal: str) -> None:
    """Refuse run folders whose trial sets cannot be taken together, as pool does: one named
    twice (its sets would count twice), or runs of different experiments."""
    seen: set[Path] = set()
    first: tuple[Path, str] | None = None
    for folder in folders:
        where = Path(folder).resolve()
        if where in seen:
            raise ExperimentError(f"run folder {str(folder)!r} is named twice: its trial sets "
                                  f"would count twice")
        seen.add(where)
        exp = run_params(folder, analysable, refusal)["experiment"]
        if first is None:
            first = (folder, exp)
        elif exp != first[1]:
            raise ExperimentError(f"cannot take runs of different experiments together: "
                                  f"{str(first[0])!r} is {first[1]}, {str(folder)!r} is {exp}")


def positive_int(folder: Path, params: dict, name: str, default: int | None = None) -> int:
    """The run parameter ``name`` (``default`` when absent), which must be a positive int."""
    v = params.get(name, default)
    if isinstance(v, bool) or not isinstance(v, int) or v < 1:
        raise ExperimentError(f"{str(folder)!r}: {name} must be a positive integer, got {v!r}")
    return v


def load_tables(folder: Path) -> tuple[list[dict[str, np.ndarray]], int]:
    """The record tables of an Exp. 1 or Exp. 3 run folder and its final window."""
    params = run_params(folder, ANALYSABLE, "has no structure analysis")
    tables = read_tables(folder, "set*.csv*")
    return tables, positive_int(folder, params, "final_window", 1000)


def describe(folders: list[Path], by: int, span: int, min_share: float) -> str:
    """The printed analysis of the trial sets of ``folders`` taken together."""
    check_together(folders, ANALYSABLE, "has no structure analysis")
    tables: list[dict[str, np.ndarray]] = []
    results = []
    for folder in folders:
        ts, fw = load_tables(folder)
        tables += ts
        results += [analyse_set(t, fw, min_share) for t in ts]
    steps = [r["structure_step"] for r in results]
    found = np.array([s for s in steps if s is not None], dtype=float)
    lines = [f"{len(results)} trial sets of {', '.join(str(f) for f in folders)}"]
    kinds = Counter(len(r["final_types"]) for r in results)
    lines.append("start types in the final structure (sets): "
                 + ", ".join(f"{k}: {n}" for k, n in sorted(kinds.items())))
    if len(found):
        q = np.quantile(found, [0.1, 0.25, 0.5, 0.75, 0.9])
        lines.append("structure step, quantiles 10/25/50/75/90 %: "
                     + " / ".join(f"{v:.0f}" for v in q)
                     + f"; never complete: {len(steps) - len(found)}")
    last = Counter(r["last_type"] for r in results if r["last_type"])
    lines.append("last type to appear: " + ", ".join(f"{t} {n}" for t, n in last.most_common()))
    late = [r for r in results if r["structure_step"] is not None and r["late_r"]]
    into = [r for r in late if aims_at(r["last_type"], r["late_r"])]
    if into:
        gap = np.median([r["structure_step"] - r["late_r_step"] for r in into])
        lines.append(f"the last type aims from a T-situation at the R type used last: "
                     f"{len(into)} of {len(late)} sets; that R type first used at step "
                     f"{np.median([r['late_r_step'] for r in into]):.0f} (median), the "
                     f"structure complete {gap:.0f} steps later (median)")
    split = split_levels(tables, steps, by, span)
    c, i = split["complete"], split["incomplete"]
    lines.append(
        f"behaviours to goal over steps {by + 1}-{by + span}: sets complete by step {by}: "
        f"{c['sets']}, {_num(c['behaviours_to_goal'])}; the others: {i['sets']}, "
        f"{_num(i['behaviours_to_goal'])}")
    return "\n".join(lines) + "\n"


def _num(v: float | None) -> str:
    return "-" if v is None else f"{v:.2f}"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m stns_experiments.structure",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", type=Path, help="Exp. 1 or Exp. 3 run folders")
    ap.add_argument("--by", type=int, default=1200, help="split the sets at this step")
    ap.add_argument("--span", type=int, default=300, help="steps after --by to compare")
    ap.add_argument("--min-share", type=float, default=0.02,
                    help="share of the final planned starts a type needs to count")
    args = ap.parse_args(argv)
    if args.by < 0 or args.span < 1:
        ap.error(f"--by must be >= 0 and --span >= 1, got {args.by} and {args.span}")
    if not 0.0 < args.min_share < 1.0:
        ap.error(f"--min-share must lie in (0, 1), got {args.min_share}")
    return print_or_fail(lambda: describe(args.runs, args.by, args.span, args.min_share))


if __name__ == "__main__":
    sys.exit(main())
