"""Parameter descriptors and validation shared by the nodes."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    SetParametersResult,
)
from rclpy.node import Node
from rclpy.parameter import Parameter

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
FAULT_NEUTRAL = {
    "goal_sensor_rotation_deg": 0.0,
    "left_wheel_gain": 1.0,
    "goal_sensor_noise_std_m": 0.0,
    "range_sensor_noise_std_m": 0.0,
}


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
