"""Orchestration of each experiment: tasks, the parallel run, summary.json and figures."""

from __future__ import annotations

import copy
import dataclasses
import json
import logging
import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from stns_experiments import metrics as M
from stns_experiments import plots
from stns_experiments.config import ExperimentError
from stns_experiments.experiments import (
    PAPER,
    dispatch,
    exp2_level_entry,
    final_level,
    load_agent,
    make_agent_config,
    make_world,
    offline_figures,
    random_summary,
    situations_of,
    summarise_sets,
    world_config,
)
from stns_experiments.pool import read_set, run_folder_of
from stns_experiments.report import read_json
from stns_experiments.runner import (
    changed_files,
    git_state,
    library_hashes,
    outside_libraries,
    run_tasks,
    set_seeds,
    workspace_root,
    write_json,
)

log = logging.getLogger("stns_experiments")

SUMMARY_KEYS = (
    "experiment", "seed", "trial_sets", "steps", "block_size", "behaviours_to_goal_by_block",
    "final_behaviours_to_goal", "convergence_step", "success_rate_r", "success_rate_t",
    "within_two_behaviours", "random_arrivals_per_100", "situations_final", "wall_seconds",
    "behaviour_steps_per_second",
)

STREAM_LEARNER, STREAM_RANDOM, STREAM_SCRATCH, STREAM_FAULT = 0, 1, 2, 3


def _finished(task: dict, path: Path) -> dict:
    """--resume: the result file of a finished task, checked to be that task's result."""
    what = "--resume: finished trial set (move the file away to run the set again)"
    if task["fn"] in ("stns", "exp2"):
        r = read_set(path, what, exp2=task["fn"] == "exp2")
    else:
        r = read_json(path, what)
    if not isinstance(r, dict) or r.get("key") != task["key"]:
        raise ExperimentError(f"{what}: {str(path)!r} is not the result of {task['key']!r}")
    return r


def _results_on_disk(tasks: list[dict], since: float | None = None) -> dict[str, dict]:
    """The result files (sets/<key>.json) of ``tasks`` already written, by key, each checked
    to be that task's result; with ``since``, only files written at or after that time."""
    found: dict[str, dict] = {}
    for t in tasks:
        f = Path(t["out"]) / "sets" / f"{t['key']}.json"
        if f.is_file() and (since is None or f.stat().st_mtime >= since):
            found[t["key"]] = _finished(t, f)
    return found


class Run:
    """One invocation: parameters, output folder, timing, task errors."""

    def __init__(self, params: dict, out: Path, jobs: int, command: str,
                 progress: bool = True, resume: bool = False) -> None:
        self.resume = resume
        self.params, self.out, self.jobs = params, Path(out), max(1, int(jobs))
        self.command, self.progress = command, progress
        self.t0 = time.monotonic()
        self.started = math.floor(time.time())  # result files written since are this run's
        self.sets_loaded = self.sets_run = 0
        self.errors: dict[str, str] = {}
        self.interrupted = False
        # the code as the run starts; finish() hashes the same directories again
        self.code = code_version()
        self.packages = library_packages()
        self.library = library_hashes(self.packages)
        if self.out.exists() and not self.out.is_dir():
            raise ExperimentError(f"--out {str(self.out)!r} is a file, not a folder")
        if (holder := run_folder_of(self.out)) is not None:  # e.g. a typo: --out runs/x/sets
            raise ExperimentError(
                f"--out {str(self.out)!r} is inside the run folder {str(holder)!r}, whose files "
                "are that run's record; choose another --out (nothing was changed)")
        earlier = self._check_earlier_run()
        # the invocations that made the folder before this one (--resume), each with its
        # command, code and time, so that a resume keeps what the earlier ones recorded
        self.earlier_sessions = earlier_sessions(self.out, earlier) if self.resume else []
        try:
            self.out.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise ExperimentError(f"--out {str(self.out)!r}: cannot make the folder: "
                                  f"{e.strerror}") from None

    # parameters a --resume may change: the figures drawn, and more trial sets (set i's seeds
    # do not depend on how many sets there are); fewer are refused
    RESUMABLE = ("figures", "trial_sets")

    def _check_earlier_run(self) -> dict:
        """An earlier run's folder is continued with --resume and the same parameters, never
        written over: a new run there would replace some of its trial sets and leave the rest
        beside the new ones. Returns the earlier config.json ({} when there is none)."""
        cfg = self.out / "config.json"
        sets = sorted((self.out / "sets").glob("*.json")) if (self.out / "sets").is_dir() else []
        if not cfg.is_file() and not sets and not (self.out / "summary.json").is_file():
            return {}
        if not self.resume:
            raise ExperimentError(
                f"--out {str(self.out)!r} holds an earlier run ({len(sets)} result files in sets/"
                f"{', config.json' if cfg.is_file() else ''}); add --resume to continue it with "
                "the same parameters, or choose another --out (nothing was changed)")
        if not cfg.is_file():
            return {}
        earlier = read_json(cfg, "--resume: the earlier run's config")
        old = earlier.get("params") if isinstance(earlier, dict) else None
        if not isinstance(old, dict):
            raise ExperimentError(f"--resume: {str(cfg)!r} holds no 'params' mapping")
        new = json.loads(json.dumps(self.params))
        before = old.get("trial_sets")
        if isinstance(before, int) and new["trial_sets"] < before:
            # the summary would cover the first sets only, beside the others' result files
            raise ExperimentError(
                f"--resume: the run in {str(self.out)!r} holds {before} trial sets; resume it "
                f"with --trial-sets {before} or more, or choose another --out")
        differ = sorted(k for k in set(old) | set(new)
                        if k not in self.RESUMABLE and old.get(k) != new.get(k))
        if differ:
            shown = "; ".join(f"{k}: {old.get(k)!r} (earlier) vs {new.get(k)!r} (now)"
                              for k in differ[:5])
            raise ExperimentError(
                f"--resume: the run in {str(self.out)!r} was made with other parameters: {shown}; "
                "resume it with the same ones, or choose another --out")
        return earlier

    def tasks(self, tasks: list[dict], label: str) -> dict[str, dict]:
        if self.interrupted:
            return {}
        done: dict[str, dict] = {}
        if self.resume:
            done = _results_on_disk(tasks)
            tasks = [t for t in tasks if t["key"] not in done]
            if done:
                log.info("resume: %d finished task(s) loaded, %d to run", len(done), len(tasks))
        res, err, intr = run_tasks(dispatch, tasks, self.jobs, label, self.progress)
        if intr:
            res.update(self._finished_during_stop(tasks, res, err))
        self.sets_loaded += len(done)
        self.sets_run += len(res)
        res = {**done, **res}
        self.errors.update(err)
        self.interrupted = self.interrupted or intr
        for k, e in err.items():
            log.error("task %s failed: %s", k, e)
        return res

    def _finished_during_stop(self, tasks: list[dict], res: dict, err: dict) -> dict[str, dict]:
        """Results of tasks that finished while a stop came: a worker writes its result file
        last (atomically), and the stop can fall before the parent has heard of it; such a
        set is kept as --resume would keep it. Only files written since this run began."""
        found = _results_on_disk([t for t in tasks if t["key"] not in res and t["key"] not in err],
                                 since=self.started)
        if found:
            log.info("stop: %d trial set(s) finished as the stop came, kept", len(found))
        return found

    def task(self, fn: str, key: str, index: int, steps: int, seeds: dict, params=None,
             out: Path | None = None, **extra: Any) -> dict:
        return {"fn": fn, "key": key, "index": index, "steps": int(steps), "seeds": seeds,
                "params": params or self.params, "out": str(out or self.out), **extra}

    def random_tasks(self) -> list[dict]:
        n = self.params["random_steps"]
        if n <= 0:
            return []
        seeds = set_seeds(self.params["seed"], 1, STREAM_RANDOM)[0]
        return [self.task("random", "random", 0, n, seeds)]

    def session(self, finished: bool = False) -> dict[str, Any]:
        """This invocation as ``sessions`` records it: at its start (config.json) the sets it
        will load or run and its time are not known yet (None)."""
        s: dict[str, Any] = {"command": self.command,
                             "started_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ",
                                                          time.gmtime(self.started)),
                             "code_version": self.code, "sets_loaded": None, "sets_run": None,
                             "wall_seconds": None}
        if finished:
            s.update(sets_loaded=self.sets_loaded, sets_run=self.sets_run,
                     wall_seconds=time.monotonic() - self.t0,
                     code_version={**self.code, "changed_during_run": changed_files(
                         self.library, library_hashes(self.packages))})
        return s

    def finish(self, summary: dict, figures: list[str]) -> dict:
        p = self.params
        now = self.session(finished=True)
        sessions = [*self.earlier_sessions, now]
        # the time of every session that made the run (one that stopped before writing its
        # summary is not known, and left out)
        wall = sum(s["wall_seconds"] for s in sessions
                   if isinstance(s.get("wall_seconds"), (int, float))
                   and not isinstance(s.get("wall_seconds"), bool))
        base = {"experiment": p["experiment"], "seed": p["seed"], "trial_sets": p["trial_sets"],
                "steps": p["steps"], "block_size": p["block_size"]}
        summary = {**base, **summary}
        for k in SUMMARY_KEYS:
            summary.setdefault(k, None)
        summary["wall_seconds"] = wall
        summary.update({
            "command": self.command,
            "config_source": p.get("config_source"),
            "final_window": p["final_window"],
            "convergence_definition": (
                f"block rule: first block from which every block's behaviours-to-goal "
                f"(pooled over trial sets) is within {p['convergence_tol']:.0%} of the final "
                f"level (last {p['final_window']} steps); value = steps before that block. "
                f"convergence_step_trailing: first block end from which the trailing "
                f"{p['trailing_window']}-step window stays within the same band."),
            "code_version": now["code_version"],
            "sessions": sessions,
            "interrupted": self.interrupted,
            "errors": self.errors,
            "figures": figures,
            "paper": PAPER.get(p["experiment"].split("-")[0], {}),
        })
        write_json(self.out / "summary.json", summary)
        return summary


def earlier_sessions(out: Path, cfg: dict) -> list[dict[str, Any]]:
    """The sessions of the run in ``out`` that a --resume continues: every one that started
    (``cfg``, its config.json as read by the --resume check), with the sets, time and code
    of those that finished (summary.json). A run
    recorded before sessions were kept counts as one session, its command from config.json
    and its code and time from summary.json (None where it wrote none)."""
    cfg_path, sum_path = out / "config.json", out / "summary.json"
    summ = (read_json(sum_path, "--resume: the earlier run's summary (move it away to resume "
                                "without its record of the earlier sessions)")
            if sum_path.is_file() else {})
    for path, d in ((cfg_path, cfg), (sum_path, summ)):
        if not isinstance(d, dict):
            raise ExperimentError(f"--resume: {str(path)!r} holds no JSON object")
        if not isinstance(d.get("sessions", []), list) or not all(
                isinstance(s, dict) for s in d.get("sessions", [])):
            raise ExperimentError(f"--resume: {str(path)!r}: 'sessions' is not a list of "
                                  f"objects: {str(d.get('sessions'))[:60]}")
    started = cfg.get("sessions")
    if started is None:
        if not cfg and not summ:
            return []
        return [{"command": summ.get("command", cfg.get("command")),
                 "started_utc": None, "code_version": summ.get("code_version"),
                 "sets_loaded": None, "sets_run": None,
                 "wall_seconds": summ.get("wall_seconds")}]
    # the summary's sessions are the config's first ones, complete where the last session to
    # write a summary finished; a later one that stopped is in the config alone
    done = summ.get("sessions", [])
    return [done[i] if i < len(done) else s for i, s in enumerate(started)]


def library_packages() -> dict[str, Path]:
    """The directories the three libraries of a run are imported from."""
    import importlib.util

    packages = {}
    for name in ("stns_core", "rover_sim", "stns_experiments"):
        spec = importlib.util.find_spec(name)
        if spec is not None and spec.origin:
            packages[name] = Path(spec.origin).parent
    return packages


def code_version() -> dict[str, Any]:
    """Git commit of the workspace, the library files that differed from it, and under
    "outside" any library imported from elsewhere (``runner.outside_libraries``). A run
    records it as it starts; its summary adds "changed_during_run", the library files
    (``runner.library_hashes``) that differed between its start and its end."""
    d = workspace_root()
    if d is None:
        return {}
    state = git_state(d, ["src/stns_core", "src/rover_sim", "src/stns_experiments"])
    if state is None:
        return {}
    outside = outside_libraries(d, library_packages())
    if outside:
        state["outside"] = outside
    return state


def _seeds(params: dict, stream: int = STREAM_LEARNER) -> list[dict]:
    return set_seeds(params["seed"], params["trial_sets"], stream)


def _write_config(run: Run, seeds: dict[str, Any]) -> None:
    """Parameters, seeds and the full resolved world and learner configurations."""
    import dataclasses

    from stns_experiments.experiments import _libs, make_agent_config

    rover_sim, _ = _libs()
    w = run.params["world"]
    world_cfg = dataclasses.asdict(rover_sim.WorldConfig.preset(w["preset"], **w["overrides"]))
    agent_cfg = make_agent_config(run.params, 0).to_dict()
    agent_cfg.pop("seed", None)
    write_json(run.out / "config.json", {"params": run.params, "seeds": seeds,
                                         "command": run.command, "world_config": world_cfg,
                                         "agent_config": agent_cfg,
                                         "sessions": [*run.earlier_sessions, run.session()]})


def _sorted(results: dict[str, dict], prefix: str) -> list[dict]:
    return [results[k] for k in sorted(results) if k.startswith(prefix)]


def _safe_figure(figures: list[str], run: Run, fn, *args, **kw) -> None:
    if not run.params["figures"]:
        return
    try:
        (run.out / "figures").mkdir(exist_ok=True)  # here: a refused run leaves none behind
        path = fn(*args, **kw)
        figures.append(str(Path(path).relative_to(run.out)))
    except Exception as e:  # noqa: BLE001 - a failed figure must not lose the results
        name = next((Path(a).name for a in args if isinstance(a, (str, Path))), fn.__name__)
        log.warning("figure %s failed: %s", name, e)
        run.errors[f"figure:{name}"] = str(e)


def _map_from_state(run: Run, state: Path, path: Path, title: str) -> Path:
    agent = load_agent(state)
    return plots.situation_map(path, agent.classify, situations_of(agent), title)


# ---------------------------------------------------------------------------- exp1 / exp3
def run_learning(run: Run) -> dict:
    """Exp. 1 and Exp. 3: trial sets of STNS from scratch, plus the random-policy rate."""
    p = run.params
    seeds = _seeds(p)
    _write_config(run, {"sets": seeds})
    tasks = [run.task("stns", f"set{i:02d}", i, p["steps"], s) for i, s in enumerate(seeds)]
    res = run.tasks(tasks + run.random_tasks(), p["experiment"])
    sets = _sorted(res, "set")
    summary = summarise_sets(sets, p, p["steps"]) if sets else {}
    summary["trial_sets_finished"] = len(sets)
    summary.update(random_summary(_sorted(res, "random")))
    summary["trial_set_seeds"] = seeds
    figures: list[str] = []
    if sets:
        exp = p["experiment"]
        fig_n = "6" if exp == "exp1" else "6 (Exp. 3)"
        _safe_figure(figures, run, plots.curve_figure,
                     run.out / "figures" / f"{exp}_behaviours_to_goal.png",
                     [{"label": f"STNS, {len(sets)} trial sets (IQR band)",
                       "y": summary["behaviours_to_goal_by_block"],
                       "lo": summary["behaviours_to_goal_by_block_q25"],
                       "hi": summary["behaviours_to_goal_by_block_q75"]}],
                     f"{exp}: behaviours to goal by block (Fig. {fig_n}), seed {p['seed']}",
                     p["block_size"], paper_level=PAPER.get(exp, {}).get("final_behaviours_to_goal"),
                     paper_label="paper's final level")
        first = sets[0]["key"]
        state = run.out / "states" / f"{first}.npz"
        if state.exists() and p["world"]["preset"] == "exp1":
            _safe_figure(figures, run, _map_from_state, run, state,
                         run.out / "figures" / f"{exp}_situations_{first}.png",
                         f"{exp}: situations after {p['steps']} steps, trial set {first} (Fig. 5)")
        elif state.exists():
            _safe_figure(figures, run, _workspace_maps, run, state, first)
    return run.finish(summary, figures)


def _workspace_maps(run: Run, state: Path, key: str) -> Path:
    agent = load_agent(state)
    seeds = set_seeds(run.params["seed"], 1, STREAM_RANDOM)[0]
    world = make_world(run.params, seeds["world_seed"])
    try:
        world.reset()
        path = run.out / "figures" / f"exp3_situations_{key}.png"
        plots.workspace_map(path, world, agent.classify, situations_of(agent), 0.0,
                            f"exp3: situations after {run.params['steps']} steps, {key} (Fig. 12)")
    finally:
        world.close()
    return path


# ---------------------------------------------------------------------------- exp2
def _fault(p: dict, level: float) -> tuple[str, float]:
    if p["fault"] == "left_wheel_slowdown_pct":
        return "left_wheel_gain", 1.0 - level / 100.0
    return "goal_sensor_rotation_deg", float(level)


def _level_name(p: dict, level: float) -> str:
    v = f"{level:g}"
    return f"{v}pct" if p["fault"] == "left_wheel_slowdown_pct" else f"{v}deg"


def _check_base_configs(p: dict, states: list[Path]) -> None:
    """--from: a relearning learner continues with the settings it was saved with, while the
    from-scratch learners take this run's; refuse states saved with other agent settings (the
    per-set seed aside) rather than compare two different learners."""
    want = dataclasses.asdict(make_agent_config(p, 0))
    dim = world_config(p).observation_dim
    for st in states:
        agent = load_agent(st)
        if agent.obs_dim != dim:  # else every relearning task dies at its first observation
            raise ExperimentError(
                f"--from: learner state {str(st)!r} takes {agent.obs_dim}-D inputs, but world "
                f"preset {p['world']['preset']!r} gives {dim}-D ones; use states of a run on "
                "the same world")
        got = dataclasses.asdict(agent.config)
        diff = [f"{k}={got.get(k)!r} (state) vs {want[k]!r} (this run)"
                for k in sorted(want) if k != "seed" and got.get(k) != want[k]]
        if diff:
            raise ExperimentError(
                f"--from: learner state {str(st)!r} was saved with other agent settings: "
                f"{'; '.join(diff)}; use the same agent settings, or run without --from")


def run_exp2(run: Run) -> dict:
    """Exp. 2: learners after ``pretrain_steps`` of Exp. 1 continue with a fault; beside
    them, learners from scratch with the fault."""
    p = run.params
    n = p["trial_sets"]
    seeds = _seeds(p)
    base_dir = Path(p["from"]) if p["from"] else run.out / "base"
    base_params = copy.deepcopy(p)
    base_params["block_size"] = 100
    base_results: list[dict] = []
    if p["from"]:
        states = sorted((base_dir / "states").glob("set*.npz"))
        if len(states) < n:
            raise ExperimentError(
                f"--from {str(base_dir)!r}: needs {n} learner states states/set*.npz, "
                f"found {len(states)}")
        for st in states[:n]:
            rj = base_dir / "sets" / (st.stem + ".json")
            if rj.exists():
                base_results.append(read_set(rj, f"--from: pre-training result of {st.name}"))
        _check_base_configs(p, states[:n])
        base_states = [str(s) for s in states[:n]]
    else:
        tasks = [run.task("stns", f"set{i:02d}", i, p["pretrain_steps"], s, params=base_params,
                          out=base_dir) for i, s in enumerate(seeds)]
        res = run.tasks(tasks, f"{p['experiment']} pre-training")
        base_results = _sorted(res, "set")
        base_states = [str(base_dir / "states" / f"{r['key']}.npz") for r in base_results]
    base_final = final_level(base_results)
    relearn_seeds = set_seeds(p["seed"], n, STREAM_FAULT)
    scratch_seeds = set_seeds(p["seed"], n, STREAM_SCRATCH)
    _write_config(run, {"pretrain": seeds, "relearn": relearn_seeds, "scratch": scratch_seeds,
                        "base_states": base_states})
    tasks = []
    for level in p["levels"]:
        name, value = _fault(p, level)
        ln = _level_name(p, level)
        for i, st in enumerate(base_states):
            tasks.append(run.task("exp2", f"{ln}-relearn-{i:02d}", i, p["steps"], relearn_seeds[i],
                                  mode="relearn", level=level, fault_name=name,
                                  fault_value=value, base_state=st))
        if p["scratch"]:
            for i in range(n):
                tasks.append(run.task("exp2", f"{ln}-scratch-{i:02d}", i, p["steps"],
                                      scratch_seeds[i], mode="scratch", level=level,
                                      fault_name=name, fault_value=value))
    res = run.tasks(tasks + run.random_tasks(), p["experiment"])
    levels: dict[str, Any] = {}
    figures: list[str] = []
    all_relearn: list[dict] = []
    for level in p["levels"]:
        ln = _level_name(p, level)
        rl = _sorted(res, f"{ln}-relearn-")
        sc = _sorted(res, f"{ln}-scratch-")
        all_relearn += rl
        entry = exp2_level_entry(level, dict([_fault(p, level)]), rl, sc, p, base_final)
        levels[ln] = entry
        if rl or sc:
            series = []
            if rl:
                series.append({"label": f"relearn after {p['pretrain_steps']} steps ({len(rl)} sets)",
                               "y": entry["relearn"]["behaviours_to_goal_by_block"],
                               "lo": entry["relearn"]["behaviours_to_goal_by_block_q25"],
                               "hi": entry["relearn"]["behaviours_to_goal_by_block_q75"]})
            if sc:
                series.append({"label": f"from scratch with the fault ({len(sc)} sets)",
                               "y": entry["scratch"]["behaviours_to_goal_by_block"],
                               "lo": entry["scratch"]["behaviours_to_goal_by_block_q25"],
                               "hi": entry["scratch"]["behaviours_to_goal_by_block_q75"],
                               "style": "--"})
            fig = "8" if p["fault"].startswith("goal") else "10"
            _safe_figure(figures, run, plots.curve_figure,
                         run.out / "figures" / f"{p['experiment']}_{ln}.png", series,
                         f"{p['experiment']} {ln}: relearning vs scratch (Fig. {fig})",
                         p["block_size"], paper_level=base_final,
                         paper_label="pre-fault level (our Exp. 1 learners)",
                         xlabel="behaviour steps after the fault")
        if rl and p["figures"]:
            st = run.out / "states" / f"{rl[0]['key']}.npz"
            if st.exists():
                fig = "7" if p["fault"].startswith("goal") else "9"
                _safe_figure(figures, run, _map_from_state, run, st,
                             run.out / "figures" / f"{p['experiment']}_{ln}_situations.png",
                             f"{p['experiment']} {ln}: situations {p['steps']} steps after "
                             f"the fault, {rl[0]['key']} (Fig. {fig})")
    panels = []
    for ln, e in levels.items():
        series = [{"label": f"relearn ({k['trial_sets']} sets)" if i == 0 else
                   f"scratch ({k['trial_sets']} sets)",
                   "y": k["behaviours_to_goal_by_block"],
                   "lo": k["behaviours_to_goal_by_block_q25"],
                   "hi": k["behaviours_to_goal_by_block_q75"], "style": "-" if i == 0 else "--"}
                  for i, k in enumerate((e.get("relearn"), e.get("scratch"))) if k]
        if series:
            delay = e.get("delay_steps")
            delay_text = "not reached" if delay is None else f"{delay} steps"
            panels.append({"title": f"{ln}: delay {delay_text}, "
                                    f"eliminated {e.get('eliminated_after_fault_mean', 0):.1f}",
                           "series": series, "level": base_final})
    if panels:
        fig = "8" if p["fault"].startswith("goal") else "10"
        _safe_figure(figures, run, plots.panel_figure,
                     run.out / "figures" / f"{p['experiment']}_all.png", panels,
                     f"{p['experiment']}: relearning after {p['pretrain_steps']} steps vs "
                     f"learning from scratch with the fault (Fig. {fig}), seed {p['seed']}",
                     p["block_size"])
    summary = summarise_sets(all_relearn, p, p["steps"]) if all_relearn else {}
    summary["relearn_runs_pooled"] = summary.pop("trial_sets", 0)
    if base_results:
        base = summarise_sets(base_results, base_params, p["pretrain_steps"])
        summary["prefault"] = {k: base.get(k) for k in (
            "trial_sets", "final_behaviours_to_goal", "convergence_step",
            "convergence_step_trailing", "success_rate_r", "success_rate_t",
            "within_two_behaviours", "situations_final", "set_cpu_seconds_mean",
            "behaviour_steps_per_cpu_second", "set_wall_seconds_mean")}
    summary.update(random_summary(_sorted(res, "random")))
    summary.update({"levels": levels, "pretrain_steps": p["pretrain_steps"],
                    "from": str(base_dir), "prefault_final_behaviours_to_goal": base_final,
                    "top_level_keys_describe": "relearn runs pooled over all fault levels",
                    "trial_set_seeds": {"pretrain": seeds, "relearn": relearn_seeds,
                                        "scratch": scratch_seeds}})
    return run.finish(summary, figures)


# ---------------------------------------------------------------------------- grid
def _reach(results_summary: dict, bs_sum, ar_sum, block: int, thresholds, window: int) -> dict:
    tr = M.trailing_curve(bs_sum, ar_sum, block, window)
    cum_b = np.cumsum(bs_sum)
    out = {}
    for th in thresholds:
        idx = np.nonzero(np.isfinite(tr) & (tr <= th))[0]
        out[f"{th:g}"] = None if len(idx) == 0 else int(cum_b[idx[0]])
    return out


def _group_counts(results: list[dict]) -> tuple[np.ndarray, np.ndarray]:
    bs = np.array([r["block_behaviours"] for r in results], dtype=np.int64).sum(0)
    ar = np.array([r["block_arrivals"] for r in results], dtype=np.int64).sum(0)
    n = max(1, len(results))
    return bs / n, ar / n


THRESHOLDS = (20, 10, 5, 3)


def run_grid(run: Run) -> dict:
    """§7.5: tabular learners on the polar and orthogonal grids beside STNS."""
    p = run.params
    seeds = _seeds(p)
    _write_config(run, {"sets": seeds})
    tasks = []
    for g in p["grids"]:
        for lr in p["learners"]:
            for i, s in enumerate(seeds):
                tasks.append(run.task("grid", f"{g}-{lr}-{i:02d}", i, p["steps"], s, grid=g,
                                      learner=lr))
    stns_results: list[dict] = []
    if p["from"]:
        d = Path(p["from"]) / "sets"
        files = sorted(d.glob("set*.json"))
        if not files:
            raise ExperimentError(f"--from {p['from']!r}: no STNS trial-set results in {str(d)!r}")
        stns_results = [read_set(f, f"--from {p['from']!r}: STNS trial-set result") for f in files]
        if not isinstance(stns_results[0].get("steps"), int):
            raise ExperimentError(f"--from {p['from']!r}: {str(files[0])!r} has no step count")
        cfg_file = Path(p["from"]) / "config.json"
        if cfg_file.is_file():  # compare on the same world: an exp1 run is no 8-D baseline
            cfg = read_json(cfg_file, f"--from {p['from']!r}: run config")
            params = cfg.get("params") if isinstance(cfg, dict) else None
            params = params if isinstance(params, dict) else {}
            world = params.get("world")
            if world is not None and world != p["world"]:
                raise ExperimentError(
                    f"--from {p['from']!r}: its STNS runs are on world {world!r}, this grid "
                    f"run on {p['world']!r}")
            block = params.get("block_size")
            if block is not None and block != p["block_size"]:  # its counts are per its blocks
                raise ExperimentError(
                    f"--from {p['from']!r}: its STNS runs count blocks of {block!r} steps, this "
                    f"grid run of {p['block_size']}; use --set block_size={block!r}")
            seed = params.get("seed")
            if seed is not None and seed != p["seed"]:  # the grids' worlds come from the root seed
                raise ExperimentError(
                    f"--from {p['from']!r}: its STNS runs are of root seed {seed!r}, this grid "
                    f"run of {p['seed']}; use --seed {seed!r}")
        if stns_results[0]["steps"] < p["steps"]:
            raise ExperimentError(
                f"--from {p['from']!r}: STNS runs have {stns_results[0]['steps']} steps, "
                f"fewer than --steps {p['steps']}")
    elif p["compare_stns"]:
        tasks += [run.task("stns", f"stns-{i:02d}", i, p["steps"], s) for i, s in enumerate(seeds)]
    res = run.tasks(tasks + run.random_tasks(), "grid")
    if not p["from"]:
        stns_results = _sorted(res, "stns-")
    groups: dict[str, Any] = {}
    series = []
    B, tw = p["block_size"], p["trailing_window"]
    stns_sum = None
    if stns_results:
        nb = math.ceil(p["steps"] / B)
        trimmed = [dict(r, block_behaviours=r["block_behaviours"][:nb],
                        block_arrivals=r["block_arrivals"][:nb]) for r in stns_results]
        stns_sum = summarise_sets(trimmed, {**p, "block_size": B}, p["steps"])
        bs, ar = _group_counts(trimmed)
        stns_sum["behaviours_needed_to_reach"] = _reach(stns_sum, bs, ar, B, THRESHOLDS, tw)
        series.append({"label": f"STNS ({len(trimmed)} sets)",
                       "y": stns_sum["behaviours_to_goal_by_block"],
                       "lo": stns_sum["behaviours_to_goal_by_block_q25"],
                       "hi": stns_sum["behaviours_to_goal_by_block_q75"]})
    first = None
    for g in p["grids"]:
        for lr in p["learners"]:
            rs = _sorted(res, f"{g}-{lr}-")
            if not rs:
                continue
            s = summarise_sets(rs, p, p["steps"])
            bs, ar = _group_counts(rs)
            s["behaviours_needed_to_reach"] = _reach(s, bs, ar, B, THRESHOLDS, tw)
            s["cells"] = rs[0].get("cells")
            s["cells_visited_mean"] = float(np.mean([r.get("cells_visited", 0) for r in rs]))
            if stns_sum is not None:
                s["ratio_to_stns"] = {
                    th: (None if v is None or stns_sum["behaviours_needed_to_reach"].get(th) in (None, 0)
                         else v / stns_sum["behaviours_needed_to_reach"][th])
                    for th, v in s["behaviours_needed_to_reach"].items()}
                sf = stns_sum["final_behaviours_to_goal"]
                s["final_ratio_to_stns"] = (None if not sf or s["final_behaviours_to_goal"] is None
                                            else s["final_behaviours_to_goal"] / sf)
                st, gt = stns_sum.get("ticks_per_arrival"), s.get("ticks_per_arrival")
                s["ticks_per_arrival_ratio_to_stns"] = None if not st or gt is None else gt / st
            groups[f"{g}-{lr}"] = s
            first = first or s
            series.append({"label": f"{g} grid, {'Q-learning' if lr == 'q' else 'model-based'} "
                                    f"({len(rs)} sets)",
                           "y": s["behaviours_to_goal_by_block"],
                           "lo": s["behaviours_to_goal_by_block_q25"],
                           "hi": s["behaviours_to_goal_by_block_q75"], "style": "--"})
    figures: list[str] = []
    if series:
        _safe_figure(figures, run, plots.curve_figure, run.out / "figures" / "grid_vs_stns.png",
                     series, f"grid baselines vs STNS, world {p['world']['preset']}"
                     f"{', 8-D grids' if p['range_edges'] else ''} (seed {p['seed']})", B)
    summary = {k: v for k, v in (first or {}).items()}
    summary.update(random_summary(_sorted(res, "random")))
    summary.update({"learners": groups, "stns": stns_sum,
                    "top_level_keys_describe": f"{p['grids'][0]}-{p['learners'][0]}",
                    "grid_settings": {k: p[k] for k in ("gamma", "initial_value", "alpha",
                                                        "epsilon", "sweeps", "range_edges")},
                    "stop_rule": "a behaviour stops at any non-zero reward or when the cell "
                                 "changes (or after max_ticks_per_step ticks)",
                    "trial_set_seeds": seeds})
    return run.finish(summary, figures)


# ---------------------------------------------------------------------------- offline
def run_offline(run: Run) -> dict:
    """§7.4: behaviours that random off-line collection needs against STNS on-line."""
    p = run.params
    seeds = _seeds(p)
    _write_config(run, {"sets": seeds})
    tasks = [run.task("offline", f"set{i:02d}", i, p["steps"], s) for i, s in enumerate(seeds)]
    res = run.tasks(tasks + run.random_tasks(), "offline")
    sets = _sorted(res, "set")
    summary = summarise_sets(sets, p, p["steps"]) if sets else {}
    rnd = random_summary(_sorted(res, "random"))
    summary.update(rnd)
    if sets:
        summary.update(offline_figures(sets, rnd.get("random_behaviours_per_arrival")))
        summary["online_steps"] = p["steps"]
    summary["trial_set_seeds"] = seeds
    return run.finish(summary, [])


RUNNERS = {"exp1": run_learning, "exp3": run_learning, "exp2-sensor": run_exp2,
           "exp2-actuator": run_exp2, "grid": run_grid, "offline": run_offline}
