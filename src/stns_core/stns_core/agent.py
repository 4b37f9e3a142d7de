"""The STNS agent: the paper's behaviour-step loop run at control-tick level.

``step(obs, reward, terminated)`` is called once per control tick (docs/INTERFACES.md). It
decides whether the running behaviour stops (a non-zero reward; the target situation
reached; for the random behaviour under the default reading, a change of the classified
situation), closes the behaviour step into a history record, learns (categorical learning,
STN), plans (IPRL or PIA) and returns the next action. The same object serves the headless
experiments and the ROS agent node.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from os import PathLike
from typing import Any

import numpy as np

from .categorical import GOAL, Learner
from .config import StnsConfig
from .errors import StnsDimensionError, StnsError, StnsInputError
from .history import ARRIVAL
from .records import StepRecord
from .situation import R_KIND

PlanElems = list[tuple[int, int]]

# Behaviour indices of docs/INTERFACES.md, used only by exploration="greedy_goal".
FORWARD, BACKWARD, CLOCKWISE, COUNTER_CLOCKWISE = 0, 1, 2, 3


def goal_bearing_deg(x: np.ndarray) -> float:
    """Bearing of the goal in the rover frame (input dims 0, 1 = goal x forward, y left)."""
    return math.degrees(math.atan2(float(x[1]), float(x[0])))


def greedy_behaviour(x: np.ndarray, align_deg: float) -> int:
    """Head for the goal: drive if it is (nearly) ahead or behind, else turn the short way
    to bring it ahead (|bearing| <= 90) or behind (|bearing| > 90)."""
    a = goal_bearing_deg(x)
    if abs(a) <= align_deg:
        return FORWARD
    if abs(a) >= 180.0 - align_deg:
        return BACKWARD
    if abs(a) <= 90.0:
        return COUNTER_CLOCKWISE if a > 0 else CLOCKWISE  # turning ccw lowers the bearing
    return CLOCKWISE if a > 0 else COUNTER_CLOCKWISE


@dataclass
class _Running:
    """The behaviour step under way."""

    x0: np.ndarray
    s0: int
    b: int
    target: int | None  # situation id, GOAL, or None for the random behaviour
    planned: bool
    reward: float = 0.0
    ticks: int = 0
    la_count: int = -1  # look-ahead ticks spent inside the target (-1: not yet reached)
    prev_x: np.ndarray | None = None  # input of the previous tick (look-ahead extrapolation)
    greedy: bool = False  # an exploration step chosen by exploration="greedy_goal"
    root: int = 0  # margin_plan="nearest_r": the R-situation the plan started from (0: none)
    approached: bool = False  # miss_stop: the target's centre has come nearer at least once
    trying: bool = False  # explore_untried: a try of a behaviour little started in s0
    pending: bool = False  # pending_r_try: a try of a behaviour without an R-situation

    def to_dict(self) -> dict[str, Any]:
        d = {
            "x0": [float(v) for v in self.x0], "s0": self.s0, "b": self.b,
            "target": self.target, "planned": self.planned, "reward": self.reward,
            "ticks": self.ticks, "la_count": self.la_count,
            "prev_x": None if self.prev_x is None else [float(v) for v in self.prev_x],
        }
        if self.greedy:  # only then: save files of the default config stay as they were
            d["greedy"] = True
        if self.root:
            d["root"] = self.root
        if self.approached:
            d["approached"] = True
        if self.trying:
            d["trying"] = True
        if self.pending:
            d["pending"] = True
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> _Running:
        d = dict(d)
        d["x0"] = np.array(d["x0"], dtype=float)
        if d["prev_x"] is not None:
            d["prev_x"] = np.array(d["prev_x"], dtype=float)
        return cls(**d)


class StnsAgent:
    """STNS learner + controller. See docs/INTERFACES.md for the tick protocol."""

    def __init__(self, config: StnsConfig, obs_dim: int, n_behaviours: int) -> None:
        if not isinstance(config, StnsConfig):
            raise StnsInputError(f"config must be a StnsConfig, got {type(config).__name__}")
        for name, value, lowest in (("obs_dim", obs_dim, 1), ("n_behaviours", n_behaviours, 1)):
            if isinstance(value, bool) or not isinstance(value, int | np.integer):
                raise StnsInputError(f"{name} must be an int, got {value!r}")
            if value < lowest:
                raise StnsInputError(f"{name} must be >= {lowest}, got {value!r}")
        if config.exploration == "greedy_goal" and (n_behaviours != 4 or obs_dim < 2):
            raise StnsInputError(
                "exploration='greedy_goal' needs the goal sensor in input dims 0, 1 and the "
                f"four behaviours of docs/INTERFACES.md; got obs_dim {obs_dim}, "
                f"n_behaviours {n_behaviours}")
        self.config = config
        self.obs_dim = int(obs_dim)
        self.n_behaviours = int(n_behaviours)
        self.rng = np.random.default_rng(config.seed)
        self.learner = Learner(config, self.obs_dim, self.n_behaviours)
        self.trial = 0
        self._run: _Running | None = None
        self._plan: PlanElems = []  # elements after the running one
        self._prev_reached: int | None = None  # target reached by the last planned step
        self._pending: list[StepRecord] = []
        self._current = 0  # situation of the last observation
        self._plan_utility = 0.0
        # margin_plan="nearest_r": outcomes (goal reached?) of the last plans started from the
        # margin with each R-situation's plan, newest last
        self._margin_uses: dict[int, list[bool]] = {}
        # explore_untried: behaviours started in each situation since its extraction
        self._tries: dict[int, list[int]] = {}

    # -- public API -------------------------------------------------------------------
    @property
    def behaviour_steps(self) -> int:
        """Records so far (behaviour steps + goal arrivals)."""
        return int(self.learner.hist.total)

    def classify(self, obs) -> int:
        """Situation id of an observation (0 = margin space)."""
        return self.learner.classify(self._check_obs(obs))

    def pop_records(self) -> list[StepRecord]:
        """StepRecords finished since the last call."""
        out, self._pending = self._pending, []
        return out

    def step(self, obs, reward: float, terminated: bool) -> int | None:
        """One control tick: the observation after the last action, its reward, goal flag."""
        x = self._check_obs(obs)
        r = self._check_reward(reward)
        run = self._run
        if run is None:
            if terminated:
                self._arrival(x)
                return None
            return self._begin(x, continuing=False)
        run.reward += r
        run.ticks += 1
        if terminated:
            self._close(x, self.learner.classify(x), terminal=True)
            self._arrival(x)
            return None
        s_now = self.learner.classify(x)
        self._current = s_now
        end = self._stop(run, x, s_now, r)
        if end is None:
            return run.b
        self._close(end[0], end[1], terminal=False)
        return self._begin(x, continuing=True)

    def reset_trial(self) -> None:
        """Drop the running behaviour without recording it (a trial cut short by the caller)."""
        self._run = None
        self._plan = []
        self._prev_reached = None

    def explain(self, fresh_utilities: bool = True) -> dict[str, Any]:
        from .explain import explain
        return explain(self, fresh_utilities)

    def save(self, path: str | PathLike) -> None:
        from .state_io import save_agent
        save_agent(self, path)

    @classmethod
    def load(cls, path: str | PathLike) -> StnsAgent:
        from .state_io import load_agent
        return load_agent(cls, path)

    # -- validation -------------------------------------------------------------------
    def _check_obs(self, obs) -> np.ndarray:
        try:
            x = np.array(obs, dtype=float)
        except (TypeError, ValueError) as exc:
            raise StnsInputError(f"observation is not numeric: {obs!r}") from exc
        if x.shape != (self.obs_dim,):
            raise StnsDimensionError(
                f"observation shape {x.shape} does not match obs_dim {self.obs_dim}: {obs!r}")
        if not np.all(np.isfinite(x)):
            raise StnsInputError(f"observation has non-finite values: {x.tolist()!r}")
        if self.config.range_clip > 0.0 and self.obs_dim > 2:  # option: preprocessing
            np.minimum(x[2:], self.config.range_clip, out=x[2:])
        return x

    @staticmethod
    def _check_reward(reward) -> float:
        if isinstance(reward, bool):
            raise StnsInputError(f"reward must be a number, got {reward!r}")
        try:
            r = float(reward)
        except (TypeError, ValueError) as exc:
            raise StnsInputError(f"reward must be a number, got {reward!r}") from exc
        if not math.isfinite(r):
            raise StnsInputError(f"reward must be finite, got {reward!r}")
        return r

    # -- the behaviour-step loop ------------------------------------------------------
    def _stop(self, run: _Running, x, s_now: int, r: float):
        """None to go on, else (end input, end situation) of the behaviour step."""
        cfg = self.config
        if r != 0.0:
            return x, s_now
        if run.planned and run.target is not None and run.target != GOAL:
            if self._planned_stop(run, x, s_now):
                return x, s_now
        elif (not run.planned and cfg.random_stop == "situation_change"
              and s_now != run.s0
              and not (run.trying and cfg.explore_untried_stop == "reward")
              and not run.pending):
            return x, s_now
        if run.greedy and self._greedy_done(run.b, x):
            return x, s_now
        if (not run.planned and cfg.explore_max_ticks
                and run.ticks >= cfg.explore_max_ticks):
            return x, s_now
        if cfg.max_behaviour_ticks and run.ticks >= cfg.max_behaviour_ticks:
            return x, s_now
        run.prev_x = x
        return None

    def _greedy_done(self, b: int, x: np.ndarray) -> bool:
        """Stop of a greedy step: a turn once the goal is ahead or behind (within
        ``greedy_align_deg``), a drive once it is more than 3 x that off the driving line."""
        a = abs(goal_bearing_deg(x))
        tol = self.config.greedy_align_deg
        if b in (CLOCKWISE, COUNTER_CLOCKWISE):
            return a <= tol or a >= 180.0 - tol
        off = a if b == FORWARD else 180.0 - a
        return off > min(3.0 * tol, 89.0)

    def _explore(self, x: np.ndarray) -> tuple[int, bool]:
        """The behaviour when no plan has positive utility: (behaviour, greedy)."""
        cfg = self.config
        if cfg.exploration == "greedy_goal" and self.rng.random() < cfg.greedy_prob:
            return greedy_behaviour(x, cfg.greedy_align_deg), True
        return int(self.rng.integers(self.n_behaviours)), False

    @staticmethod
    def _next_tick(run: _Running, x: np.ndarray) -> np.ndarray:
        """The input extrapolated one tick on (``2 x_t - x_(t-1)``)."""
        prev = run.x0 if run.prev_x is None else run.prev_x
        return 2.0 * x - prev

    def _stays(self, run: _Running, x: np.ndarray) -> bool:
        """One tick of look-ahead: is the input extrapolated one tick on still in the target?"""
        return self.learner.classify(self._next_tick(run, x)) == run.target

    def _planned_stop(self, run: _Running, x: np.ndarray, s_now: int) -> bool:
        """Does a planned behaviour with a situation as target stop at this tick? The paper's
        rule (the first tick in the target) and the readings ``target_lookahead_ticks``,
        ``target_stop``, ``plan_stop`` and ``miss_stop`` (algorithm.md, "Readings")."""
        cfg = self.config
        if run.la_count >= 0 and s_now != run.target:
            return True  # went on inside the target, then left it: the step ends here
        if (cfg.plan_stop == "higher_utility" and run.la_count < 0
                and s_now not in (0, run.s0, run.target) and self._better(s_now, run.target)):
            return True
        if s_now != run.target:
            return run.la_count < 0 and self._passing(run, x)
        run.la_count += 1  # ticks spent inside the target: 0 at the first
        cap = cfg.target_lookahead_ticks
        if cfg.target_stop == "deepest":  # cap 0: no cap
            return bool(cap and run.la_count >= cap) or not self._deeper(run, x)
        return run.la_count >= cap or not self._stays(run, x)

    def _passing(self, run: _Running, x: np.ndarray) -> bool:
        """Option miss_stop: is a planned behaviour that has not reached its target passing
        it by? True at the tick after which the next one (extrapolated) lies farther from
        the target's centre (Mahalanobis, its own shape), once an earlier tick had come
        nearer: a behaviour that starts off away from the target is left to run as before.
        "margin": only behaviours started in the margin; "all": any."""
        cfg = self.config
        if cfg.miss_stop == "never" or (cfg.miss_stop == "margin" and run.s0 != 0):
            return False
        d2 = self._target_d2(run, x, self._next_tick(run, x))
        if d2 is None:
            return False
        if d2[1] < d2[0]:
            run.approached = True
            return False
        return run.approached and bool(d2[1] > d2[0])

    def _better(self, sid: int, target: int) -> bool:
        """Option plan_stop="higher_utility": is situation ``sid`` of higher utility (as of
        the last re-ordering) than the running behaviour's target?"""
        ids = self.learner.by_id
        target_u = ids[target].utility if target in ids else 0.0
        return ids[sid].utility > target_u

    def _deeper(self, run: _Running, x: np.ndarray) -> bool:
        """Option target_stop="deepest": would the next tick (extrapolated one tick on) still
        be classified into the target and lie nearer its centre (Mahalanobis) than ``x``?"""
        if run.target not in self.learner.by_id:  # the margin (situation 0) has no centre
            return False
        nxt = self._next_tick(run, x)
        if self.learner.classify(nxt) != run.target:
            return False
        d2 = self._target_d2(run, x, nxt)
        return bool(d2[1] < d2[0])

    def _target_d2(self, run: _Running, x: np.ndarray, nxt: np.ndarray) -> np.ndarray | None:
        """Squared Mahalanobis distances of ``x`` and ``nxt`` from the target's centre, in the
        target's own shape; None for a target without a centre (the margin)."""
        sit = self.learner.by_id.get(run.target)
        return None if sit is None else sit.mahalanobis2(np.stack([x, nxt]))

    def _kind(self, sid: int) -> str:
        sit = self.learner.by_id.get(sid)
        return "0" if sit is None else sit.kind

    def _close(self, x_end, s_end: int, terminal: bool) -> None:
        run = self._run
        if run is None:
            raise StnsError("internal: no behaviour step is running")
        success: bool | None = None
        if run.planned:
            success = bool(terminal) if run.target == GOAL else s_end == run.target
        if run.root and self.config.margin_plan_window:
            uses = self._margin_uses.setdefault(run.root, [])
            uses.append(bool(success))
            del uses[:-self.config.margin_plan_window]
        self._prev_reached = run.target if (run.planned and success and not terminal) else None
        rec = StepRecord(
            index=self.behaviour_steps, x=run.x0.copy(), situation=run.s0,
            kind=self._kind(run.s0), behaviour=run.b,
            target=None if run.target == GOAL else run.target, planned=run.planned,
            reward=float(run.reward), next_situation=int(s_end), success=success,
            ticks=run.ticks, arrival=False, trial=self.trial)
        self._pending.append(rec)
        self._run = None
        self.learner.add_record(run.x0, run.s0, run.b, run.reward, np.array(x_end, dtype=float),
                                int(s_end), bool(terminal))

    def _arrival(self, x) -> None:
        s = self.learner.classify(x)
        self._current = s
        rec = StepRecord(
            index=self.behaviour_steps, x=x.copy(), situation=s, kind=self._kind(s),
            behaviour=None, target=None, planned=False, reward=0.0, next_situation=None,
            success=None, ticks=0, arrival=True, trial=self.trial)
        self._pending.append(rec)
        self.learner.add_record(x, s, ARRIVAL, 0.0, x, s, True)
        self.trial += 1
        self._run = None
        self._plan = []
        self._prev_reached = None

    def _plan_root(self, x: np.ndarray, s: int) -> int:
        """The situation a new plan starts from: the current one (the paper), or under option
        margin_plan="nearest_r", from the margin, the R-situation nearest to the input if it
        lies within ``margin_plan_reach`` of its boundaries and (``margin_plan_window`` W > 0)
        its plan has not missed the goal in more than half of its last W uses from the margin;
        "nearest_r_bitten": also only if the R-situation's bite, carried beyond its boundary,
        accepts the input (``Learner.reach_accepts``) (algorithm.md, "Readings")."""
        cfg = self.config
        if s != 0 or cfg.margin_plan == "margin":
            return s
        rid = self.learner.nearest(x, cfg.margin_plan_reach, R_KIND)
        if (rid and cfg.margin_plan == "nearest_r_bitten"
                and not self.learner.reach_accepts(rid, x)):
            return 0  # a miss of its behaviour lies nearer than any of its successes
        uses = self._margin_uses.get(rid, [])
        if (cfg.margin_plan_window and len(uses) >= cfg.margin_plan_window
                and 2 * uses.count(False) > len(uses)):
            return 0  # its behaviour does not work out here: the margin's own plan
        return rid

    def _plan_alive(self) -> bool:
        ids = self.learner.by_id
        return all(d in ids or d == GOAL or d == 0 for _, d in self._plan)

    def _untried(self, s: int) -> int | None:
        """Option explore_untried K: a behaviour started fewer than K times in situation ``s``
        since its extraction (the least-started, ties at random), else None. Not in the
        margin, where the random behaviour already tries them all. The try stops as the
        random behaviour does, or with ``explore_untried_stop="reward"`` only on a reward (a
        drive then runs on to the goal or a wall) (algorithm.md, "Readings")."""
        k = self.config.explore_untried
        if not k or s == 0:
            return None
        tries = self._tries.get(s)
        if tries is None:
            ids = self.learner.by_id  # a new situation: forget those eliminated since
            self._tries = {i: t for i, t in self._tries.items() if i in ids}
            tries = self._tries[s] = [0] * self.n_behaviours
        least = min(tries)
        if least >= k:
            return None
        return int(self.rng.choice([b for b, t in enumerate(tries) if t == least]))

    def _pending_try(self, x: np.ndarray) -> int | None:
        """Option pending_r_try: a behaviour that has reached the goal but has no R-situation
        yet, tried where its nearest outcome was a goal arrival (one of them at random), else
        None; "nearest_success" at any step, "planned_nearest_success" only instead of a
        plan. Such a try runs unplanned and stops only on a reward, so each one adds a goal
        arrival towards N_init^R or a miss that bites the region off (algorithm.md,
        "Readings")."""
        if self.config.pending_r_try == "never":
            return None
        cands = self.learner.pending_r_behaviours(x)
        if not cands:
            return None
        return int(cands[0]) if len(cands) == 1 else int(self.rng.choice(cands))

    def _pending_t_try(self, x: np.ndarray) -> tuple[int, int] | None:
        """Option pending_t_try: from the margin, instead of a plan, a (behaviour,
        R-situation) pair that has no T-situation yet, where the margin outcome of that
        behaviour nearest to the input reached that R-situation (one pair at random), else
        None. It runs as a plan of one step aimed at the R-situation, so each one adds a
        T-result towards the T-situation's N_init^T or a miss nearer than the success
        (algorithm.md, "Readings")."""
        if self.config.pending_t_try == "never":
            return None
        pairs = self.learner.pending_t_pairs(x)
        if not pairs:
            return None
        return pairs[0] if len(pairs) == 1 else pairs[int(self.rng.integers(len(pairs)))]

    def _begin(self, x: np.ndarray, continuing: bool) -> int:
        s = self.learner.classify(x)
        self._current = s
        greedy = False
        margin_root = 0
        b_try = self._untried(s)
        b_pending = None
        if b_try is None and self.config.pending_r_try == "nearest_success":
            b_pending = self._pending_try(x)
        if b_try is not None:  # stopped as the random behaviour (explore_untried_stop)
            b, d, planned = b_try, None, False
            self._plan = []
        elif b_pending is not None:  # stopped only on a reward
            b, d, planned = b_pending, None, False
            self._plan = []
        elif (continuing and self._plan and self._prev_reached is not None
                and s == self._prev_reached and self._plan_alive()):
            b, d = self._plan.pop(0)
            planned = True
        else:
            root = self._plan_root(x, s)
            u, plan = self.learner.plan(root)
            if not (u > 0.0 and plan) and root != 0 and self.config.no_plan == "margin_plan":
                root = 0  # no plan of positive utility here: the margin's plan, if it has one
                u, plan = self.learner.plan(root)
            self._plan_utility = u
            if u > 0.0 and plan:
                (b, d), self._plan = plan[0], plan[1:]
                planned = True
                margin_root = root if root != s else 0
            else:
                (b, greedy), d, planned = self._explore(x), None, False
                self._plan = []
        if planned and self.config.pending_r_try == "planned_nearest_success":
            b_pending = self._pending_try(x)  # only instead of a plan: exploration as before
            if b_pending is not None:
                b, d, planned, margin_root = b_pending, None, False, 0
                self._plan = []
        if planned and s == 0 and b_pending is None:
            pair = self._pending_t_try(x)  # only instead of a plan, as pending_r_try's
            if pair is not None:
                (b, d), self._plan, margin_root = pair, [], 0
        if s in self._tries:
            self._tries[s][int(b)] += 1
        self._run = _Running(x0=x.copy(), s0=s, b=int(b), target=d, planned=planned,
                             greedy=greedy, root=margin_root, trying=b_try is not None,
                             pending=b_pending is not None)
        return int(b)

