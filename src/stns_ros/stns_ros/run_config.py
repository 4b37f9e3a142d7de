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
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml

from stns_ros.driver import seeds_from_run_seed
from stns_ros.errors import StnsRosError
from stns_ros.faults import FaultScenario, load_scenario, parse_scenario, read_yaml
from stns_ros.params import FAULT_PARAMS, check_fault

SCHEMA: dict[str, dict[str, Any]] = {
    "run": {"name": "run", "seed": 0, "steps": 3000, "mode": "lockstep", "real_time_factor": 1.0},
    "world": {"preset": "exp1", "overrides": {}, "faults": {}, "seed": None},
    "learner": {"preset": "exp1", "overrides": {}, "seed": None, "state_in": "", "save_state": True},
    "recording": {"enabled": True, "compression": "zstd", "chunk_size": 262144},
}
TOP_KEYS = set(SCHEMA) | {"faults", "nodes"}


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
        given = data.get(section) or {}
        if not isinstance(given, Mapping):
            raise StnsRosError(f"{where}{section} must be a mapping, got {given!r}")
        extra = sorted(set(given) - set(defaults))
        if extra:
            raise StnsRosError(f"{where}{section}: unknown key(s) {extra}; known: {sorted(defaults)}")
        cfg[section] = {**copy.deepcopy(defaults), **copy.deepcopy(dict(given))}
    try:
        run, world, learner, rec = cfg["run"], cfg["world"], cfg["learner"], cfg["recording"]
        if not isinstance(run["name"], str) or not run["name"]:
            raise StnsRosError(f"run.name must be a non-empty string, got {run['name']!r}")
        _int("run.seed", run["seed"], 0, 2**32 - 1)
        _int("run.steps", run["steps"], 1)
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
        if not isinstance(world["faults"], Mapping):
            raise StnsRosError(f"world.faults must be a mapping, got {world['faults']!r}")
        for name, value in world["faults"].items():
            if name not in FAULT_PARAMS:
                raise StnsRosError(f"world.faults.{name}: unknown fault parameter; known: "
                                   f"{', '.join(FAULT_PARAMS)}")
            reason = check_fault(name, value)
            if reason:
                raise StnsRosError(f"world.faults.{name}: {reason}")
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
        _check_library_configs(world, learner)
        faults = data.get("faults")
        if faults is None:
            scenario = FaultScenario("none")
        elif isinstance(faults, str):
            scenario = load_scenario(_resolve(base, faults))
        else:
            scenario = parse_scenario(faults, "faults")
        cfg["faults"] = scenario.to_dict()
        nodes = data.get("nodes")
        if nodes is not None:
            if not isinstance(nodes, str):
                raise StnsRosError(f"nodes must be the path of a ROS parameter file, got {nodes!r}")
            nodes = _resolve(base, nodes)
            load_node_params(nodes)
        cfg["nodes"] = nodes
    except StnsRosError as e:
        raise StnsRosError(f"{where}{e}") from None
    return cfg


def _check_library_configs(world: dict, learner: dict) -> None:
    from rover_sim import RoverSimError, WorldConfig
    from stns_core import StnsConfig, StnsError

    try:
        wc = WorldConfig.preset(world["preset"], **world["overrides"])
    except (RoverSimError, TypeError) as e:
        raise StnsRosError(f"world.overrides: {e}") from None
    try:
        StnsConfig.preset(learner["preset"], **{**learner["overrides"], "seed": learner["seed"]})
    except Exception as e:  # StnsError subclasses; the library's message names the field
        raise StnsRosError(f"learner.overrides: {e}") from None
    if learner["state_in"]:  # read it now: a bad file would otherwise stop the agent mid-run
        from stns_ros.driver import make_agent

        try:
            make_agent({}, wc.observation_dim, learner["state_in"])
        except (StnsError, StnsRosError, OSError) as e:
            raise StnsRosError(f"learner.state_in: {e}") from None


def load_run_config(path: str | Path) -> dict[str, Any]:
    p = Path(path)
    return parse_run_config(read_yaml(p, "run config"), str(p), p.resolve().parent)


def load_node_params(path: str | Path) -> dict[str, dict[str, Any]]:
    """A ROS parameter file (``node: {ros__parameters: {...}}``) as {node: params}."""
    p = Path(path)
    try:
        data = yaml.safe_load(p.read_text())
    except OSError as e:
        raise StnsRosError(f"cannot read node parameter file {str(p)!r}: {e.strerror}") from None
    except yaml.YAMLError as e:
        raise StnsRosError(f"{p}: not valid YAML: {e}") from None
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
                    ) -> dict[str, dict[str, Any]]:
    """The ROS parameters of each node of the run (tuning file first, run config wins)."""
    import json

    run, world, learner, rec = cfg["run"], cfg["world"], cfg["learner"], cfg["recording"]
    base = load_node_params(cfg["nodes"]) if cfg.get("nodes") else {}
    from stns_core import StnsConfig

    lc = StnsConfig.preset(learner["preset"], **{**learner["overrides"], "seed": learner["seed"]})
    overrides = json.dumps(world["overrides"], sort_keys=True)
    sim = {
        "world_preset": world["preset"],
        "world_overrides": overrides,
        "seed": world["seed"],
        "mode": run["mode"],
        "real_time_factor": run["real_time_factor"],
        "record_path": str(out_dir / "bag") if rec["enabled"] else "",
        "record_compression": rec["compression"],
        "record_chunk_size": rec["chunk_size"],
        "run_config": run_config_json,
        **{k: float(v) for k, v in world["faults"].items()},
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
    }
    injector = {
        "use_sim_time": True,  # at_time triggers and the sim-time stamps of the events
        "scenario_json": json.dumps(cfg["faults"]),
        "sim_node": "rover_sim",
    }
    return {
        "rover_sim": {**base.get("rover_sim", {}), **sim},
        "stns_agent": {**base.get("stns_agent", {}), **agent},
        "fault_injector": {**base.get("fault_injector", {}), **injector},
    }


def write_params_file(params: Mapping[str, Mapping[str, Any]], path: Path) -> None:
    path.write_text(yaml.safe_dump(
        {node: {"ros__parameters": dict(p)} for node, p in params.items()},
        sort_keys=False, width=10**9))
