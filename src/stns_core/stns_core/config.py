"""Typed, frozen configuration of the STNS learner (paper section 7 parameters + readings).

Every field maps one to one onto a ROS parameter of the agent node (same snake_case name).
The reading options (``random_stop``, ``majority``, ...) are documented in ``algorithm.md``
with the paper section each departs from or resolves.
"""

from __future__ import annotations

import dataclasses
import numbers
from dataclasses import dataclass
from typing import Any

import numpy as np

from .errors import StnsConfigError

PLANNERS = ("iprl", "pia")
RANDOM_STOPS = ("situation_change", "reward")
MAJORITIES = ("strict", "plurality")
BOUNDARY_REFITS = ("every_step", "interval")
RELABELS = ("after_modification", "never")
EXPLORATIONS = ("uniform", "greedy_goal")
SHAPE_SCOPES = ("all", "t_only")
TARGET_STOPS = ("first", "deepest")
PLAN_STOPS = ("target", "higher_utility")
T_RESULTS = ("reached", "unpunished")
MARGIN_PLANS = ("margin", "nearest_r", "nearest_r_bitten")
R_BREAK_FORGETS = ("positives", "history")
NO_PLANS = ("explore", "margin_plan")
USELESS = ("negative", "no_positive_plan")
MARGIN_STNS = ("all", "no_positives")
MISS_STOPS = ("never", "margin", "all")
EXPLORE_UNTRIED_STOPS = ("random_stop", "reward")
PENDING_R_TRIES = ("never", "nearest_success", "planned_nearest_success")
PENDING_T_TRIES = ("never", "planned_nearest_success")
VALIDITY_CHECKS = ("before_periodic", "also_after_periodic")

_PRESETS: dict[str, dict[str, Any]] = {
    # Paper section 7.1 (Exp. 1 and, from a saved learner, Exp. 2).
    "exp1": dict(n_init_r=3, n_min_r=3, n_init_t=15, n_min_t=7, r_min_r=5.0, gamma=0.7,
                 p_min=0.1, n_max=7, history_size=1000, adjust_interval=100),
    # Paper section 7.3 (8-D input).
    "exp3": dict(n_init_r=9, n_min_r=9, n_init_t=20, n_min_t=12, r_min_r=5.0, gamma=0.7,
                 p_min=0.2, n_max=7, history_size=10000, adjust_interval=100),
}


@dataclass(frozen=True)
class StnsConfig:
    """Parameters of the learner. Validated on construction; immutable.

    Paper parameters (section 7): ``n_init_r`` (N_init^R), ``n_min_r`` (N_min^R),
    ``n_init_t`` (N_init^T), ``n_min_t`` (N_min^T), ``r_min_r`` (r_min^R), ``gamma``,
    ``p_min``, ``n_max``, ``history_size``, ``adjust_interval`` (boundaries and order).
    """

    n_init_r: int = 3
    n_min_r: int = 3
    n_init_t: int = 15
    n_min_t: int = 7
    r_min_r: float = 5.0
    gamma: float = 0.7
    p_min: float = 0.1
    n_max: int = 7
    history_size: int = 1000
    adjust_interval: int = 100
    planner: str = "iprl"
    seed: int = 0
    # Readings of open points (algorithm.md, "Readings").
    random_stop: str = "situation_change"
    majority: str = "strict"
    boundary_refit: str = "every_step"
    target_lookahead_ticks: int = 0
    target_stop: str = "first"
    plan_stop: str = "target"
    t_result: str = "reached"
    margin_plan: str = "margin"
    margin_plan_reach: float = 2.0
    margin_plan_window: int = 10
    r_break_window: int = 0
    r_break_forget: str = "positives"
    r_break_fraction: float = 0.5
    contradiction_radius: float = 0.0
    contradiction_window: int = 0
    nn_window: int = 0
    stn_half_life: float = 0.0
    margin_stn: str = "all"
    miss_stop: str = "never"
    explore_untried: int = 0
    explore_untried_stop: str = "random_stop"
    pending_r_try: str = "never"
    pending_t_try: str = "never"
    useless: str = "negative"
    no_plan: str = "explore"
    relabel: str = "after_modification"
    validity_check: str = "before_periodic"
    iprl_memo: bool = True
    cov_reg: float = 1e-3
    max_behaviour_ticks: int = 0
    event_log_size: int = 500
    # Exp. 3 remedies of paper section 7.3 (algorithm.md, "Section 7.3 options"). The
    # defaults switch every one of them off: the learner is then bit-for-bit the one above.
    exploration: str = "uniform"
    greedy_prob: float = 1.0
    greedy_align_deg: float = 5.0
    elimination_grace_steps: int = 0
    explore_max_ticks: int = 0
    shape_trim: float = 1.0
    boundary_quantile: float = 1.0
    shape_scope: str = "all"
    negatives_from_history: bool = False
    range_clip: float = 0.0

    def __post_init__(self) -> None:
        ints = {
            "n_init_r": 1, "n_min_r": 1, "n_init_t": 1, "n_min_t": 1, "n_max": 1,
            "history_size": 2, "adjust_interval": 1, "seed": 0,
            "target_lookahead_ticks": 0, "max_behaviour_ticks": 0, "event_log_size": 1,
            "elimination_grace_steps": 0, "explore_max_ticks": 0, "r_break_window": 0,
            "margin_plan_window": 0, "nn_window": 0, "explore_untried": 0,
            "contradiction_window": 0,
        }
        for name, lowest in ints.items():
            value = getattr(self, name)
            if isinstance(value, bool | np.bool_) or not isinstance(value, numbers.Integral):
                raise StnsConfigError(f"{name} must be an int, got {value!r}")
            value = int(value)
            object.__setattr__(self, name, value)
            if value < lowest:
                raise StnsConfigError(f"{name} must be >= {lowest}, got {value!r}")
        for name in ("r_min_r", "gamma", "p_min", "cov_reg", "greedy_prob", "greedy_align_deg",
                     "shape_trim", "boundary_quantile", "range_clip", "margin_plan_reach",
                     "r_break_fraction", "contradiction_radius", "stn_half_life"):
            value = getattr(self, name)
            if isinstance(value, bool | np.bool_) or not isinstance(value, numbers.Real):
                raise StnsConfigError(f"{name} must be a number, got {value!r}")
            if value != value or value in (float("inf"), float("-inf")):
                raise StnsConfigError(f"{name} must be finite, got {value!r}")
            object.__setattr__(self, name, float(value))
        if not 0.0 <= self.gamma < 1.0:
            raise StnsConfigError(f"gamma must be in [0, 1), got {self.gamma!r}")
        if not 0.0 <= self.p_min < 1.0:
            raise StnsConfigError(f"p_min must be in [0, 1), got {self.p_min!r}")
        if self.cov_reg <= 0.0:
            raise StnsConfigError(f"cov_reg must be > 0, got {self.cov_reg!r}")
        if not 0.0 <= self.greedy_prob <= 1.0:
            raise StnsConfigError(f"greedy_prob must be in [0, 1], got {self.greedy_prob!r}")
        if not 0.0 < self.greedy_align_deg < 90.0:
            raise StnsConfigError(
                f"greedy_align_deg must be in (0, 90), got {self.greedy_align_deg!r}")
        if not 0.0 < self.shape_trim <= 1.0:
            raise StnsConfigError(f"shape_trim must be in (0, 1], got {self.shape_trim!r}")
        if not 0.0 < self.boundary_quantile <= 1.0:
            raise StnsConfigError(
                f"boundary_quantile must be in (0, 1], got {self.boundary_quantile!r}")
        if self.margin_plan_reach <= 0.0:
            raise StnsConfigError(
                f"margin_plan_reach must be > 0, got {self.margin_plan_reach!r}")
        if not 0.0 <= self.r_break_fraction < 1.0:
            raise StnsConfigError(
                f"r_break_fraction must be in [0, 1), got {self.r_break_fraction!r}")
        if self.contradiction_radius < 0.0:
            raise StnsConfigError(
                f"contradiction_radius must be >= 0 (0 = off), got {self.contradiction_radius!r}")
        if self.stn_half_life < 0.0:
            raise StnsConfigError(
                f"stn_half_life must be >= 0 (0 = off), got {self.stn_half_life!r}")
        if self.range_clip < 0.0:
            raise StnsConfigError(f"range_clip must be >= 0 (0 = off), got {self.range_clip!r}")
        if self.n_min_r > self.history_size or self.n_init_t > self.history_size:
            raise StnsConfigError(
                f"history_size {self.history_size} is smaller than the instance counts")
        if not isinstance(self.iprl_memo, bool | np.bool_):
            raise StnsConfigError(f"iprl_memo must be a bool, got {self.iprl_memo!r}")
        object.__setattr__(self, "iprl_memo", bool(self.iprl_memo))
        if not isinstance(self.negatives_from_history, bool | np.bool_):
            raise StnsConfigError(
                f"negatives_from_history must be a bool, got {self.negatives_from_history!r}")
        object.__setattr__(self, "negatives_from_history", bool(self.negatives_from_history))
        choices = {
            "planner": PLANNERS, "random_stop": RANDOM_STOPS, "majority": MAJORITIES,
            "boundary_refit": BOUNDARY_REFITS, "relabel": RELABELS,
            "exploration": EXPLORATIONS, "shape_scope": SHAPE_SCOPES,
            "target_stop": TARGET_STOPS, "plan_stop": PLAN_STOPS, "t_result": T_RESULTS,
            "margin_plan": MARGIN_PLANS, "useless": USELESS, "r_break_forget": R_BREAK_FORGETS,
            "margin_stn": MARGIN_STNS, "miss_stop": MISS_STOPS, "no_plan": NO_PLANS,
            "explore_untried_stop": EXPLORE_UNTRIED_STOPS, "pending_r_try": PENDING_R_TRIES,
            "pending_t_try": PENDING_T_TRIES, "validity_check": VALIDITY_CHECKS,
        }
        for name, allowed in choices.items():
            value = getattr(self, name)
            if isinstance(value, bool | np.bool_):  # YAML 1.1 reads on/off/yes/no as booleans
                raise StnsConfigError(
                    f"{name} must be one of {allowed}, got the boolean {value!r} (in YAML, quote "
                    f"words such as on, off, yes, no)")
            if value not in allowed:
                raise StnsConfigError(f"{name} must be one of {allowed}, got {value!r}")

    @classmethod
    def preset(cls, name: str, **overrides: Any) -> StnsConfig:
        """The paper's parameters for ``"exp1"`` (also Exp. 2) or ``"exp3"``, plus overrides."""
        if name not in _PRESETS:
            raise StnsConfigError(f"unknown preset {name!r}; known: {sorted(_PRESETS)}")
        values = dict(_PRESETS[name])
        values.update(overrides)
        return cls.from_dict(values)

    def replace(self, **changes: Any) -> StnsConfig:
        """A copy with some fields changed (validated)."""
        unknown = set(changes) - {f.name for f in dataclasses.fields(self)}
        if unknown:
            raise StnsConfigError(f"unknown StnsConfig keys: {sorted(unknown)}")
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict[str, Any]:
        """Plain dict (json-serialisable), one key per field."""
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> StnsConfig:
        """Build from a dict; unknown keys are rejected with StnsConfigError."""
        if not isinstance(data, dict):
            raise StnsConfigError(f"config must be a dict, got {type(data).__name__}")
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = set(data) - known
        if unknown:
            raise StnsConfigError(f"unknown StnsConfig keys: {sorted(unknown)}")
        return cls(**data)
