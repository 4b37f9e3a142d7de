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
        self._successors: list | None = None

    @property
    def successors(self) -> list[list[list[tuple[int, float, float]] | None]]:
        """successors[i][b] = [(j, p, r), ...] in node order, or None when b is untried in i."""
        if self._successors is None:
            n, nb = self.n_nodes, self.n_behaviours
            table: list[list] = [[None] * nb for _ in range(n)]
            ii, bb, jj = np.nonzero(self.counts > 0)
            ps = self.p[ii, bb, jj].tolist()
            rs = self.r[ii, bb, jj].tolist()
            for i, b, j, p, r in zip(ii.tolist(), bb.tolist(), jj.tolist(), ps, rs, strict=True):
                row = table[i][b]
                if row is None:
                    row = table[i][b] = []
                row.append((j, p, r))
            self._successors = table
        return self._successors

    @classmethod
    def from_records(cls, s: np.ndarray, b: np.ndarray, s_next: np.ndarray,
                     reward: np.ndarray, n_nodes: int, n_behaviours: int,
                     weights: np.ndarray | None = None) -> Stn:
        """Counts from dense node indices of the history's behaviour records (each record
        counted with its weight, 1 by default)."""
        key = (s * n_behaviours + b) * n_nodes + s_next
        size = n_nodes * n_behaviours * n_nodes
        counts = np.bincount(key, weights=weights, minlength=size).astype(float)
        sums = np.bincount(key, weights=reward if weights is None else weights * reward,
                           minlength=size)
        shape = (n_nodes, n_behaviours, n_nodes)
        return cls(counts.reshape(shape), sums.reshape(shape))

    @classmethod
    def from_model(cls, p: np.ndarray, r: np.ndarray, scale: float = 1000.0) -> Stn:
        """A hand-built STN (tests): probabilities ``p`` (n, B, n) and rewards ``r``."""
        p = np.asarray(p, dtype=float)
        counts = p * scale
        return cls(counts, counts * np.asarray(r, dtype=float))
