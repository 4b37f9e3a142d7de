"""Baseline agents with the StnsAgent tick protocol: a random policy and tabular grid learners.

Both keep the protocol of INTERFACES.md (``step(obs, reward, terminated)`` once per control
tick, ``None`` at a goal arrival, ``pop_records()``, ``behaviour_steps``) and produce records
with the StepRecord fields, so the same tick loop and the same metrics serve every learner.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import sparse

from stns_core import StepRecord

N_BEHAVIOURS = 4
N_SECTORS = 6       # range-sensor sectors (rover_sim), obs[2:8] in Exp. 3


# The baselines record exactly what the learner records, so one set of metrics serves all.
Record = StepRecord

class _BehaviourAgent:
    """Common machinery: run one behaviour until a stop condition, record each step."""

    def __init__(self, rng: np.random.Generator, max_ticks: int = 2000) -> None:
        self.rng = rng
        self.max_ticks = int(max_ticks)
        self.behaviour_steps = 0
        self._records: list[Record] = []
        self._trial = 0
        self._new_trial = True
        self._running: dict | None = None

    # subclasses: state(obs) -> int, choose(state, obs) -> (behaviour, planned),
    # learn(state, behaviour, reward, next_state, terminal), stop(start_state, obs) -> bool
    def state(self, obs: np.ndarray) -> int:
        return 0

    def stop(self, start_state: int, obs: np.ndarray) -> bool:
        return False

    def learn(self, s: int, b: int, r: float, s2: int | None, terminal: bool) -> None:
        return None

    def choose(self, s: int, obs: np.ndarray) -> tuple[int, bool]:
        return int(self.rng.integers(N_BEHAVIOURS)), False

    def _add(self, rec: Record) -> None:
        self._records.append(rec)
        self.behaviour_steps += 1

    def _close(self, obs: np.ndarray | None, terminal: bool) -> None:
        run = self._running
        s2 = None if terminal else self.state(obs)
        self.learn(run["s"], run["b"], run["reward"], s2, terminal)
        self._add(Record(
            index=self.behaviour_steps, x=run["x"], situation=run["s"], kind="0",
            behaviour=run["b"], target=None, planned=run["planned"], reward=run["reward"],
            next_situation=-1 if terminal else s2, success=None, ticks=run["ticks"],
            arrival=False, trial=self._trial))
        self._running = None

    def _start(self, obs: np.ndarray) -> int:
        s = self.state(obs)
        b, planned = self.choose(s, obs)
        self._running = {"x": np.array(obs, dtype=np.float64), "s": s, "b": int(b),
                         "planned": planned, "reward": 0.0, "ticks": 0}
        return int(b)

    def step(self, obs: np.ndarray, reward: float, terminated: bool) -> int | None:
        if self._new_trial:
            self._trial += 1
            self._new_trial = False
        run = self._running
        if run is not None:
            run["reward"] += float(reward)
            run["ticks"] += 1
            if terminated:
                self._close(None, terminal=True)
                self._add(Record(
                    index=self.behaviour_steps, x=np.array(obs, dtype=np.float64),
                    situation=-1, kind="0", behaviour=None, target=None, planned=False,
                    reward=0.0, next_situation=None, success=None, ticks=0, arrival=True,
                    trial=self._trial))
                self._new_trial = True
                return None
            if reward != 0.0 or run["ticks"] >= self.max_ticks or self.stop(run["s"], obs):
                self._close(obs, terminal=False)
            else:
                return run["b"]
        return self._start(obs)

    def pop_records(self) -> list[Record]:
        out, self._records = self._records, []
        return out


class RandomAgent(_BehaviourAgent):
    """Uniformly random behaviours, each run until a non-zero reward (the empty start of
    STNS: with no situation the classified situation never changes)."""


# ---------------------------------------------------------------------- grids
RING_EDGES = (15.0, 30.0, 60.0)   # the paper's rings at 5/15/30/60/120 (r < 5 is the goal)


def polar_cell(x: float, y: float, sectors: int = 24) -> int:
    """Polar grid of Fig. 13a: rings 5-15, 15-30, 30-60, 60-120 (and beyond) x 24 sectors of
    15 degrees, sector 0 centred on the rover's forward axis. 96 cells."""
    r = math.hypot(x, y)
    ring = int(np.searchsorted(RING_EDGES, r, side="right"))
    width = 2.0 * math.pi / sectors
    sector = int(math.floor((math.atan2(y, x) + width / 2.0) / width)) % sectors
    return ring * sectors + sector


def orthogonal_cell(x: float, y: float, half: int = 10, size: float = 10.0) -> int:
    """Orthogonal grid of Fig. 13b: 10-unit cells centred on the axes (|x| < 5, |y| < 5 are
    one column and one row), 21 x 21 cells covering +-105, the border cells open outwards."""
    i = min(max(int(math.floor(x / size + 0.5)), -half), half) + half
    j = min(max(int(math.floor(y / size + 0.5)), -half), half) + half
    return i * (2 * half + 1) + j


GRID_CELLS = {"polar": (polar_cell, 4 * 24), "orthogonal": (orthogonal_cell, 21 * 21)}

# Above this many (cell, behaviour) rows the model-based learner keeps its model sparse: the
# 8-D grids (goal cells x 3^6 range levels) would need a dense 10^10-entry count matrix.
DENSE_MODEL_MAX_ROWS = 4096


def range_code(ranges: np.ndarray, edges: tuple[float, ...]) -> int:
    """The six sector ranges as one number: each sector's level (0 = nearest) in base
    ``len(edges) + 1``, sector 0 the least significant digit. ``edges`` are the level
    boundaries in u, increasing (§7.5: two edges give "near, middle and far")."""
    levels = np.searchsorted(np.asarray(edges, dtype=np.float64), np.asarray(ranges), side="right")
    base = len(edges) + 1
    return int(np.dot(levels, base ** np.arange(len(levels))))


class GridAgent(_BehaviourAgent):
    """Tabular learner on a grid of the goal-sensor space (§7.5), optionally times the range
    sensor's sectors cut into levels (the 8-D grids of §7.5).

    A behaviour runs until a reward or until the cell changes. Values are per behaviour
    step with discount ``gamma``; an untried (cell, behaviour) pair has ``initial_value``
    (optimistic +10: with zero initial values the grids hardly learn, STNS-NOTES §11).
    ``learner="q"``: one-step Q-learning, step size 1/n(cell, behaviour) unless ``alpha``.
    ``learner="model"``: maximum-likelihood model (counts, mean rewards) and ``sweeps`` of
    value iteration over the tried pairs after every behaviour (dense up to
    ``DENSE_MODEL_MAX_ROWS`` rows, else sparse; ``sparse_model`` forces either). Greedy choice
    (ties at random), with probability ``epsilon`` a random behaviour.
    ``range_edges``: empty for the 2-D grids of Fig. 13; with k edges, a cell is the goal
    cell and the level of each of the six sector ranges (obs[2:8]): goal cells x (k+1)^6.
    """

    def __init__(self, grid: str, learner: str, rng: np.random.Generator, gamma: float = 0.7,
                 initial_value: float = 10.0, alpha: float | None = None, epsilon: float = 0.0,
                 sweeps: int = 3, max_ticks: int = 2000, range_edges: tuple[float, ...] = (),
                 sparse_model: bool | None = None) -> None:
        super().__init__(rng, max_ticks)
        self.goal_cell, goal_cells = GRID_CELLS[grid]
        self.range_edges = tuple(float(e) for e in range_edges)
        self.range_codes = (len(self.range_edges) + 1) ** N_SECTORS if self.range_edges else 1
        self.n_cells = goal_cells * self.range_codes
        self.learner = learner
        self.gamma, self.init, self.alpha = gamma, initial_value, alpha
        self.epsilon, self.sweeps = epsilon, sweeps
        n, a = self.n_cells, N_BEHAVIOURS
        self.q = np.full((n, a), float(initial_value))
        self.n = np.zeros((n, a), dtype=np.int64)
        if learner == "model":
            self.sparse = (n * a > DENSE_MODEL_MAX_ROWS if sparse_model is None
                           else bool(sparse_model))
            if self.sparse:
                self._model = _SparseModel(n, a, float(initial_value))
            else:
                # transitions to cells 0..n-1 and to the terminal goal (column n)
                self.counts = np.zeros((n * a, n + 1))
                self.rsum = np.zeros(n * a)

    def state(self, obs: np.ndarray) -> int:
        cell = self.goal_cell(float(obs[0]), float(obs[1]))
        if not self.range_edges:
            return cell
        return cell * self.range_codes + range_code(obs[2:2 + N_SECTORS], self.range_edges)

    def stop(self, start_state: int, obs: np.ndarray) -> bool:
        return self.state(obs) != start_state

    def choose(self, s: int, obs: np.ndarray) -> tuple[int, bool]:
        if self.epsilon > 0 and self.rng.random() < self.epsilon:
            return int(self.rng.integers(N_BEHAVIOURS)), False
        q = self.q[s]
        best = np.flatnonzero(q >= q.max() - 1e-12)
        return int(best[self.rng.integers(len(best))]), True

    def learn(self, s: int, b: int, r: float, s2: int | None, terminal: bool) -> None:
        self.n[s, b] += 1
        if self.learner == "q":
            target = r if terminal else r + self.gamma * float(self.q[s2].max())
            step = self.alpha if self.alpha is not None else 1.0 / self.n[s, b]
            self.q[s, b] += step * (target - self.q[s, b])
            return
        k = s * N_BEHAVIOURS + b
        s2_col = self.n_cells if terminal else int(s2)
        if self.sparse:
            self._model.add(k, s2_col, r)
            self._model.sweep(self.q, self.gamma, self.sweeps)
            return
        self.counts[k, s2_col] += 1.0
        self.rsum[k] += r
        tried = self.n.reshape(-1) > 0
        nk = self.n.reshape(-1)[tried].astype(np.float64)
        p = self.counts[tried] / nk[:, None]
        rmean = self.rsum[tried] / nk
        q = self.q.reshape(-1)
        for _ in range(self.sweeps):
            v = np.concatenate([self.q.max(axis=1), [0.0]])
            q[tried] = rmean + self.gamma * (p @ v)


class _SparseModel:
    """The model-based learner's counts for the tried (cell, behaviour) pairs only, and the
    same value-iteration sweeps as the dense form (each sweep from the values before it)."""

    def __init__(self, n_cells: int, n_behaviours: int, initial_value: float) -> None:
        self.n_cells, self.a = n_cells, n_behaviours
        self.row_of: dict[int, int] = {}        # pair k = cell * a + behaviour -> row
        self.keys: list[int] = []               # row -> pair k
        self.entry_of: dict[tuple[int, int], int] = {}
        self.rows: list[int] = []
        self.cols: list[int] = []
        self.vals: list[float] = []
        self.visits: list[int] = []             # per row
        self.rsum: list[float] = []
        # v(cell) = max over behaviours of q; untried cells keep the optimistic value; goal 0
        self.v = np.full(n_cells + 1, float(initial_value))
        self.v[n_cells] = 0.0

    def add(self, k: int, col: int, r: float) -> None:
        row = self.row_of.get(k)
        if row is None:
            row = self.row_of[k] = len(self.keys)
            self.keys.append(k)
            self.visits.append(0)
            self.rsum.append(0.0)
        self.visits[row] += 1
        self.rsum[row] += r
        e = self.entry_of.get((row, col))
        if e is None:
            self.entry_of[(row, col)] = len(self.vals)
            self.rows.append(row)
            self.cols.append(col)
            self.vals.append(1.0)
        else:
            self.vals[e] += 1.0

    def sweep(self, q: np.ndarray, gamma: float, sweeps: int) -> None:
        n_rows = len(self.keys)
        visits = np.asarray(self.visits, dtype=np.float64)
        rows = np.asarray(self.rows)
        counts = sparse.csr_matrix((np.asarray(self.vals) / visits[rows], (rows, self.cols)),
                                   shape=(n_rows, self.n_cells + 1))
        rmean = np.asarray(self.rsum) / visits
        keys = np.asarray(self.keys)
        cells = np.unique(keys // self.a)
        flat = q.reshape(-1)
        for _ in range(sweeps):
            flat[keys] = rmean + gamma * (counts @ self.v)
            self.v[cells] = q[cells].max(axis=1)
