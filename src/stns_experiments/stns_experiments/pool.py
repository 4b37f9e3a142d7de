"""Pool the trial sets of several runs of one experiment into one larger sample.

    python -m stns_experiments.pool runs/exp3-seed0 runs/exp3-seed1 ... [--json FILE]

Runs made with the same settings on other root seeds (``--seed``), or on other fault levels
of one seed (Exp. 2 ``--levels``), hold different trial sets of the same experiment. This
command takes every trial set of every run once, computes the figures of the run summary on
the union with the same functions (one definition, metrics.py), and prints them as the
report does, with the per-set mean and standard error of the final level and, for long runs,
the level over longer final windows. It refuses runs whose settings differ (other than the
seed, the number of trial sets, the levels and the output options; the recorded, resolved
learner and world configurations are what is compared), a trial set held by two
runs, and runs whose library code differs between their git commits (``--any-code`` to pool
them anyway, named in the output).
"""

from __future__ import annotations

import argparse
import math
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np

from stns_experiments import metrics as M
from stns_experiments import report
from stns_experiments.config import ExperimentError
from stns_experiments.experiments import (
    exp2_level_entry,
    final_level,
    random_summary,
    summarise_sets,
)
from stns_experiments.report import json_kind, read_object
from stns_experiments.runner import workspace_root, write_json

# parameters that may differ between pooled runs: they choose which trial sets a run holds
# or what it writes, not how a trial set is run
FREE_PARAMS = ("seed", "trial_sets", "levels", "from", "figures", "save_states",
               "config_source")
LIBRARY_DIRS = ("src/stns_core/stns_core", "src/rover_sim/rover_sim",
                "src/stns_experiments/stns_experiments")
# modules that only summarise, print or draw finished runs: no trial set runs through them
REPORT_ONLY = ("stns_experiments/pool.py", "stns_experiments/report.py",
               "stns_experiments/plots.py", "stns_experiments/structure.py",
               "stns_experiments/bootstrap.py", "stns_experiments/breakdown.py",
               "stns_experiments/fault_reach.py")
POOLABLE = ("exp1", "exp3", "exp2-sensor", "exp2-actuator")


SET_KEYS = ("key", "block_behaviours", "block_arrivals", "final_behaviours", "final_arrivals")


def _set_files(folder: Path) -> list[Path]:
    return sorted(p for p in (folder / "sets").glob("*.json") if p.stem != "random")


def _is_count(v: Any) -> bool:
    return isinstance(v, int) and not isinstance(v, bool) and v >= 0


# optional fields of a trial-set result (older runs lack some): [successes, tries] pairs,
# counts, and non-negative numbers
PAIR_KEYS = ("success_r", "success_t", "within_two", "success_t2", "success_t3",
             "success_t4plus")
COUNT_KEYS = ("steps", "situations_final", "final_ticks", "run_ticks", "run_arrivals")
NUMBER_KEYS = ("wall_seconds", "cpu_seconds")


def _is_pair(v: Any) -> bool:
    return isinstance(v, list) and len(v) == 2 and all(map(_is_count, v)) and v[0] <= v[1]


def read_set(path: Path, what: str, exp2: bool = False, steps: int | None = None,
             block_size: int | None = None) -> dict:
    """A trial set's result file (sets/*.json) of an STNS learner, checked: its block and
    final counts (and for Exp. 2 its mode and level) are there and are counts, its optional
    figures have their kinds, and with ``block_size`` its blocks cover its steps (its own
    ``steps``, else the run's ``steps``)."""
    r = read_object(path, what)
    need = SET_KEYS + (("mode", "level") if exp2 else ())
    missing = [k for k in need if k not in r]
    if missing:
        raise ExperimentError(f"{what}: {str(path)!r} lacks {', '.join(missing)}")
    for k in ("block_behaviours", "block_arrivals"):
        if not isinstance(r[k], list) or not all(_is_count(v) for v in r[k]):
            raise ExperimentError(f"{what}: {str(path)!r}: {k} must be a list of counts, "
                                  f"got {r[k]!r}")
    for k in ("final_behaviours", "final_arrivals"):
        if not _is_count(r[k]):
            raise ExperimentError(f"{what}: {str(path)!r}: {k} must be a count, got {r[k]!r}")
    if exp2 and (isinstance(r["level"], bool) or not isinstance(r["level"], int | float)):
        raise ExperimentError(f"{what}: {str(path)!r}: level must be a number, "
                              f"got {r['level']!r}")
    _check_optional(r, path, what)
    n_bs, n_ar = len(r["block_behaviours"]), len(r["block_arrivals"])
    if n_bs != n_ar:
        raise ExperimentError(f"{what}: {str(path)!r}: block_behaviours holds {n_bs} blocks "
                              f"but block_arrivals {n_ar}")
    n_steps = r.get("steps", steps)
    if _is_count(block_size) and block_size > 0 and _is_count(n_steps):
        want = math.ceil(n_steps / block_size)
        if n_bs != want:
            raise ExperimentError(f"{what}: {str(path)!r}: it holds {n_bs} blocks, the run's "
                                  f"{n_steps} steps in blocks of {block_size} make {want}")
    return r


def _check_optional(r: dict, path: Path, what: str) -> None:
    for k in PAIR_KEYS:
        if k in r and not _is_pair(r[k]):
            raise ExperimentError(f"{what}: {str(path)!r}: {k} must be a pair of counts "
                                  f"[successes, tries], got {r[k]!r}")
    for k in COUNT_KEYS:
        if r.get(k) is not None and not _is_count(r[k]):
            raise ExperimentError(f"{what}: {str(path)!r}: {k} must be a count, got {r[k]!r}")
    for k in NUMBER_KEYS:
        v = r.get(k)
        if v is not None and (isinstance(v, bool) or not isinstance(v, int | float)
                              or not math.isfinite(v) or v < 0):
            raise ExperimentError(f"{what}: {str(path)!r}: {k} must be a number >= 0, "
                                  f"got {v!r}")


def _object_in(d: dict, key: str, path: Path, what: str) -> dict:
    """``d[key]`` of a run file: a JSON object, or {} when absent or null; another kind of
    value is named, as it would fail later where it is read."""
    v = d.get(key)
    if v is None:
        return {}
    if not isinstance(v, dict):
        raise ExperimentError(f"{what}: {str(path)!r}: {key} holds {json_kind(v)}, "
                              f"not a JSON object")
    return v


def load_run(folder: Path) -> dict[str, Any]:
    """A run folder's config, summary and per-set results (and Exp. 2 pre-training sets)."""
    folder = Path(folder)
    cfg_path, summ_path = folder / "config.json", folder / "summary.json"
    cfg = read_object(cfg_path, "run config")
    summ = read_object(summ_path, "run summary")
    for key in ("agent_config", "world_config"):
        _object_in(cfg, key, cfg_path, "run config")
    for key in ("code_version", "paper"):
        _object_in(summ, key, summ_path, "run summary")
    p = _object_in(cfg, "params", cfg_path, "run config")
    exp = p.get("experiment")
    if exp not in POOLABLE:
        raise ExperimentError(f"{str(folder)!r}: experiment {exp!r} cannot be pooled "
                              f"(poolable: {', '.join(POOLABLE)})")
    sets = [read_set(f, "trial-set result", str(exp).startswith("exp2"), p.get("steps"),
                     p.get("block_size")) for f in _set_files(folder)]
    if not sets:
        raise ExperimentError(f"{str(folder)!r}: no trial-set results in sets/")
    n = summ.get("trial_sets")
    if exp in ("exp1", "exp3") and _is_count(n) and n != len(sets):
        # the summary counts the sets it was made from: result files were lost or added since
        raise ExperimentError(f"{str(folder)!r}: its summary.json counts {n} trial sets but "
                              f"sets/ holds {len(sets)} result files")
    run = {"folder": folder, "params": p, "config": cfg, "summary": summ, "sets": sets,
           "random": None, "base_dir": None, "base_sets": []}
    rnd = folder / "sets" / "random.json"
    if rnd.exists():
        run["random"] = read_object(rnd, "random-policy result")
    if exp.startswith("exp2"):
        base = Path(p["from"]) if p.get("from") else folder / "base"
        if not base.is_absolute() and not base.exists():
            # --from is recorded as given, relative to where the run was started
            base = folder.resolve().parent.parent / base
        run["base_dir"] = base.resolve()
        # pre-training ran in blocks of its own run's size: only the run's own blocks checked
        run["base_sets"] = [read_set(f, "pre-training result") for f in _set_files(base)]
    return run


def _agent_defaults() -> dict[str, Any]:
    """The learner's option defaults. A setting missing from an older run's config.json is an
    option added later, whose default is, by the project's rule, the learner as it was."""
    try:
        from stns_core import StnsConfig
    except ImportError:  # pragma: no cover - depends on the workspace build
        return {}
    return StnsConfig().to_dict()


def _comparable(run: dict) -> dict[str, Any]:
    p = {k: v for k, v in run["params"].items() if k not in FREE_PARAMS}
    recorded = run["config"].get("agent_config") or {}
    agent = {k: v for k, v in {**_agent_defaults(), **recorded}.items() if k != "seed"}
    world_rec = run["config"].get("world_config") or {}
    world = {k: v for k, v in world_rec.items() if k != "seed"}
    # Where the resolved configuration is recorded it decides, not how it was given: an
    # option set to its default with --set is the same learner as one left out.
    if recorded:
        p.pop("agent", None)
    if world_rec:
        p.pop("world", None)
    return {"params": p, "agent_config": agent, "world_config": world}


def _flat(d: Any, prefix: str = "") -> dict[str, Any]:
    if not isinstance(d, dict):
        return {prefix.rstrip("."): d}
    out: dict[str, Any] = {}
    for k, v in d.items():
        out.update(_flat(v, f"{prefix}{k}."))
    return out


def check_same_settings(runs: list[dict]) -> None:
    """Refuse runs whose settings differ in anything but the free parameters."""
    exps = {str(r["folder"]): r["params"]["experiment"] for r in runs}
    if len(set(exps.values())) > 1:  # named first: every other setting differs with it
        raise ExperimentError("cannot pool runs of different experiments: " + ", ".join(
            f"{f!r} is {e}" for f, e in exps.items()))
    ref = _flat(_comparable(runs[0]))
    for run in runs[1:]:
        got = _flat(_comparable(run))
        for k in sorted(set(ref) | set(got)):
            if ref.get(k) != got.get(k):
                raise ExperimentError(
                    f"cannot pool {str(runs[0]['folder'])!r} and {str(run['folder'])!r}: "
                    f"setting {k} is {ref.get(k)!r} in the first and {got.get(k)!r} in the "
                    f"second")


def _unique(runs: list[dict], key: str, label: str) -> list[dict]:
    """Every trial set once: (root seed, task key) must not be held by two runs."""
    seen: dict[tuple, Path] = {}
    out = []
    for run in runs:
        for r in run[key]:
            k = (run["params"]["seed"], r["key"])
            if k in seen:
                raise ExperimentError(
                    f"{label} {r['key']} of root seed {k[0]} is in both {str(seen[k])!r} and "
                    f"{str(run['folder'])!r}: pooling would count it twice")
            seen[k] = run["folder"]
            out.append(r)
    return out


def library_changes(commits: list[str], cwd: Path | None = None) -> list[str] | None:
    """Library files that differ between the first commit and each other one (git), the
    report-only modules aside, or None when git cannot tell (no repository, unknown commit)."""
    commits = [c for c in dict.fromkeys(commits) if c]
    cwd = cwd or workspace_root()  # where the runs' commits were recorded
    changed: list[str] = []
    for other in commits[1:]:
        try:
            res = subprocess.run(["git", "diff", "--name-only", commits[0], other, "--",
                                  *LIBRARY_DIRS], cwd=cwd, capture_output=True, text=True,
                                 timeout=30)
        except (OSError, subprocess.SubprocessError):
            return None
        if res.returncode != 0:
            return None
        changed += [ln for ln in res.stdout.splitlines()
                    if ln.endswith(".py") and not ln.endswith(REPORT_ONLY)]
    return sorted(set(changed))


def set_code_versions(summary: dict) -> list[dict]:
    """The code versions a run's trial sets may have run on: that of each of its sessions
    (``sessions``: a --resume adds one) but those that ran no set; a session whose code is
    not recorded gives {}. A run written before sessions were kept: its ``code_version``."""
    sessions = summary.get("sessions")
    if not isinstance(sessions, list) or not sessions:
        return [summary.get("code_version") or {}]
    versions = [s.get("code_version") if isinstance(s, dict) else None
                for s in sessions if not (isinstance(s, dict) and s.get("sets_run") == 0)]
    return [v if isinstance(v, dict) else {} for v in versions]


def code_note(runs: list[dict], any_code: bool) -> str:
    versions = [v for r in runs for v in set_code_versions(r["summary"])]
    commits = [v.get("commit") for v in versions]
    dirty = sorted({f for v in versions for f in v.get("uncommitted", [])
                    if f.endswith(".py") and f.startswith(LIBRARY_DIRS)
                    and not f.endswith(REPORT_ONLY)})
    if not all(commits):
        note = "code: a run has no recorded commit"
    else:
        changed = library_changes(commits)
        named = ", ".join(dict.fromkeys(commits))
        if changed is None:
            note = f"code: commits {named} (git cannot compare them here)"
        elif changed:
            if not any_code:
                raise ExperimentError(
                    f"the runs ran on different library code (commits {named}; changed: "
                    f"{', '.join(changed)}); pass --any-code to pool them anyway")
            note = f"code: commits {named}; POOLED ACROSS LIBRARY CHANGES in {', '.join(changed)}"
        else:
            note = (f"code: commits {named}, the same library code "
                    f"(git diff of {', '.join(LIBRARY_DIRS)})")
    if dirty:
        note += f"; uncommitted library files at run time: {', '.join(dirty)}"
    during = changed_during_note(runs)
    if during:
        if not any_code:
            raise ExperimentError(
                f"library files changed while a run was going ({during}), so its trial sets "
                f"may have run on different code; pass --any-code to pool it anyway")
        note += f"; LIBRARY CHANGED DURING A RUN: {during}"
    outside = outside_note(runs)
    if outside:
        if not any_code:
            raise ExperimentError(
                f"a run used library code from outside its workspace ({outside}), so its "
                f"commit does not name the code; pass --any-code to pool it anyway")
        note += f"; LIBRARIES FROM OUTSIDE THE WORKSPACE: {outside}"
    return note


def changed_during_note(runs: list[dict]) -> str:
    """The library files (report-only modules aside) that changed between a run's start and
    its end (``code_version``'s "changed_during_run"), per run, or ''. Runs recorded before
    the start was read hold no such list."""
    parts = []
    for r in runs:
        files = sorted({f for v in set_code_versions(r["summary"])
                        for f in v.get("changed_during_run") or [] if not f.endswith(REPORT_ONLY)})
        if files:
            parts.append(f"{r['folder']}: {', '.join(files)}")
    return "; ".join(parts)


def outside_note(runs: list[dict]) -> str:
    """The libraries the runs imported from outside their workspace (``code_version``'s
    "outside"), one entry per run and library, or ''."""
    parts: list[str] = []
    for r in runs:
        for v in set_code_versions(r["summary"]):
            for name, o in sorted((v.get("outside") or {}).items()):
                o = o if isinstance(o, dict) else {}
                what = f"commit {o['commit']}" if o.get("commit") else "no git commit"
                if o.get("uncommitted"):
                    what += f", uncommitted {', '.join(map(str, o['uncommitted']))}"
                parts.append(f"{r['folder']}: {name} from {o.get('path', '?')} ({what})")
    return "; ".join(dict.fromkeys(parts))


def window_levels(results: list[dict], params: dict, steps: int) -> dict[str, float]:
    """Behaviours to goal over the last 1000, 5000 and 10000 steps (those the run holds),
    pooled from the block counts."""
    B = params["block_size"]
    bs = np.array([r["block_behaviours"] for r in results], dtype=np.int64).sum(0)
    ar = np.array([r["block_arrivals"] for r in results], dtype=np.int64).sum(0)
    out = {}
    for w in (params["final_window"], 5000, 10000):
        if w % B == 0 and w <= steps and str(w) not in out:
            n = w // B
            out[str(w)] = float(M.ratio(bs[-n:].sum(), ar[-n:].sum()))
    return out


def per_set_spread(per_set_final: list[float]) -> dict[str, float | None]:
    """Mean and standard error of the trial sets' own final levels."""
    vals = np.array(per_set_final, dtype=float)
    vals = vals[np.isfinite(vals)]
    if len(vals) == 0:
        return {"mean": None, "standard_error": None}
    se = float(vals.std(ddof=1) / math.sqrt(len(vals))) if len(vals) > 1 else None
    return {"mean": float(vals.mean()), "standard_error": se}


def collect(folders: list[Path], any_code: bool = False) -> dict[str, Any]:
    """The trial sets of the runs in ``folders``, each once, after every check of ``pool``:
    ``params`` (the first run's), ``sets``, ``base_sets`` (Exp. 2 pre-training, each once:
    runs of one seed share them), ``levels`` (Exp. 2: level -> (key prefix, relearning sets,
    from-scratch sets)) and ``pooled_from``."""
    if not folders:
        raise ExperimentError("name at least one run folder")
    runs = [load_run(Path(f)) for f in folders]
    seen: set[str] = set()
    for r in runs:
        where = str(r["folder"].resolve())
        if where in seen:
            raise ExperimentError(f"run folder {str(r['folder'])!r} is named twice: its trial "
                                  f"sets would count twice")
        seen.add(where)
    check_same_settings(runs)
    bases: dict[tuple, dict] = {}
    for r in runs:
        for b in r["base_sets"]:
            bases.setdefault((r["params"]["seed"], b["key"]), b)
    sets = _unique(runs, "sets", "trial set")
    levels: dict[float, tuple[str, list[dict], list[dict]]] = {}
    if str(runs[0]["params"]["experiment"]).startswith("exp2"):
        for level in sorted({float(s["level"]) for s in sets}):
            rl = [s for s in sets if float(s["level"]) == level and s.get("mode") == "relearn"]
            sc = [s for s in sets if float(s["level"]) == level and s.get("mode") == "scratch"]
            levels[level] = ((rl or sc)[0]["key"].split("-")[0], rl, sc)
    return {
        "runs": runs, "params": dict(runs[0]["params"]), "sets": sets,
        "base_sets": list(bases.values()), "levels": levels,
        "randoms": {r["params"]["seed"]: r["random"] for r in runs if r["random"]},
        "pooled_from": {"runs": [str(r["folder"]) for r in runs],
                        "root_seeds": sorted({r["params"]["seed"] for r in runs}),
                        "code": code_note(runs, any_code), "any_code": any_code},
    }


def pool(folders: list[Path], any_code: bool = False) -> dict[str, Any]:
    """The pooled summary of the runs in ``folders`` (same keys as a run's summary.json for
    the figures it holds, plus ``pooled_from``)."""
    c = collect(folders, any_code)
    p = c["params"]
    exp, steps = p["experiment"], p["steps"]
    out: dict[str, Any] = {
        "experiment": exp, "steps": steps, "block_size": p["block_size"],
        "final_window": p["final_window"], "pooled_from": c["pooled_from"],
        "paper": c["runs"][0]["summary"].get("paper", {}),
    }
    out.update(random_summary(list(c["randoms"].values())))
    sets = c["sets"]
    if exp in ("exp1", "exp3"):
        out.update(summarise_sets(sets, p, steps))
        out["behaviours_to_goal_last"] = window_levels(sets, p, steps)
        out["final_behaviours_to_goal_per_set_spread"] = per_set_spread(
            out["final_behaviours_to_goal_per_set"])
        return out
    base_sets = c["base_sets"]
    base_final = final_level(base_sets)
    levels: dict[str, Any] = {}
    for level, (name, rl, sc) in c["levels"].items():
        levels[name] = exp2_level_entry(level, (rl or sc)[0].get("fault", {}), rl, sc, p,
                                        base_final)
    out.update({"trial_sets": len(base_sets), "prefault_final_behaviours_to_goal": base_final,
                "levels": levels})
    return out


def describe(s: dict) -> str:
    src = s["pooled_from"]
    lines = [f"### {s['experiment']}: pooled, root seeds {', '.join(map(str, src['root_seeds']))}",
             "", "Command: `python -m stns_experiments.pool "
             + ("--any-code " if src.get("any_code") else "") + " ".join(src["runs"]) + "`", "",
             f"Runs: {', '.join('`' + r + '`' for r in src['runs'])}; {src['code']}.", ""]
    if s["experiment"] in ("exp1", "exp3"):
        lines.append(f"{s['trial_sets']} trial sets x {s['steps']} steps.")
        lines.append("")
        lines.append(report.learning_table(s))
        last = s.get("behaviours_to_goal_last", {})
        spread = s.get("final_behaviours_to_goal_per_set_spread", {})
        lines += ["", "Behaviours to goal over the last " + ", ".join(
            f"{w} steps: {v:.2f}" for w, v in last.items()) + "."]
        if spread.get("mean") is not None:
            se = spread.get("standard_error")
            lines.append(f"Per set, last {s['final_window']} steps: mean {spread['mean']:.2f}"
                         + ("" if se is None else f", standard error {se:.2f}") + ".")
    else:
        level = s.get("prefault_final_behaviours_to_goal")
        lines.append(f"{s['trial_sets']} pre-fault learners (level "
                     f"{'-' if level is None else f'{level:.2f}'}); per level the relearning "
                     f"and from-scratch sets below.")
        lines.append("")
        lines.append(report.exp2_table(s))
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m stns_experiments.pool",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", type=Path, help="run folders of one experiment")
    ap.add_argument("--json", type=Path, help="also write the pooled summary to this file")
    ap.add_argument("--any-code", action="store_true",
                    help="pool runs made on different library code (named in the output)")
    args = ap.parse_args(argv)
    try:
        s = pool(args.runs, any_code=args.any_code)
    except ExperimentError as e:
        sys.stderr.write(f"error: {e}\n")
        return 2
    return print_and_save(describe(s), s, args.json)


def run_folder_of(path: Path) -> Path | None:
    """The run folder ``path`` lies in (an stns-experiment run: config.json beside sets/ or
    summary.json; a bring-up: run_config.json), or None."""
    for d in Path(path).absolute().parents:
        if ((d / "config.json").is_file() and ((d / "sets").is_dir() or (d / "summary.json").is_file())
                or (d / "run_config.json").is_file()):
            return d
    return None


def print_and_save(text: str, data: dict, json_path: Path | None) -> int:
    """Print a report module's tables and, with ``--json``, write its figures as
    summary.json is written (atomic, no bare NaN); the command's exit code."""
    if json_path and (run := run_folder_of(json_path)) is not None:
        # a run's files are its record: pooled figures over its summary.json would lose it
        # (and the run could not be pooled again)
        sys.stderr.write(f"error: --json {str(json_path)!r} is inside the run folder "
                         f"{str(run)!r}; choose a file outside it (nothing was written)\n")
        return 2
    sys.stdout.write(text)
    if json_path:
        try:
            write_json(json_path, data)
        except OSError as e:
            sys.stderr.write(f"error: --json {str(json_path)!r}: {e}\n")
            return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
