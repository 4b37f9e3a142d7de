"""Parameter descriptors and validation shared by the nodes."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    SetParametersResult,
)
from rclpy.exceptions import ParameterNotDeclaredException
from rclpy.node import Node
from rclpy.parameter import Parameter

from stns_ros.topics import OTHER_TOPICS, TYPES

# Fault parameters of the simulator node: name -> (lower, upper, lower_open, description).
FAULT_PARAMS: dict[str, tuple[float, float, bool, str]] = {
    "goal_sensor_rotation_deg": (
        -180.0, 180.0, False, "Goal sensor reading rotated by this angle (ccw), degrees."),
    "left_wheel_gain": (
        0.0, 2.0, True, "Left wheel turns at this fraction of its command, in (0, 2]."),
    "goal_sensor_noise_std_m": (
        0.0, 1.0, False, "Gaussian noise std on each goal coordinate, metres."),
    "range_sensor_noise_std_m": (
        0.0, 1.0, False, "Gaussian noise std on each sector range, metres."),
}
#: The most behaviour steps a run may ask for (the agent's ``max_behaviour_steps``).
MAX_STEPS = 10**9

FAULT_NEUTRAL = {
    "goal_sensor_rotation_deg": 0.0,
    "left_wheel_gain": 1.0,
    "goal_sensor_noise_std_m": 0.0,
    "range_sensor_noise_std_m": 0.0,
}


@dataclass(frozen=True)
class Tuning:
    """A node parameter left to the tuning file (config/nodes.yaml): the run config does not
    set it. The nodes declare it from here and `check_tuning` checks a file's value of it."""

    default: bool | int | float | tuple[str, ...]
    description: str
    range: tuple[float, float] | None = None
    read_only: bool = False
    choices: tuple[str, ...] | None = None  # what each entry of a list parameter may be


TUNING: dict[str, dict[str, Tuning]] = {
    "rover_sim": {
        "publish_ranges": Tuning(
            True, "Publish the six sector ranges every tick (always on when the task's input "
            "has them)."),
        "resend_period": Tuning(
            0.25, "Lockstep: re-send an unanswered frame after this many wall seconds.",
            (0.01, 10.0)),
        "record_topics": Tuning(
            OTHER_TOPICS,
            "Topics of the other nodes to record (the sim's own topics are always recorded).",
            read_only=True, choices=tuple(TYPES)),  # the recorder knows these types only
    },
    "stns_agent": {
        "watchdog_timeout": Tuning(
            1.0, "Stop the rover (zero command) when no frame came for this many wall seconds.",
            (0.05, 60.0)),
        "explain_every": Tuning(
            10, "Publish /stns/plan and /stns/situation every this many behaviour steps.",
            (1, 100000)),
        "markers_every": Tuning(
            100, "Publish /stns/situations every this many behaviour steps.", (1, 100000)),
        "progress_every": Tuning(
            250, "Log progress every this many behaviour steps.", (1, 10**9)),
        "checkpoint_every": Tuning(
            250, "Save the learner to state_out every this many behaviour steps, so a killed "
            "agent loses at most that many (0 = only on shutdown).", (0, 10**9)),
    },
    "fault_injector": {
        "check_period": Tuning(
            0.01, "Wall seconds between checks of sim-time triggers.", (0.001, 1.0),
            read_only=True),
    },
}


TYPE_WORDS = {
    Parameter.Type.BOOL: "true or false",
    Parameter.Type.INTEGER: "an integer",
    Parameter.Type.DOUBLE: "a number with a decimal point",
    Parameter.Type.STRING: "a string",
    Parameter.Type.STRING_ARRAY: "a list of strings",
}


class NamedRefusals:
    """Node mixin: rclpy's own refusals of a set_parameters call name the parameter and the
    value ("Wrong parameter type, expected 'Type.DOUBLE' got 'Type.STRING'" names neither, and
    its undeclared-parameter error loses the names). Hooks rclpy's (Jazzy) descriptor check."""

    def _apply_descriptor(self, parameter: Parameter, descriptor=None, check_read_only=True):
        res = super()._apply_descriptor(parameter, descriptor, check_read_only)
        if res.successful:
            return res
        if res.reason.startswith("Trying to set a read-only parameter"):
            res.reason = (f"{parameter.name} is read-only: it is set when the node starts, "
                          f"not while it runs (got {parameter.value!r})")
        elif res.reason.startswith("Wrong parameter type"):  # rclpy's declare tests this prefix
            d = descriptor if descriptor is not None else self.describe_parameter(parameter.name)
            want = Parameter.Type(d.type)
            res.reason = (f"Wrong parameter type: {parameter.name} must be "
                          f"{TYPE_WORDS.get(want, want.name)}, got {parameter.value!r}")
        return res

    def _check_undeclared_parameters(self, parameter_list: list[Parameter]) -> None:
        unknown = [p.name for p in parameter_list
                   if isinstance(p, Parameter) and p.name not in self._parameters]
        if unknown and not self._allow_undeclared_parameters:
            raise ParameterNotDeclaredException(
                f"{', '.join(unknown)} (known: {', '.join(sorted(self._parameters))})")
        super()._check_undeclared_parameters(parameter_list)


def declare_tuning(node: Node, table: str, name: str) -> Any:
    """Declare tuning parameter `name` as ``TUNING[table]`` describes it (`table` is the
    node's default name: a remapped node keeps its parameters)."""
    t = TUNING[table][name]
    default = list(t.default) if isinstance(t.default, tuple) else t.default
    return declare(node, name, default, t.description, range=t.range, read_only=t.read_only)


def check_tuning(node: str, name: str, value: Any) -> tuple[Any, str | None]:
    """(value as the node declares it, None) if `value` suits tuning parameter `name` of
    `node`, else (value, the reason). An integer becomes a float for a float parameter: ROS
    would refuse 1 for a double."""
    t = TUNING[node][name]
    want = t.default
    if isinstance(want, bool):
        ok = isinstance(value, bool)
        kind = "true or false"
    elif isinstance(want, tuple):
        ok = isinstance(value, list) and all(isinstance(v, str) for v in value)
        kind = "a list of strings"
    elif isinstance(want, int):
        ok = isinstance(value, int) and not isinstance(value, bool)
        kind = "an integer"
    else:
        ok = (isinstance(value, int | float) and not isinstance(value, bool)
              and math.isfinite(value))
        kind = "a finite number"
        value = float(value) if ok else value
    if not ok:
        return value, f"{name} must be {kind}, got {value!r}"
    if t.choices is not None and (bad := [v for v in value if v not in t.choices]):
        return value, f"{name}: no type known for {bad[0]!r}; known: {', '.join(t.choices)}"
    if t.range is not None and not t.range[0] <= value <= t.range[1]:
        return value, f"{name} must be in [{t.range[0]:g}, {t.range[1]:g}], got {value!r}"
    return value, None


def declare(
    node: Node,
    name: str,
    default: Any,
    description: str,
    *,
    range: tuple[float, float] | None = None,  # noqa: A002 - the descriptor's word
    read_only: bool = False,
    choices: Sequence[str] = (),
    type_: Parameter.Type | None = None,
) -> Any:
    """Declare one parameter with a descriptor (ranges, read-only, choices in the text)."""
    text = description + (f" One of: {', '.join(choices)}." if choices else "")
    desc = ParameterDescriptor(description=text, read_only=read_only)
    if range is not None:
        if isinstance(default, bool) or not isinstance(default, int | float):
            raise TypeError(f"range given for non-numeric parameter {name}")
        if isinstance(default, int):
            desc.integer_range = [IntegerRange(from_value=int(range[0]), to_value=int(range[1]), step=1)]
        else:
            desc.floating_point_range = [
                FloatingPointRange(from_value=float(range[0]), to_value=float(range[1]), step=0.0)
            ]
    if default is None:
        return node.declare_parameter(name, type_ or Parameter.Type.STRING, desc).value
    return node.declare_parameter(name, default, desc).value


def check_fault(name: str, value: Any) -> str | None:
    """None if `value` is a valid value of fault parameter `name`, else the reason."""
    lo, hi, lo_open, _ = FAULT_PARAMS[name]
    if isinstance(value, bool) or not isinstance(value, int | float):
        return f"{name} must be a number, got {value!r}"
    v = float(value)
    if not math.isfinite(v):
        return f"{name} must be finite, got {value!r}"
    if v < lo or v > hi or (lo_open and v == lo):
        left = "(" if lo_open else "["
        return f"{name} must be in {left}{lo:g}, {hi:g}], got {value!r}"
    return None


def check_choice(name: str, value: Any, choices: Sequence[str]) -> str | None:
    if value not in choices:
        return f"{name} must be one of {', '.join(choices)}, got {value!r}"
    return None


def result(reason: str | None) -> SetParametersResult:
    return SetParametersResult(successful=reason is None, reason=reason or "")
