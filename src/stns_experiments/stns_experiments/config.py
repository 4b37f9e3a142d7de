"""Experiment parameters: built-in paper presets, YAML files in config/, command-line overrides.

An experiment's parameters are a plain nested dict. The built-in defaults below are the
paper's settings; ``config/<exp>.yaml`` repeats them for users to copy and edit. A YAML file
may hold any subset of the keys of its experiment; unknown keys, wrong types and values out
of range raise :class:`ExperimentError` naming the key and the value.
"""

from __future__ import annotations

import copy
import math
import os
from collections.abc import Hashable, Mapping
from pathlib import Path
from typing import Any

import yaml

EXPERIMENTS = ("exp1", "exp2-sensor", "exp2-actuator", "exp3", "offline", "grid")


class ExperimentError(Exception):
    """Root exception of stns_experiments: bad parameters, missing inputs, failed runs."""


_COMMON: dict[str, Any] = {
    "trial_sets": 20,
    "steps": 10000,
    "seed": 0,
    "block_size": 100,
    "final_window": 1000,
    "convergence_tol": 0.1,
    "trailing_window": 500,
    "random_steps": 5000,
    "max_ticks_per_step": 2000,
    "world": {"preset": "exp1", "overrides": {}},
    "agent": {"preset": "exp1", "overrides": {}},
    "save_states": True,
    "figures": True,
}

DEFAULTS: dict[str, dict[str, Any]] = {
    "exp1": {**_COMMON},
    "exp2-sensor": {
        **_COMMON,
        "trial_sets": 10,
        "steps": 5000,
        "block_size": 250,
        "pretrain_steps": 10000,
        "fault": "goal_sensor_rotation_deg",
        "levels": [10, 15, 20, 25, 90, 180],
        "scratch": True,
        "from": None,
    },
    "exp2-actuator": {
        **_COMMON,
        "trial_sets": 10,
        "steps": 5000,
        "block_size": 250,
        "pretrain_steps": 10000,
        "fault": "left_wheel_slowdown_pct",
        "levels": [5, 10, 15],
        "scratch": True,
        "from": None,
    },
    "exp3": {
        **_COMMON,
        "trial_sets": 4,  # as the runs of docs/RESULTS.md (the paper does not say)
        "steps": 28000,
        "world": {"preset": "exp3", "overrides": {}},
        "agent": {"preset": "exp3", "overrides": {}},
    },
    "offline": {
        **_COMMON,
        "trial_sets": 10,
        "steps": 1200,
        "max_random_behaviours": 300000,
    },
    "grid": {
        **_COMMON,
        "trial_sets": 5,
        "grids": ["polar", "orthogonal"],
        "learners": ["q", "model"],
        "gamma": 0.7,
        "initial_value": 10.0,
        "alpha": None,
        "epsilon": 0.0,
        "sweeps": 3,
        "range_edges": [],
        "compare_stns": True,
        "from": None,
        "agent": {"preset": "exp1", "overrides": {}},
    },
}

_FAULTS = ("goal_sensor_rotation_deg", "left_wheel_slowdown_pct")
_GRIDS = ("polar", "orthogonal")
_LEARNERS = ("q", "model")


def _int(key: str, v: Any, lo: int = 0, hi: int | None = None) -> int:
    if isinstance(v, bool) or not isinstance(v, int):
        raise ExperimentError(f"{key} must be an integer, got {v!r}")
    if v < lo or (hi is not None and v > hi):
        rng = f">= {lo}" if hi is None else f"in [{lo}, {hi}]"
        raise ExperimentError(f"{key} must be {rng}, got {v!r}")
    return v


def _num(key: str, v: Any, lo: float | None = None, hi: float | None = None,
         lo_open: bool = False) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise ExperimentError(f"{key} must be a finite number, got {v!r}")
    if lo is not None and (v < lo or (lo_open and v == lo)):
        raise ExperimentError(f"{key} must be {'>' if lo_open else '>='} {lo}, got {v!r}")
    if hi is not None and v > hi:
        raise ExperimentError(f"{key} must be <= {hi}, got {v!r}")
    return float(v)


def _bool(key: str, v: Any) -> bool:
    if not isinstance(v, bool):
        raise ExperimentError(f"{key} must be true or false, got {v!r}")
    return v


def _section(key: str, v: Any) -> dict[str, Any]:
    if not isinstance(v, Mapping):
        raise ExperimentError(f"{key} must be a mapping with 'preset' and 'overrides', got {v!r}")
    unknown = sorted(set(v) - {"preset", "overrides"})
    if unknown:
        raise ExperimentError(f"unknown key(s) {unknown} in {key}; known: preset, overrides")
    preset = v.get("preset")
    if not isinstance(preset, str) or not preset:
        raise ExperimentError(f"{key}.preset must be a preset name, got {preset!r}")
    overrides = v.get("overrides") or {}
    if not isinstance(overrides, Mapping) or not all(isinstance(k, str) for k in overrides):
        raise ExperimentError(f"{key}.overrides must be a mapping of names, got {overrides!r}")
    return {"preset": preset, "overrides": dict(overrides)}


# The 8-D grids hold goal cells x (edges + 1)^6 cells; beyond 3 edges (orthogonal: 1.8
# million cells) the value table alone outgrows a small machine's memory.
MAX_RANGE_EDGES = 3


def _range_edges(v: Any) -> list[float]:
    """``range_edges`` of the grid experiment: increasing positive range boundaries (u)."""
    if not isinstance(v, list):
        raise ExperimentError(f"range_edges must be a list of range boundaries in u, got {v!r}")
    if len(v) > MAX_RANGE_EDGES:
        raise ExperimentError(
            f"range_edges: at most {MAX_RANGE_EDGES} boundaries (levels^6 range cells per "
            f"goal cell), got {len(v)}: {v!r}")
    edges = [_num("range_edges[]", e, 0.0, lo_open=True) for e in v]
    if any(b <= a for a, b in zip(edges[:-1], edges[1:], strict=True)):
        raise ExperimentError(f"range_edges must increase, got {v!r}")
    return edges


def validate(exp: str, params: Mapping[str, Any]) -> dict[str, Any]:
    """Check every value; return a normalised copy. Raises ExperimentError naming the key."""
    if exp not in DEFAULTS:
        raise ExperimentError(f"unknown experiment {exp!r}; known: {', '.join(EXPERIMENTS)}")
    known = set(DEFAULTS[exp]) | {"experiment"}
    unknown = sorted(set(params) - known)
    if unknown:
        raise ExperimentError(
            f"unknown key(s) {unknown} for {exp}; known: {', '.join(sorted(known))}")
    p = dict(params)
    if p.get("experiment", exp) != exp:
        raise ExperimentError(f"experiment: the file is for {p['experiment']!r}, not {exp!r}")
    p["experiment"] = exp
    p["trial_sets"] = _int("trial_sets", p["trial_sets"], 1, 10000)
    p["steps"] = _int("steps", p["steps"], 1)
    p["seed"] = _int("seed", p["seed"], 0, 2**63 - 1)
    p["block_size"] = _int("block_size", p["block_size"], 1)
    p["final_window"] = _int("final_window", p["final_window"], 1)
    p["convergence_tol"] = _num("convergence_tol", p["convergence_tol"], 0.0, 10.0, lo_open=True)
    p["trailing_window"] = _int("trailing_window", p["trailing_window"], 1)
    p["random_steps"] = _int("random_steps", p["random_steps"], 0)
    p["max_ticks_per_step"] = _int("max_ticks_per_step", p["max_ticks_per_step"], 1)
    p["world"] = _section("world", p["world"])
    p["agent"] = _section("agent", p["agent"])
    if "seed" in p["agent"]["overrides"]:  # make_agent_config replaces it, per trial set
        raise ExperimentError("agent.overrides.seed is not used: each trial set's learner seed "
                              "comes from the root seed (--seed); drop it")
    p["save_states"] = _bool("save_states", p["save_states"])
    p["figures"] = _bool("figures", p["figures"])
    if exp.startswith("exp2"):
        p["pretrain_steps"] = _int("pretrain_steps", p["pretrain_steps"], 1)
        if p["fault"] not in _FAULTS:
            raise ExperimentError(f"fault must be one of {', '.join(_FAULTS)}, got {p['fault']!r}")
        levels = p["levels"]
        if not isinstance(levels, list) or not levels:
            raise ExperimentError(f"levels must be a non-empty list, got {levels!r}")
        if p["fault"] == "left_wheel_slowdown_pct":
            p["levels"] = [_num("levels[]", v) for v in levels]
            bad = [v for v in levels if not 0.0 <= v < 100.0]
            if bad:
                raise ExperimentError(
                    f"levels: a slowdown must be in [0, 100) %, got {bad[0]!r}")
        else:
            p["levels"] = [_num("levels[]", v, -360.0, 360.0) for v in levels]
        twice = sorted({v for v in p["levels"] if p["levels"].count(v) > 1})
        if twice:  # two runs of one level would write the same result files
            raise ExperimentError(f"levels: {', '.join(f'{v:g}' for v in twice)} given more "
                                  f"than once in {levels!r}")
        p["scratch"] = _bool("scratch", p["scratch"])
        if p["from"] is not None and not isinstance(p["from"], (str, os.PathLike)):
            raise ExperimentError(f"from must be a directory path, got {p['from']!r}")
    if exp == "offline":
        p["max_random_behaviours"] = _int("max_random_behaviours", p["max_random_behaviours"], 1)
    if exp == "grid":
        for key, allowed in (("grids", _GRIDS), ("learners", _LEARNERS)):
            v = p[key]
            if not isinstance(v, list) or not v or any(x not in allowed for x in v):
                raise ExperimentError(f"{key} must be a non-empty list from {list(allowed)}, got {v!r}")
        p["gamma"] = _num("gamma", p["gamma"], 0.0, 1.0, lo_open=True)
        p["initial_value"] = _num("initial_value", p["initial_value"])
        if p["alpha"] is not None:
            p["alpha"] = _num("alpha", p["alpha"], 0.0, 1.0, lo_open=True)
        p["epsilon"] = _num("epsilon", p["epsilon"], 0.0, 1.0)
        p["sweeps"] = _int("sweeps", p["sweeps"], 1)
        p["range_edges"] = _range_edges(p["range_edges"])
        p["compare_stns"] = _bool("compare_stns", p["compare_stns"])
        if p["from"] is not None and not isinstance(p["from"], (str, os.PathLike)):
            raise ExperimentError(f"from must be a directory path, got {p['from']!r}")
    if p["final_window"] > p["steps"]:
        p["final_window"] = p["steps"]
    return p


def merge(base: Mapping[str, Any], over: Mapping[str, Any]) -> dict[str, Any]:
    """Recursive dict merge: mappings merge key by key, anything else replaces."""
    out = copy.deepcopy(dict(base))
    for k, v in over.items():
        if isinstance(v, Mapping) and isinstance(out.get(k), Mapping):
            out[k] = merge(out[k], v)
        else:
            out[k] = copy.deepcopy(v)
    return out


class _UniqueKeyLoader(yaml.SafeLoader):
    """SafeLoader refusing a key given twice in one mapping: PyYAML keeps the last, and the
    other, maybe the one meant, would be dropped without a word."""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict:
        seen: set = set()
        for key_node, _ in node.value:
            if key_node.tag == "tag:yaml.org,2002:merge":  # `<<:` keys may be overridden
                continue
            key = self.construct_object(key_node, deep=deep)
            if not isinstance(key, Hashable):
                continue  # the base class names an unhashable key itself
            if key in seen:
                raise yaml.constructor.ConstructorError(
                    None, None, f"key {key!r} is given twice", key_node.start_mark)
            seen.add(key)
        return super().construct_mapping(node, deep=deep)


def load_yaml(path: Path) -> dict[str, Any]:
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as e:
        raise ExperimentError(f"cannot read config file {str(path)!r}: {e.strerror}") from None
    except UnicodeDecodeError as e:  # a UTF-16 or binary file: YAML never sees it
        raise ExperimentError(f"config file {str(path)!r} is not UTF-8 text: byte "
                              f"0x{e.object[e.start]:02x} at offset {e.start}") from None
    try:
        data = yaml.load(text, Loader=_UniqueKeyLoader)  # noqa: S506 - a SafeLoader
    except yaml.YAMLError as e:
        raise ExperimentError(f"config file {str(path)!r} is not valid YAML: "
                              f"{_yaml_problem(e)}") from None
    if data is None:
        return {}
    if not isinstance(data, Mapping):
        raise ExperimentError(f"config file {str(path)!r} must hold a mapping, got {type(data).__name__}")
    return dict(data)


def _yaml_problem(e: yaml.YAMLError) -> str:
    """A YAML error on one line, with its line and column in the file (PyYAML's own text
    spans lines and names the parsed text "<unicode string>")."""
    mark = getattr(e, "problem_mark", None)
    problem = getattr(e, "problem", None) or str(e).splitlines()[0]
    at = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
    return f"{problem}{at}"


def find_config_dir() -> Path | None:
    """config/ of the workspace: $STNS_WS/config, else the nearest ./config upwards."""
    ws = os.environ.get("STNS_WS")
    if ws and (Path(ws) / "config").is_dir():
        return Path(ws) / "config"
    here = Path.cwd().resolve()
    for d in (here, *here.parents):
        if (d / "config").is_dir() and (d / "src" / "stns_experiments").is_dir():
            return d / "config"
    return None


def parse_set(item: str) -> tuple[list[str], Any]:
    """``a.b.c=VALUE`` -> (["a", "b", "c"], VALUE parsed as YAML)."""
    if "=" not in item:
        raise ExperimentError(f"--set expects KEY=VALUE, got {item!r}")
    key, text = item.split("=", 1)
    parts = key.strip().split(".")
    if not all(parts):
        raise ExperimentError(f"--set has an empty key in {item!r}")
    try:
        value = yaml.safe_load(text) if text.strip() else None
    except yaml.YAMLError:
        raise ExperimentError(f"--set value of {key!r} is not valid YAML: {text!r}") from None
    return parts, value


def nest(parts: list[str], value: Any) -> dict[str, Any]:
    out: dict[str, Any] = {parts[-1]: value}
    for p in reversed(parts[:-1]):
        out = {p: out}
    return out


def resolve(exp: str, config_file: Path | None = None, use_workspace_file: bool = True,
            overrides: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Defaults <- YAML file (explicit, or config/<exp>.yaml of the workspace) <- overrides."""
    if exp not in DEFAULTS:
        raise ExperimentError(f"unknown experiment {exp!r}; known: {', '.join(EXPERIMENTS)}")
    params = copy.deepcopy(DEFAULTS[exp])
    source = "built-in defaults"
    if config_file is None and use_workspace_file:
        d = find_config_dir()
        if d is not None and (d / f"{exp}.yaml").is_file():
            config_file = d / f"{exp}.yaml"
    if config_file is not None:
        data = load_yaml(config_file)
        for key in ("world", "agent"):
            if key in data and not isinstance(data[key], Mapping):
                raise ExperimentError(f"{key} must be a mapping with 'preset' and 'overrides', got {data[key]!r}")
        params = merge(params, data)
        source = str(config_file)
    if overrides:
        params = merge(params, overrides)
    params = validate(exp, params)
    params["config_source"] = source
    return params
