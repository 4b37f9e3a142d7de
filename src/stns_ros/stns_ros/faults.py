"""Fault scenarios: YAML parsing and validation (no rclpy).

A scenario file::

    name: rotation15
    description: rotate the goal sensor by 15 degrees part-way
    faults:
      - at_step: 1500                         # behaviour step (or at_time: sim seconds)
        set: {goal_sensor_rotation_deg: 15.0} # step change of one or more parameters
      - at_time: 120.0
        ramp: {left_wheel_gain: 0.9}          # linear ramp from the current value ...
        duration: 10.0                        # ... over this many sim seconds
        increments: 10                        # ... in this many parameter changes
      - at_step: 2500
        clear: true                           # every fault back to neutral

Parameters are the simulator node's fault parameters (`params.FAULT_PARAMS`). Every error
names the offending key and value.
"""

from __future__ import annotations

import math
from collections.abc import Hashable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from stns_ros.errors import StnsRosError
from stns_ros.params import FAULT_NEUTRAL, FAULT_PARAMS, check_fault

# a ramp's parameter changes are listed when it fires: 10^4 is 1000 s of 0.1-s ticks
MAX_INCREMENTS = 10_000
ENTRY_KEYS = {"at_step", "at_time", "set", "ramp", "clear", "duration", "increments", "note"}


@dataclass(frozen=True)
class FaultEvent:
    index: int
    kind: str  # "set", "ramp" or "clear"
    values: dict[str, float]
    at_step: int | None = None
    at_time: float | None = None
    duration: float = 0.0
    increments: int = 1
    note: str = ""

    def to_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {"at_step": self.at_step} if self.at_step is not None else {
            "at_time": self.at_time}
        if self.kind == "clear":
            d["clear"] = True
        else:
            d[self.kind] = dict(self.values)
        if self.kind == "ramp":
            d["duration"] = self.duration
            d["increments"] = self.increments
        if self.note:
            d["note"] = self.note
        return d

    def describe(self) -> str:
        when = f"step {self.at_step}" if self.at_step is not None else f"t={self.at_time}s"
        what = ", ".join(f"{k}={v:g}" for k, v in self.values.items())
        extra = f" over {self.duration:g}s" if self.kind == "ramp" else ""
        return f"at {when}: {self.kind} {what}{extra}"


@dataclass(frozen=True)
class FaultScenario:
    name: str
    faults: tuple[FaultEvent, ...] = ()
    description: str = ""
    source: str = ""

    def to_dict(self) -> dict[str, Any]:
        """Plain data in the YAML form (`parse_scenario` reads it back)."""
        return {"name": self.name, "description": self.description,
                "faults": [e.to_dict() for e in self.faults]}


def _where(source: str, key: str) -> str:
    return f"{source}: {key}" if source else key


def _number(where: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise StnsRosError(f"{where} must be a number, got {value!r}")
    if not math.isfinite(float(value)):
        raise StnsRosError(f"{where} must be finite, got {value!r}")
    return float(value)


def _values(where: str, data: Any) -> dict[str, float]:
    if not isinstance(data, Mapping) or not data:
        raise StnsRosError(f"{where} must be a non-empty mapping parameter: value, got {data!r}")
    out = {}
    for name, value in data.items():
        if name not in FAULT_PARAMS:
            raise StnsRosError(
                f"{where}.{name}: unknown fault parameter {name!r}; known: {', '.join(FAULT_PARAMS)}")
        reason = check_fault(name, value)
        if reason:
            raise StnsRosError(f"{where}.{name}: {reason}")
        out[name] = float(value)
    return out


def parse_scenario(data: Any, source: str = "") -> FaultScenario:
    """Validate plain data (a loaded YAML document) into a FaultScenario."""
    if data is None:
        data = {}
    if not isinstance(data, Mapping):
        raise StnsRosError(_where(source, f"a fault scenario must be a mapping, got {data!r}"))
    unknown = sorted(set(data) - {"name", "description", "faults"})
    if unknown:
        raise StnsRosError(_where(source, f"unknown key(s) {unknown}; known: name, description, faults"))
    name = data.get("name", Path(source).stem if source else "scenario")
    if not isinstance(name, str) or not name:
        raise StnsRosError(_where(source, f"name must be a non-empty string, got {name!r}"))
    entries = data.get("faults", []) or []
    if not isinstance(entries, list):
        raise StnsRosError(_where(source, f"faults must be a list, got {entries!r}"))
    events = []
    for i, e in enumerate(entries):
        w = _where(source, f"faults[{i}]")
        if not isinstance(e, Mapping):
            raise StnsRosError(f"{w} must be a mapping, got {e!r}")
        unknown = sorted(set(e) - ENTRY_KEYS)
        if unknown:
            raise StnsRosError(f"{w}: unknown key(s) {unknown}; known: {sorted(ENTRY_KEYS)}")
        whens = [k for k in ("at_step", "at_time") if k in e]
        if len(whens) != 1:
            raise StnsRosError(f"{w} needs exactly one of at_step, at_time; got {whens or 'none'}")
        at_step = at_time = None
        if "at_step" in e:
            v = e["at_step"]
            if isinstance(v, bool) or not isinstance(v, int) or v < 0:
                raise StnsRosError(f"{w}.at_step must be an integer >= 0, got {v!r}")
            at_step = v
        else:
            at_time = _number(f"{w}.at_time", e["at_time"])
            if at_time < 0:
                raise StnsRosError(f"{w}.at_time must be >= 0 sim seconds, got {e['at_time']!r}")
        kinds = [k for k in ("set", "ramp", "clear") if k in e]
        if len(kinds) != 1:
            raise StnsRosError(f"{w} needs exactly one of set, ramp, clear; got {kinds or 'none'}")
        kind = kinds[0]
        duration, increments = 0.0, 1
        if kind == "clear":
            if e["clear"] is not True:
                raise StnsRosError(f"{w}.clear must be true, got {e['clear']!r}")
            values = dict(FAULT_NEUTRAL)
        else:
            values = _values(f"{w}.{kind}", e[kind])
        if kind == "ramp":
            if "duration" not in e:
                raise StnsRosError(f"{w}: a ramp needs duration (sim seconds)")
            duration = _number(f"{w}.duration", e["duration"])
            if duration <= 0:
                raise StnsRosError(f"{w}.duration must be > 0 sim seconds, got {e['duration']!r}")
            increments = e.get("increments", 10)
            if (isinstance(increments, bool) or not isinstance(increments, int)
                    or not 1 <= increments <= MAX_INCREMENTS):
                raise StnsRosError(f"{w}.increments must be an integer in [1, {MAX_INCREMENTS}], "
                                   f"got {increments!r}")
        else:
            for k in ("duration", "increments"):
                if k in e:
                    raise StnsRosError(f"{w}.{k} only applies to a ramp")
        note = e.get("note", "")
        events.append(FaultEvent(i, kind, values, at_step, at_time, duration, increments,
                                 str(note)))
    return FaultScenario(name, tuple(events), str(data.get("description", "")), source)


def load_scenario(path: str | Path) -> FaultScenario:
    """Read and validate a scenario YAML file."""
    p = Path(path)
    return parse_scenario(read_yaml(p, "fault scenario"), str(p))


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


def read_yaml(path: Path, what: str) -> Any:
    """Parse a YAML file; an unreadable file or bad YAML is a StnsRosError naming it."""
    try:
        text = path.read_text()
    except OSError as e:
        raise StnsRosError(f"cannot read {what} {str(path)!r}: {e.strerror}") from None
    except UnicodeDecodeError as e:  # a UTF-16 or binary file: YAML never sees it
        raise StnsRosError(f"{what} {str(path)!r} is not UTF-8 text: byte "
                           f"0x{e.object[e.start]:02x} at offset {e.start}") from None
    try:
        return yaml.load(text, Loader=_UniqueKeyLoader)  # noqa: S506 - a SafeLoader
    except yaml.YAMLError as e:
        raise StnsRosError(f"{path}: not valid YAML: {yaml_problem(e)}") from None


def yaml_problem(e: yaml.YAMLError) -> str:
    """A YAML error on one line, with its line and column in the file (PyYAML's own text
    spans lines and names the parsed text "<unicode string>")."""
    mark = getattr(e, "problem_mark", None)
    problem = getattr(e, "problem", None) or str(e).splitlines()[0]
    at = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
    return f"{problem}{at}"


def ramp_points(start: dict[str, float], event: FaultEvent, t0: float) -> list[tuple[float, dict[str, float]]]:
    """(sim time, values) of the parameter changes of a ramp that starts at t0 from `start`."""
    pts = []
    for k in range(1, event.increments + 1):
        frac = k / event.increments
        vals = {n: start.get(n, FAULT_NEUTRAL[n]) + frac * (v - start.get(n, FAULT_NEUTRAL[n]))
                for n, v in event.values.items()}
        pts.append((t0 + frac * event.duration, vals))
    return pts


@dataclass
class ScenarioClock:
    """Which events are due, given the behaviour step count and the sim time (no rclpy)."""

    scenario: FaultScenario
    fired: set[int] = field(default_factory=set)

    def due(self, steps: int, sim_time: float) -> list[FaultEvent]:
        out = []
        for e in self.scenario.faults:
            if e.index in self.fired:
                continue
            if (e.at_step is not None and steps >= e.at_step) or (
                e.at_time is not None and sim_time >= e.at_time
            ):
                self.fired.add(e.index)
                out.append(e)
        return out

    @property
    def finished(self) -> bool:
        return len(self.fired) == len(self.scenario.faults)
