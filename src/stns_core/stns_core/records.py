"""StepRecord: one finished behaviour step (or goal arrival), as experiments consume it."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class StepRecord:
    """One behaviour step (docs/INTERFACES.md).

    ``target`` is the target situation id of a planned behaviour, or None when the plan
    element's result is the goal reward (``planned`` tells it from a random behaviour).
    ``success``: a planned step reached its target (or, aiming at the goal, got the goal
    reward); None for random behaviours and arrival records.
    """

    index: int
    x: np.ndarray
    situation: int
    kind: str
    behaviour: int | None
    target: int | None
    planned: bool
    reward: float
    next_situation: int | None
    success: bool | None
    ticks: int
    arrival: bool
    trial: int

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["x"] = [float(v) for v in self.x]
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> StepRecord:
        d = dict(d)
        d["x"] = np.array(d["x"], dtype=float)
        return cls(**d)
