"""Markdown tables from run folders, for docs/RESULTS.md.

    python -m stns_experiments.report runs/exp1-full [runs/exp2-sensor ...]

Prints, for each folder, the summary's figures beside the paper's with the exact command
that produced them (taken from summary.json), so the report is never typed by hand.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from stns_experiments.config import EXPERIMENTS, ExperimentError


def read_json(path: Path, what: str) -> Any:
    """The JSON content of a file; a missing or unreadable file is named (with ``what``)."""
    try:
        return json.loads(path.read_text())
    except FileNotFoundError:
        raise ExperimentError(f"{what}: {str(path)!r} does not exist") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise ExperimentError(f"{what}: {str(path)!r} is not readable JSON: {e}") from None


def json_kind(v: Any, limit: int = 60) -> str:
    """A JSON value as an error names it: its kind and its text, cut at ``limit`` characters."""
    if v is None:
        return "null"
    kind = {dict: "an object", list: "a list", str: "a string", bool: "a boolean"}.get(
        type(v), "a number")
    text = json.dumps(v)
    return f"{kind} {text if len(text) <= limit else text[:limit] + '...'}"


def read_object(path: Path, what: str) -> dict[str, Any]:
    """The JSON object of a file; a missing or unreadable file, or one holding another kind
    of JSON value (a list, a number), is named (with ``what``) with what it holds."""
    d = read_json(path, what)
    if not isinstance(d, dict):
        raise ExperimentError(f"{what}: {str(path)!r} holds {json_kind(d)}, not a JSON object")
    return d


def print_or_fail(make_text: Callable[[], str]) -> int:
    """The exit code of a command that prints ``make_text()``: 0, or 2 with an
    ExperimentError written as one "error:" line and nothing printed."""
    try:
        text = make_text()
    except ExperimentError as e:
        sys.stderr.write(f"error: {e}\n")
        return 2
    sys.stdout.write(text)
    return 0


def read_summary(folder: Path) -> dict[str, Any]:
    """A run folder's summary.json, checked to be the summary of one of the experiments."""
    path = folder / "summary.json"
    s = read_object(path, "run summary")
    exp = s.get("experiment")
    if exp not in EXPERIMENTS:
        raise ExperimentError(
            f"run summary: {str(path)!r} is not the summary of an experiment (its "
            f"\"experiment\" is {exp!r}; expected one of {', '.join(EXPERIMENTS)})")
    return s


class _NotAFigure(ValueError):
    """A summary value printed as a number that is not one (a hand edit): `describe` names
    its key."""

    def __init__(self, value: Any) -> None:
        super().__init__(f"{json_kind(value)}, not a number or null")
        self.value = value


def _figure(v: Any) -> Any:
    """``v`` if it is a number or None (a boolean is neither: it would print as 100 %)."""
    if v is not None and (isinstance(v, bool) or not isinstance(v, int | float)):
        raise _NotAFigure(v)
    return v


def _keys_of(d: Any, value: Any, prefix: str = "") -> list[str]:
    """The dotted keys of every entry of ``d`` (nested objects too) holding ``value``: the
    first alone could be another entry of the same value (a true flag beside a true rate)."""
    if not isinstance(d, dict):
        return []
    keys = []
    for k, v in d.items():
        if type(v) is type(value) and v == value:
            keys.append(f"{prefix}{k}")
        keys += _keys_of(v, value, f"{prefix}{k}.")
    return keys


def _pct(v) -> str:
    return "-" if _figure(v) is None else f"{100 * v:.1f} %"


def _num(v, nd: int = 2) -> str:
    if _figure(v) is None:
        return "-"
    if isinstance(v, int):
        return str(v)
    return f"{v:.{nd}f}"


def learning_table(s: dict) -> str:
    paper = s.get("paper", {})
    rows = [
        ("convergence (block rule), steps", _num(paper.get("convergence_step")),
         _num(s.get("convergence_step"))),
        ("convergence (trailing 500-step rule), steps", "-", _num(s.get("convergence_step_trailing"))),
        ("convergence per set, median (block / trailing)", "-",
         f"{_num(s.get('convergence_step_per_set_median'), 0)} / "
         f"{_num(s.get('convergence_step_trailing_per_set_median'), 0)}"),
        (f"behaviours to goal, last {s.get('final_window')} steps",
         _num(paper.get("final_behaviours_to_goal")), _num(s.get("final_behaviours_to_goal"))),
        ("success from R situations", _pct(paper.get("success_rate_r")), _pct(s.get("success_rate_r"))
         + _counts(s.get("success_counts_r"))),
        ("success from T situations", _pct(paper.get("success_rate_t")), _pct(s.get("success_rate_t"))
         + _counts(s.get("success_counts_t"))),
    ]
    if "success_rate_t2" in s or "success_rate_t2" in paper:
        rows += [("success from T situations 2 steps from goal", _pct(paper.get("success_rate_t2")),
                  _pct(s.get("success_rate_t2"))),
                 ("success from T situations 3 steps from goal", _pct(paper.get("success_rate_t3")),
                  _pct(s.get("success_rate_t3")))]
    rows += [
        ("trials within two behaviours", _pct(paper.get("within_two_behaviours")),
         _pct(s.get("within_two_behaviours")) + _counts(s.get("within_two_counts"))),
        ("random policy: goal arrivals per 100 steps", _num(paper.get("random_arrivals_per_100")),
         _num(s.get("random_arrivals_per_100"))),
        ("situations at the end (mean)", "6 (optimum, Fig. 5b)" if s["experiment"] == "exp1" else "-",
         _num(s.get("situations_final"), 1)),
    ]
    if s.get("ticks_per_arrival") is not None:
        rows.append((f"control ticks per goal arrival, last {s.get('final_window')} steps / "
                     f"whole run", "-", f"{_num(s.get('final_ticks_per_arrival'), 1)} / "
                     f"{_num(s.get('ticks_per_arrival'), 1)}"))
    if s.get("first_extraction_behaviours_mean") is not None:
        rows.append(("first situation extracted after (behaviours, mean)",
                     _num(paper.get("first_situation_behaviours"), 1),
                     _num(s.get("first_extraction_behaviours_mean"), 1)))
    if s.get("first_situation_step_mean") is not None:
        rows.append(("first step started in a situation (mean)", "-",
                     _num(s.get("first_situation_step_mean"), 1)))
    rows.append(("speed: behaviour steps per second per process (wall, shared CPU)", "-",
                 _num(s.get("behaviour_steps_per_second"), 0)))
    if s.get("set_cpu_seconds_mean") is not None:
        rows.append((f"speed: CPU seconds per {s.get('steps')}-step trial set (one core)", "-",
                     _num(s.get("set_cpu_seconds_mean"), 1)))
    head = "| what | paper | measured |\n|---|---|---|\n"
    return head + "\n".join(f"| {a} | {b} | {c} |" for a, b, c in rows)


def _counts(c) -> str:
    return "" if not c else f" ({c[0]}/{c[1]})"


def exp2_table(s: dict) -> str:
    head = ("| fault | relearn: final | scratch: final | relearn reaches scratch level at | "
            "scratch at | delay (steps) | blocks worse than pre-fault | situations eliminated "
            "(mean) | sets without elimination | pre-fault situations gone (mean of) |\n"
            "|---|---|---|---|---|---|---|---|---|---|\n")
    rows = []
    for name, e in s.get("levels", {}).items():
        rl, sc = e.get("relearn", {}), e.get("scratch", {})
        rows.append(
            f"| {name} | {_num(rl.get('final_behaviours_to_goal'))} | "
            f"{_num(sc.get('final_behaviours_to_goal'))} | {_num(e.get('relearn_reaches_at'))} | "
            f"{_num(e.get('scratch_reaches_at'))} | {_num(e.get('delay_steps'))} | "
            f"{_num(e.get('blocks_worse_than_prefault'))} of {len(rl.get('behaviours_to_goal_by_block', []))} | "
            f"{_num(e.get('eliminated_after_fault_mean'), 1)} | "
            f"{e.get('sets_without_elimination', '-')}/{rl.get('trial_sets', '-')} | "
            f"{_num(e.get('original_situations_gone_mean'), 1)} of "
            f"{_num(e.get('situations_before_mean'), 1)} |")
    return head + "\n".join(rows)


def grid_table(s: dict) -> str:
    th = list((s.get("stns") or {}).get("behaviours_needed_to_reach", {}))
    cols = ["learner", "final behaviours to goal", "final, x STNS",
            "control ticks per arrival, final / whole run", "cells visited"]
    cols += [f"behaviours to reach {t}" for t in th]
    head = "| " + " | ".join(cols) + " |\n|" + "---|" * len(cols) + "\n"
    rows = []
    groups = dict(s.get("learners", {}))
    if s.get("stns"):
        groups = {"STNS": s["stns"], **groups}
    for name, g in groups.items():
        need = g.get("behaviours_needed_to_reach", {})
        ratio = g.get("ratio_to_stns", {})
        cells = g.get("cells")
        visited = "-" if cells is None else f"{_num(g.get('cells_visited_mean'), 0)}/{cells}"
        final_ratio = g.get("final_ratio_to_stns")
        cells_row = [name, _num(g.get("final_behaviours_to_goal")),
                     "-" if final_ratio is None else f"{final_ratio:.1f}",
                     f"{_num(g.get('final_ticks_per_arrival'), 1)} / "
                     f"{_num(g.get('ticks_per_arrival'), 1)}"
                     + (f" (x{g['ticks_per_arrival_ratio_to_stns']:.1f})"
                        if g.get("ticks_per_arrival_ratio_to_stns") else ""), visited]
        cells_row += [_num(need.get(t)) + (f" (x{ratio[t]:.1f})" if ratio.get(t) else "")
                      for t in th]
        rows.append("| " + " | ".join(cells_row) + " |")
    return head + "\n".join(rows)


def offline_table(s: dict) -> str:
    def lower(flag: str) -> str:
        return " (lower bound)" if s.get(flag) else ""

    rows = [
        ("on-line steps (STNS)", "1200", _num(s.get("online_steps"))),
        ("on-line behaviours (mean)", "967.9", _num(s.get("online_behaviours_mean"), 1)),
        ("R positives, summed over the R-situations (mean per set)", "225.5",
         _num(s.get("positives_r_sum_mean"), 1)),
        ("T positives, summed over the T-situations (mean per set)", "212.7",
         _num(s.get("positives_t_sum_mean"), 1)),
        ("R / T situations (mean per set)", "-",
         f"{_num(s.get('situations_r_mean'), 1)} / {_num(s.get('situations_t_mean'), 1)}"),
        ("positives per R / T situation (mean)", "-",
         f"{_num(s.get('positives_r_mean'), 1)} / {_num(s.get('positives_t_mean'), 1)}"),
        ("random behaviours until the sums are collected (mean)", "11694 (estimate)",
         _num(s.get("random_behaviours_totals_mean"), 0)),
        ("ratio, measured on the sums (random / on-line behaviours)", "12.1",
         _num(s.get("ratio_measured_totals"), 1) + lower("ratio_totals_is_lower_bound")),
        ("random behaviours until every situation has its own count (mean)", "-",
         _num(s.get("random_behaviours_mean"), 0)),
        ("ratio, measured per situation", "-",
         _num(s.get("ratio_measured"), 1) + lower("ratio_is_lower_bound")),
        ("ratio by the paper's arithmetic, our rates", "12.1", _num(s.get("ratio_paper_arithmetic"), 1)),
    ]
    head = "| what | paper | measured |\n|---|---|---|\n"
    return head + "\n".join(f"| {a} | {b} | {c} |" for a, b, c in rows)


def describe(folder: Path) -> str:
    """The Markdown section of one run folder: its command and its table."""
    s = read_summary(folder)
    try:
        return _describe(folder, s)
    except _NotAFigure as e:
        raise ExperimentError(f"run summary: {str(folder / 'summary.json')!r}: "
                              f"{' or '.join(_keys_of(s, e.value)) or 'a figure'} holds {e}") from None
    except (AttributeError, IndexError, KeyError, TypeError, ValueError) as e:
        raise ExperimentError(f"run summary: {str(folder / 'summary.json')!r} holds a value "
                              f"of the wrong kind ({type(e).__name__}: {e})") from None


def _describe(folder: Path, s: dict[str, Any]) -> str:
    exp = s["experiment"]
    lines = [f"### {exp}: `{folder}`", "",
             f"Command: `{s.get('command')}` (seed {s.get('seed')}, {s.get('trial_sets')} trial "
             f"sets x {s.get('steps')} steps; wall {s.get('wall_seconds', 0):.0f} s"
             + ("; INTERRUPTED" if s.get("interrupted") else "") + ")", ""]
    if exp in ("exp1", "exp3"):
        lines.append(learning_table(s))
    elif exp.startswith("exp2"):
        lines.append(exp2_table(s))
    elif exp == "grid":
        lines.append(grid_table(s))
    elif exp == "offline":
        lines.append(offline_table(s))
    if s.get("errors"):
        lines += ["", f"Errors: {s['errors']}"]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m stns_experiments.report",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", type=Path, help="run folders (with summary.json)")
    args = ap.parse_args(argv)
    return print_or_fail(lambda: "".join(describe(f) + "\n" for f in args.runs))


if __name__ == "__main__":
    sys.exit(main())
