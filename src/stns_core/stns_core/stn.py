"""The situation transition network (paper section 6.1): maximum likelihood over the history.

Nodes: 0 = situation 0 (margin space), 1..S = the situations in discrimination order,
S + 1 = the goal (terminal: a behaviour that ended at goal arrival leads there; utility 0).
``p(i, j; b)`` = count(i, b, j) / count(i, b); ``r(i, j; b)`` = mean reward of those records.
"""

from __future__ import annotations

import numpy as np


class Stn:
    """Transition probabilities and mean rewards, with per-(i, b) successor lists."""

    def __init__(self, counts: np.ndarray, reward_sums: np.ndarray) -> None:
        self.counts = np.asarray(counts, dtype=float)
        self.reward_sums = np.asarray(reward_sums, dtype=float)
        n, nb, n2 = self.counts.shape
        if n != n2:
            raise ValueError(f"counts must be (n, B, n), got {self.counts.shape}")
        self.n_nodes = n
        self.n_behaviours = nb
        self.goal = n - 1
        totals = self.counts.sum(axis=2, keepdims=True)
        with np.errstate(invalid="ignore", divide="ignore"):
            self.p = np.where(totals > 0, self.counts / np.where(totals > 0, totals, 1), 0.0)
            self.r = np.where(self.counts > 0,
                              self.reward_sums / np.where(self.counts > 0, self.counts, 1), 0.0)
        self.tried = totals[:, :, 0] > 0
        # successors[i][b] = list of (j, p, r) in node order, or None when b is untried in i
        self.successors: list[list[list[tuple[int, float, float]] | None]] = []
        for i in range(n):
            row: list[list[tuple[int, float, float]] | None] = []
            for b in range(nb):
                if not self.tried[i, b]:
                    row.append(None)
                    continue
                js = np.flatnonzero(self.counts[i, b] > 0)
                row.append([(int(j), float(self.p[i, b, j]), float(self.r[i, b, j])) for j in js])
            self.successors.append(row)

    @classmethod
    def from_records(cls, s: np.ndarray, b: np.ndarray, s_next: np.ndarray,
                     reward: np.ndarray, n_nodes: int, n_behaviours: int) -> Stn:
        """Counts from dense node indices of the history's behaviour records."""
        key = (s * n_behaviours + b) * n_nodes + s_next
        size = n_nodes * n_behaviours * n_nodes
        counts = np.bincount(key, minlength=size).astype(float)
        sums = np.bincount(key, weights=reward, minlength=size)
        shape = (n_nodes, n_behaviours, n_nodes)
        return cls(counts.reshape(shape), sums.reshape(shape))

    @classmethod
    def from_model(cls, p: np.ndarray, r: np.ndarray, scale: float = 1000.0) -> Stn:
        """A hand-built STN (tests): probabilities ``p`` (n, B, n) and rewards ``r``."""
        p = np.asarray(p, dtype=float)
        counts = p * scale
        return cls(counts, counts * np.asarray(r, dtype=float))
