"""The situation classifier (paper section 5.3, Fig. 3): an ordered list, first acceptance wins.

The ellipsoid tests of all situations run at once (stacked whitening matrices); the
nearest-neighbour test runs only for the situations whose ellipsoid contains the input, from
the top of the list, and stops at the first that accepts. Nothing accepts -> situation 0.
"""

from __future__ import annotations

import numpy as np

from .situation import Situation

MARGIN = 0  # situation 0, the margin space


class Classifier:
    """Classifies inputs with the current ordered list of situations.

    ``order`` is the discrimination tree (shared with the learner); call ``invalidate`` after
    any change of order or shapes. Instance changes are tracked by each situation itself.
    """

    def __init__(self, dim: int) -> None:
        self.dim = dim
        self.order: list[Situation] = []
        self._stale = True
        self._means = np.zeros((0, dim))
        self._whiten = np.zeros((0, dim, dim))
        self._b2 = np.zeros(0)
        self._kinds = np.zeros(0, dtype=object)

    def invalidate(self) -> None:
        self._stale = True

    def _rebuild(self) -> None:
        d = self.dim
        n = len(self.order)
        self._means = np.zeros((n, d))
        self._whiten = np.zeros((n, d, d))
        self._b2 = np.full(n, -1.0)  # never inside when not fitted
        self._kinds = np.array([sit.kind for sit in self.order], dtype=object)
        for k, sit in enumerate(self.order):
            if sit.fitted:
                self._means[k] = sit.mean
                self._whiten[k] = sit.whiten
                self._b2[k] = sit.boundary2()
        self._stale = False

    def _mahalanobis2(self, x: np.ndarray) -> np.ndarray:
        """Squared Mahalanobis distance of one input from every situation (list order)."""
        if self._stale:
            self._rebuild()
        z = np.matmul(self._whiten, (x - self._means)[:, :, None])[:, :, 0]
        return np.einsum("si,si->s", z, z)

    def classify(self, x: np.ndarray, hist_x: np.ndarray) -> int:
        """Situation id of one input (0 = margin space)."""
        if not self.order:
            return MARGIN
        d2 = self._mahalanobis2(x)
        for k in np.flatnonzero(d2 <= self._b2):
            sit = self.order[k]
            if sit.nn_accepts(x, hist_x):
                return sit.id
        return MARGIN

    def nearest(self, x: np.ndarray, reach: float, kind: str | None = None) -> int:
        """Id of the fitted situation (of ``kind``, if given) whose ellipsoid is nearest to
        ``x`` in Mahalanobis distance relative to its boundary, if within ``reach``
        boundaries (option ``margin_plan``); 0 if none."""
        if not self.order:
            return MARGIN
        d2 = self._mahalanobis2(x)
        fitted = self._b2 > 0.0
        if kind is not None:
            fitted &= self._kinds == kind
        if not fitted.any():
            return MARGIN
        rel = np.where(fitted, d2 / np.where(fitted, self._b2, 1.0), np.inf)
        k = int(np.argmin(rel))
        return self.order[k].id if rel[k] <= reach * reach else MARGIN

    def classify_batch(self, xs: np.ndarray, hist_x: np.ndarray) -> np.ndarray:
        """Situation ids of many inputs (same rule as ``classify``)."""
        out = np.zeros(len(xs), dtype=np.int64)
        if not self.order or len(xs) == 0:
            return out
        if self._stale:
            self._rebuild()
        open_ = np.ones(len(xs), dtype=bool)
        for k, sit in enumerate(self.order):
            if not sit.fitted:
                continue
            idx = np.flatnonzero(open_)
            if len(idx) == 0:
                break
            z = np.einsum("ij,kj->ik", xs[idx] - self._means[k], self._whiten[k])
            inside = idx[np.einsum("ij,ij->i", z, z) <= self._b2[k]]
            if len(inside) == 0:
                continue
            acc = inside[sit.nn_accepts_batch(xs[inside], hist_x)]
            out[acc] = sit.id
            open_[acc] = False
        return out
