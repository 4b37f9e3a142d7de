"""The run config of a bring-up (config/default.yaml): loading, validation, node parameters.

::

    run:      {name: default, seed: 7, steps: 3000, mode: lockstep, real_time_factor: 1.0}
    world:    {preset: exp1, overrides: {}, faults: {}, seed: null}
    learner:  {preset: exp1, overrides: {}, seed: null, state_in: "", save_state: true}
    faults:   faults_rotation15.yaml   # path (relative to this file), an inline scenario, or null
    recording: {enabled: true, compression: zstd, chunk_size: 262144}
    nodes:    nodes.yaml               # optional ROS parameter file of the nodes (tuning)

Seeds: ``run.seed`` K gives the world and learner seeds of trial set 0 of
``stns-experiment <exp> --seed K`` (`driver.seeds_from_run_seed`); ``world.seed`` /
``learner.seed`` override them. Every error names the key and the value.
"""

from __future__ import annotations

import copy
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml

from stns_ros.driver import seeds_from_run_seed
from stns_ros.errors import StnsRosError
from stns_ros.faults import (
    FaultScenario,
    load_scenario,
    parse_scenario,
    read_yaml,
)
from stns_ros.params import (
    FAULT_NEUTRAL,
    FAULT_PARAMS,
    MAX_STEPS,
    TUNING,
    check_fault,
    check_tuning,
)

SCHEMA: dict[str, dict[str, Any]] = {
    "run": {"name": "run", "seed": 0, "steps": 3000, "mode": "lockstep", "real_time_factor": 1.0},
    "world": {"preset": "exp1", "overrides": {}, "faults": {}, "seed": None},
    "learner": {"preset": "exp1", "overrides": {}, "seed": None, "state_in": "", "save_state": True},
    "recording": {"enabled": True, "compression": "zstd", "chunk_size": 262144},
}
TOP_KEYS = set(SCHEMA) | {"faults", "nodes"}
NAME_RE = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]*")  # run.name is a folder name under runs/


def _int(key: str, v: Any, lo: int, hi: int | None = None) -> int:
    if isinstance(v, bool) or not isinstance(v, int) or v < lo or (hi is not None and v > hi):
        rng = f">= {lo}" if hi is None else f"in [{lo}, {hi}]"
        raise StnsRosError(f"{key} must be an integer {rng}, got {v!r}")
    return v


def _choice(key: str, v: Any, choices: tuple[str, ...]) -> str:
    if v not in choices:
        raise StnsRosError(f"{key} must be one of {', '.join(choices)}, got {v!r}")
    return v


def _resolve(base: Path, value: str) -> str:
    p = Path(value).expanduser()
    return str(p if p.is_absolute() else (base / p).resolve())


def parse_run_config(data: Any, source: str = "", base_dir: Path | None = None) -> dict[str, Any]:
    """Validate and complete a run config; returns plain data with every default filled in,
    the fault scenario parsed (``faults`` becomes its plain data) and seeds resolved."""
    where = f"{source}: " if source else ""
    base = base_dir or Path.cwd()
    if not isinstance(data, Mapping):
        raise StnsRosError(f"{where}a run config must be a mapping, got {data!r}")
    unknown = sorted(set(data) - TOP_KEYS)
    if unknown:
        raise StnsRosError(f"{where}unknown key(s) {unknown}; known: {sorted(TOP_KEYS)}")
    cfg: dict[str, Any] = {}
    for section, defaults in SCHEMA.items():
        given = data.get(section)
        if given is None:  # an empty section (``run:``) takes the defaults; false or 0 does not
            given = {}
        if not isinstance(given, Mapping):
            raise StnsRosError(f"{where}{section} must be a mapping, got {given!r}")
        extra = sorted(set(given) - set(defaults))
        if extra:
            raise StnsRosError(f"{where}{section}: unknown key(s) {extra}; known: {sorted(defaults)}")
        cfg[section] = {**copy.deepcopy(defaults), **copy.deepcopy(dict(given))}
    try:
        run, world, learner, rec = cfg["run"], cfg["world"], cfg["learner"], cfg["recording"]
        if not isinstance(run["name"], str) or not NAME_RE.fullmatch(run["name"]):
            raise StnsRosError(
                f"run.name must be a plain folder name (letters, digits, '.', '_', '-'; "
                f"--out takes a path), got {run['name']!r}")
        _int("run.seed", run["seed"], 0, 2**32 - 1)
        _int("run.steps", run["steps"], 1, MAX_STEPS)
        _choice("run.mode", run["mode"], ("lockstep", "free_running"))
        rtf = run["real_time_factor"]
        if isinstance(rtf, bool) or not isinstance(rtf, int | float) or not 0.01 <= rtf <= 100:
            raise StnsRosError(f"run.real_time_factor must be in [0.01, 100], got {rtf!r}")
        run["real_time_factor"] = float(rtf)
        _choice("world.preset", world["preset"], ("exp1", "exp3"))
        _choice("learner.preset", learner["preset"], ("exp1", "exp3"))
        for sec in ("world", "learner"):
            if not isinstance(cfg[sec]["overrides"], Mapping):
                raise StnsRosError(f"{sec}.overrides must be a mapping, got {cfg[sec]['overrides']!r}")
            cfg[sec]["overrides"] = dict(cfg[sec]["overrides"])
        if "seed" in learner["overrides"]:  # learner.seed replaces it when the config is built
            raise StnsRosError("learner.overrides.seed is not used: the learner's seed is "
                               "learner.seed (by default from run.seed); set that instead, "
                               f"got {learner['overrides']['seed']!r}")
        if not isinstance(world["faults"], Mapping):
            raise StnsRosError(f"world.faults must be a mapping, got {world['faults']!r}")
        for name, value in world["faults"].items():
            if name not in FAULT_PARAMS:
                raise StnsRosError(f"world.faults.{name}: unknown fault parameter; known: "
                                   f"{', '.join(FAULT_PARAMS)}")
            reason = check_fault(name, value)
            if reason:
                raise StnsRosError(f"world.faults.{name}: {reason}")
        seed_given = learner["seed"] is not None
        ws, ls = seeds_from_run_seed(run["seed"])
        world["seed"] = ws if world["seed"] is None else _int(
            "world.seed", world["seed"], 0, 2**32 - 1)
        learner["seed"] = ls if learner["seed"] is None else _int(
            "learner.seed", learner["seed"], 0, 2**32 - 1)
        if not isinstance(learner["state_in"], str):
            raise StnsRosError(f"learner.state_in must be a path string, got {learner['state_in']!r}")
        if learner["state_in"]:
            learner["state_in"] = _resolve(base, learner["state_in"])
            if not Path(learner["state_in"]).exists():
                raise StnsRosError(f"learner.state_in: no saved learner at {learner['state_in']!r}")
        if not isinstance(learner["save_state"], bool):
            raise StnsRosError(f"learner.save_state must be true or false, got {learner['save_state']!r}")
        if not isinstance(rec["enabled"], bool):
            raise StnsRosError(f"recording.enabled must be true or false, got {rec['enabled']!r}")
        _choice("recording.compression", rec["compression"], ("zstd", "lz4", "none"))
        _int("recording.chunk_size", rec["chunk_size"], 1024, 2**26)
        _check_library_configs(world, learner, seed_given)
        faults = data.get("faults")
        if faults is None:
            scenario = FaultScenario("none")
        elif isinstance(faults, str):
            if not faults.strip():
                raise StnsRosError("faults must be a scenario file, an inline scenario or "
                                   "null, got ''")
            scenario = load_scenario(_resolve(base, faults))
        else:
            scenario = parse_scenario(faults, "faults")
        cfg["faults"] = scenario.to_dict()
        nodes = data.get("nodes")
        if nodes is not None:
            if not isinstance(nodes, str) or not nodes.strip():
                raise StnsRosError(f"nodes must be the path of a ROS parameter file, got {nodes!r}")
            nodes = _resolve(base, nodes)
        cfg["nodes"] = nodes
        node_parameters(cfg, base, "")  # checks the tuning file against what the run sets
    except StnsRosError as e:
        raise StnsRosError(f"{where}{e}") from None
    return cfg


def _check_library_configs(world: dict, learner: dict, seed_given: bool) -> None:
    from rover_sim import RoverSimError, WorldConfig
    from stns_core import StnsConfig, StnsError

    try:
        wc = WorldConfig.preset(world["preset"], **world["overrides"])
    except (RoverSimError, TypeError) as e:
        raise StnsRosError(f"world.overrides: {e}") from None
    try:
        want = StnsConfig.preset(learner["preset"], **{**learner["overrides"],
                                                       "seed": learner["seed"]}).to_dict()
    except Exception as e:  # StnsError subclasses; the library's message names the field
        raise StnsRosError(f"learner.overrides: {e}") from None
    if learner["state_in"]:  # read it now: a bad file would otherwise stop the agent mid-run
        from stns_ros.driver import make_agent

        try:
            saved = make_agent({}, wc.observation_dim, learner["state_in"]).config.to_dict()
        except (StnsError, StnsRosError, OSError) as e:
            raise StnsRosError(f"learner.state_in: {e}") from None
        # a saved learner goes on with the settings it was saved with: an override that
        # differs would be recorded in params.yaml yet never used
        given = [*learner["overrides"], *(["seed"] if seed_given else [])]
        differ = [f"{'learner.seed' if k == 'seed' else 'learner.overrides.' + k} = {want[k]!r}"
                  f" (saved: {saved.get(k)!r})" for k in given if saved.get(k) != want[k]]
        if differ:
            raise StnsRosError(
                f"learner.state_in {learner['state_in']!r} keeps the settings it was saved "
                f"with, and these differ: {'; '.join(differ)}; drop them, or start a new "
                "learner (state_in: \"\")")


def load_run_config(path: str | Path) -> dict[str, Any]:
    p = Path(path)
    return parse_run_config(read_yaml(p, "run config"), str(p), p.resolve().parent)


def load_node_params(path: str | Path) -> dict[str, dict[str, Any]]:
    """A ROS parameter file (``node: {ros__parameters: {...}}``) as {node: params}."""
    p = Path(path)
    data = read_yaml(p, "node parameter file")
    out: dict[str, dict[str, Any]] = {}
    if not isinstance(data, Mapping):
        raise StnsRosError(f"{p}: a ROS parameter file must be a mapping, got {data!r}")
    for node, body in data.items():
        if not isinstance(body, Mapping) or not isinstance(body.get("ros__parameters"), Mapping):
            raise StnsRosError(f"{p}: {node} needs a ros__parameters mapping")
        out[str(node).lstrip("/")] = dict(body["ros__parameters"])
    return out


NODE_NAMES = ("rover_sim", "stns_agent", "fault_injector")


def node_parameters(cfg: Mapping[str, Any], out_dir: Path, run_config_json: str
                    ) -> tuple[dict[str, dict[str, Any]], list[str]]:
    """The ROS parameters of each node of the run, and a note for each tuning-file value
    that the run config replaces. The tuning file (``nodes``) may hold the `TUNING`
    parameters and the ones the run sets; anything else, and a bad tuning value, is a
    `StnsRosError` naming the node, the parameter and the value."""
    import json

    run, world, learner, rec = cfg["run"], cfg["world"], cfg["learner"], cfg["recording"]
    from stns_core import StnsAgent, StnsConfig

    if learner["state_in"]:  # the agent goes on with the saved learner's own settings
        lc = StnsAgent.load(learner["state_in"]).config
    else:
        lc = StnsConfig.preset(learner["preset"], **{**learner["overrides"],
                                                     "seed": learner["seed"]})
    overrides = json.dumps(world["overrides"], sort_keys=True)
    sim = {
        "use_sim_time": False,  # it is the clock
        "world_preset": world["preset"],
        "world_overrides": overrides,
        "seed": world["seed"],
        "mode": run["mode"],
        "real_time_factor": run["real_time_factor"],
        "record_path": str(out_dir / "bag") if rec["enabled"] else "",
        "record_compression": rec["compression"],
        "record_chunk_size": rec["chunk_size"],
        "run_config": run_config_json,
        **{k: float(world["faults"].get(k, v)) for k, v in FAULT_NEUTRAL.items()},
    }
    agent = {
        "use_sim_time": True,
        "learner_preset": learner["preset"],
        **lc.to_dict(),
        "world_preset": world["preset"],
        "world_overrides": overrides,
        "max_behaviour_steps": run["steps"],
        "state_in": learner["state_in"],
        "state_out": str(out_dir / "learner_state") if learner["save_state"] else "",
        "stats_out": "",
        "wait_for_recorder": False,
    }
    injector = {
        "use_sim_time": True,  # at_time triggers and the sim-time stamps of the events
        "scenario": "",  # a file here would replace the run's scenario
        "scenario_json": json.dumps(cfg["faults"]),
        "sim_node": "rover_sim",
    }
    run_set = {"rover_sim": sim, "stns_agent": agent, "fault_injector": injector}
    tuning, notes = (check_node_params(load_node_params(cfg["nodes"]), cfg["nodes"], run_set)
                     if cfg.get("nodes") else ({}, []))
    return {n: {**tuning.get(n, {}), **run_set[n]} for n in NODE_NAMES}, notes


# where each run-set parameter comes from, for the notes on replaced tuning-file values
_SOURCE = {"seed": "world.seed / run.seed", "mode": "run.mode",
           "real_time_factor": "run.real_time_factor", "world_preset": "world.preset",
           "world_overrides": "world.overrides", "learner_preset": "learner.preset",
           "max_behaviour_steps": "run.steps", "state_in": "learner.state_in",
           "scenario": "faults", "scenario_json": "faults",
           **{k: f"world.faults.{k}" for k in FAULT_PARAMS}}


def _source(node: str, name: str) -> str:
    import dataclasses

    from stns_core import StnsConfig

    if node == "stns_agent" and name == "seed":
        return "learner.seed / run.seed"
    if node == "stns_agent" and name in {f.name for f in dataclasses.fields(StnsConfig)}:
        return f"learner.overrides.{name}"
    return _SOURCE.get(name, "the run config")


def check_node_params(given: Mapping[str, Mapping[str, Any]], source: str,
                      run_set: Mapping[str, Mapping[str, Any]]
                      ) -> tuple[dict[str, dict[str, Any]], list[str]]:
    """The tuning values of a node parameter file (`load_node_params`), checked, with ints
    made floats where the node declares a double; and a note for each value the run sets
    otherwise (``run_set``). Unknown nodes and parameters are errors: a misspelt name would
    otherwise be dropped without a word."""
    tuning: dict[str, dict[str, Any]] = {}
    notes: list[str] = []
    for node, params in given.items():
        if node not in TUNING:
            raise StnsRosError(f"{source}: unknown node {node!r}; known: {', '.join(NODE_NAMES)}")
        tuning[node] = {}
        for name, value in params.items():
            if name in TUNING[node]:
                value, reason = check_tuning(node, name, value)
                if reason:
                    raise StnsRosError(f"{source}: {node}.{reason}")
                tuning[node][name] = value
            elif name in run_set[node]:
                ours = run_set[node][name]
                same = value == ours and type(value) is type(ours) or (
                    isinstance(ours, float) and isinstance(value, int | float)
                    and not isinstance(value, bool) and float(value) == ours)
                if not same:
                    where = _source(node, name)
                    notes.append(f"{source}: {node}.{name} = {value!r} is replaced by the run's "
                                 f"{_short(ours)} (set it in {where})")
            else:
                known = sorted({*TUNING[node], *run_set[node]})
                raise StnsRosError(f"{source}: {node}: unknown parameter {name!r}; known: "
                                   f"{', '.join(known)}")
    return tuning, notes


def _short(v: Any) -> str:
    text = repr(v)
    return text if len(text) <= 60 else text[:57] + "..."


def unreached_faults(cfg: Mapping[str, Any]) -> list[str]:
    """The scenario's at_step events that no behaviour step of the run would feel: an event
    at step N changes steps N+1 on. at_time events are not judged (sim seconds per behaviour
    step vary)."""
    steps = cfg["run"]["steps"]
    return [f"faults[{i}] at_step {e['at_step']} does not come before the end of the run "
            f"({steps} behaviour steps): it changes nothing"
            for i, e in enumerate(cfg["faults"]["faults"])
            if e.get("at_step") is not None and e["at_step"] >= steps]


def write_params_file(params: Mapping[str, Mapping[str, Any]], path: Path) -> None:
    path.write_text(yaml.safe_dump(
        {node: {"ros__parameters": dict(p)} for node, p in params.items()},
        sort_keys=False, width=10**9))
