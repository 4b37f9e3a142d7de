"""A situation (paper sections 5.1, 5.2): attributes and the bitten hyper-ellipsoid.

Macroscopic test: Mahalanobis distance from the mean of the positive instances, with their
(regularised) sample covariance, within the boundary (the farthest positive instance,
operation 2). Microscopic test, only inside: nearest neighbour among the positive and
negative instances, each axis scaled by the positive instances' standard deviation; the input
belongs if the nearest instance is positive.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

R_KIND = "R"
T_KIND = "T"
BOUNDARY_TOL = 1e-9  # relative: the farthest positive instance itself is inside


def regularised_cov(points: np.ndarray, cov_reg: float, mean: np.ndarray | None = None
                    ) -> np.ndarray:
    """Sample covariance plus ``cov_reg * trace/d`` (and a tiny absolute floor) on the diagonal.

    Positive definite for any number of points (even one, or collinear ones), so a Cholesky
    factorisation always exists and no singular matrix is ever inverted.
    """
    n, d = points.shape
    if mean is None:
        mean = points.mean(axis=0)
    if n > 1:
        c = points - mean
        cov = (c.T @ c) / (n - 1)
    else:
        cov = np.zeros((d, d))
    scale = float(np.trace(cov)) / d
    eps = cov_reg * scale + 1e-9 * (1.0 + float(mean @ mean) / d)
    cov[np.diag_indices(d)] += eps
    return cov


def t_result_mask(hist, b: int, parent: int, unpunished: bool = False) -> np.ndarray:
    """History records in which behaviour ``b`` reached situation ``parent`` (a T-result);
    ``unpunished`` (option ``t_result="unpunished"``): only those without a penalty."""
    m = hist.valid & (hist.b == b) & ~hist.terminal & (hist.s_next == parent)
    return m & (hist.reward >= 0.0) if unpunished else m


def in_nn_window(members: np.ndarray, recent: np.ndarray | None) -> np.ndarray:
    """Option ``nn_window``: the ``members`` (history-slot mask) among the newest records
    (``recent``), or all of them when none is, or without the option (``recent`` None)."""
    if recent is not None:
        inside = members & recent
        if inside.any():
            return inside
    return members


class Situation:
    """One situation: attributes, instance populations (masks over history slots), shape."""

    def __init__(self, sid: int, kind: str, behaviour: int, capacity: int, dim: int,
                 parent: int = 0, reward_key: float = 0.0, created: int = 0) -> None:
        self.id = int(sid)
        self.kind = kind
        self.behaviour = int(behaviour)
        self.parent = int(parent)  # T-situation's parent id (0 for R)
        self.reward_key = float(reward_key)  # R-situation's goal reward (0.0 for T)
        self.created = int(created)
        self.pos = np.zeros(capacity, dtype=bool)
        self.neg = np.zeros(capacity, dtype=bool)
        self.utility = 0.0
        self.mean = np.zeros(dim)
        self.cov = np.eye(dim)
        self.boundary = 0.0
        self.fitted = False
        self._derive_factors()
        self.shape_dirty = True  # positives changed since the last fit
        self.nn_dirty = True  # instance populations changed since the NN cache was built
        self._nn_pts = np.zeros((0, dim))
        self._nn_sqn = np.zeros(0)
        self._nn_lab = np.zeros(0, dtype=bool)
        # option nn_window: the history slots of the newest records (shared with the
        # learner); None: the NN test uses every instance (the paper)
        self.nn_recent: np.ndarray | None = None

    # -- attributes -------------------------------------------------------------------
    def attributes(self) -> tuple:
        if self.kind == R_KIND:
            return (R_KIND, self.behaviour, self.reward_key)
        return (T_KIND, self.behaviour, self.parent)

    def result_met(self, b: int, reward: float, s_next: int, terminal: bool,
                   r_min_r: float, unpunished: bool = False) -> bool:
        """Did a behaviour step (b, reward, reached s_next) meet this situation's definition?
        ``unpunished`` (option ``t_result="unpunished"``): a T-result also needs reward >= 0."""
        if b != self.behaviour:
            return False
        if self.kind == R_KIND:
            return reward > r_min_r and round(reward, 6) == self.reward_key
        return (not terminal) and s_next == self.parent and (not unpunished or reward >= 0.0)

    def positive_mask(self, hist, r_min_r: float, unpunished: bool = False) -> np.ndarray:
        """All history records meeting the definition (extraction / redefinition / relabel)."""
        if self.kind == R_KIND:
            return (hist.valid & (hist.b == self.behaviour) & (hist.reward > r_min_r)
                    & (np.round(hist.reward, 6) == self.reward_key))
        return t_result_mask(hist, self.behaviour, self.parent, unpunished)

    @property
    def n_pos(self) -> int:
        return int(np.count_nonzero(self.pos))

    @property
    def n_neg(self) -> int:
        return int(np.count_nonzero(self.neg & ~self.pos))

    # -- shape (operation 2) ----------------------------------------------------------
    def fit(self, x: np.ndarray, cov_reg: float, trim: float = 1.0,
            quantile: float = 1.0) -> None:
        """Mean, regularised covariance and boundary on the farthest positive instance.

        ``trim < 1`` (option ``shape_trim``, not the paper's): after the full fit, keep the
        ``ceil(trim * n)`` positives nearest to the mean (Mahalanobis; at least d + 1), refit
        mean and covariance on them and put the boundary on the farthest kept one.
        ``quantile < 1`` (option ``boundary_quantile``): the boundary on that quantile of the
        (kept) positives' Mahalanobis distances instead of the farthest one.
        """
        pts = x[self.pos]
        self.shape_dirty = False
        self.nn_dirty = True
        if len(pts) == 0:
            self.fitted = False
            return
        self.mean = pts.mean(axis=0)
        self.cov = regularised_cov(pts, cov_reg, self.mean)
        self._derive_factors()
        z = np.einsum("ij,kj->ik", pts - self.mean, self.whiten)  # (BLAS threads: slow here)
        d2 = np.einsum("ij,ij->i", z, z)
        if trim < 1.0:
            n, d = pts.shape
            k = max(d + 1, int(np.ceil(trim * n)))
            if k < n:
                pts = pts[np.sort(np.argsort(d2, kind="stable")[:k])]
                self.mean = pts.mean(axis=0)
                self.cov = regularised_cov(pts, cov_reg, self.mean)
                self._derive_factors()
                z = np.einsum("ij,kj->ik", pts - self.mean, self.whiten)
                d2 = np.einsum("ij,ij->i", z, z)
        if quantile < 1.0:
            self.boundary = float(np.sqrt(np.quantile(d2, quantile)))
        else:
            self.boundary = float(np.sqrt(np.max(d2)))
        self.fitted = True

    def _derive_factors(self) -> None:
        chol = np.linalg.cholesky(self.cov)
        # inverse of the lower Cholesky factor: z = whiten @ (x - mean), |z|^2 = Mahalanobis^2
        self.whiten = np.linalg.inv(chol)
        self.std = np.sqrt(np.diag(self.cov))

    def set_shape(self, mean, cov, boundary, fitted) -> None:
        """Restore a saved shape exactly (state_io)."""
        self.mean = np.array(mean, dtype=float)
        self.cov = np.array(cov, dtype=float)
        self.boundary = float(boundary)
        self.fitted = bool(fitted)
        self._derive_factors()
        self.shape_dirty = False
        self.nn_dirty = True

    def boundary2(self) -> float:
        return self.boundary * self.boundary * (1.0 + BOUNDARY_TOL) + 1e-12

    def mahalanobis2(self, x: np.ndarray) -> np.ndarray:
        z = np.einsum("ij,kj->ik", np.atleast_2d(x) - self.mean, self.whiten)
        return np.einsum("ij,ij->i", z, z)

    # -- microscopic test -------------------------------------------------------------
    def nn_members(self) -> np.ndarray:
        """Slots of the instances the NN test compares: all positives and negatives, or with
        option ``nn_window`` those among the newest records if there are any."""
        return in_nn_window(self.pos | self.neg, self.nn_recent)

    def _nn_cache(self, x: np.ndarray) -> None:
        members = self.nn_members()
        pts = x[members] / self.std
        self._nn_pts = np.ascontiguousarray(pts)
        self._nn_sqn = np.einsum("ij,ij->i", pts, pts)
        self._nn_lab = self.pos[members]
        self.nn_dirty = False

    def nn_accepts(self, xq: np.ndarray, hist_x: np.ndarray) -> bool:
        """Nearest instance (std-scaled Euclidean) is positive; first index wins ties."""
        if self.nn_dirty:
            self._nn_cache(hist_x)
        if len(self._nn_lab) == 0:
            return False
        q = xq / self.std
        score = self._nn_sqn - 2.0 * (self._nn_pts @ q)
        return bool(self._nn_lab[int(np.argmin(score))])

    def nn_accepts_batch(self, xq: np.ndarray, hist_x: np.ndarray) -> np.ndarray:
        """``nn_accepts`` for many inputs (a k-d tree over the scaled instances)."""
        if self.nn_dirty:
            self._nn_cache(hist_x)
        out = np.zeros(len(xq), dtype=bool)
        if len(self._nn_lab) == 0 or len(xq) == 0:
            return out
        _, nearest = cKDTree(self._nn_pts).query(xq / self.std, k=1)
        return self._nn_lab[nearest]

    def accepts(self, xq: np.ndarray, hist_x: np.ndarray) -> bool:
        """Full bitten-ellipsoid test: ellipsoid first, nearest neighbour only inside."""
        if not self.fitted:
            return False
        if self.mahalanobis2(xq)[0] > self.boundary2():
            return False
        return self.nn_accepts(xq, hist_x)
