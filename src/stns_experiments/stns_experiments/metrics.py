"""Figures of merit computed from per-step record tables (see records.py).

Definitions (docs/RESULTS.md repeats them; every figure of the package uses these):

* A *behaviour step* is one record: a behaviour, or a goal arrival (paper footnote 8).
  Steps are numbered 1, 2, ... within a phase; block ``b`` of size ``B`` holds steps
  ``b*B+1 .. (b+1)*B``.
* *Behaviours to goal* of a span of steps = behaviours (non-arrival records) in the span
  divided by goal arrivals in the span. Over several trial sets the counts are pooled
  (sum of behaviours / sum of arrivals), which stays finite when one set has a block
  without an arrival. A span with no arrival at all has no value (NaN).
* *Final level* = behaviours to goal over the last ``final_window`` (1000) steps.
* *Convergence (block rule, the one reported as ``convergence_step``)*: the first block
  ``b`` from which every block's behaviours to goal stays within ``tol`` (10 %) of the
  final level; ``convergence_step = b * B`` (the steps done before that block). None when
  even the last block is outside.
* *Convergence (trailing rule)*: the first block end ``t`` (with ``t >= window``, 500) from
  which the behaviours to goal over the trailing window ``(t - window, t]`` stays within
  ``tol`` of the final level at every later block end; reported as ``t``.
* *Success rate* of R (T) situations = fraction of *planned* behaviours that started in an
  R (T) situation and succeeded (reached the target situation or, from an R-situation, the
  goal reward), over the final window.
* *Within two behaviours* = fraction of the trials that both started and reached the goal
  inside the final window that needed at most two behaviours.
"""

from __future__ import annotations

import math

import numpy as np


def block_counts(table: dict[str, np.ndarray], block_size: int, n_steps: int
                 ) -> tuple[np.ndarray, np.ndarray]:
    """(behaviours, arrivals) per block of ``block_size`` steps over steps 1..n_steps."""
    n_blocks = math.ceil(n_steps / block_size)
    step = table["step"]
    keep = (step >= 1) & (step <= n_steps)
    blk = (step[keep] - 1) // block_size
    arr = table["arrival"][keep]
    behaviours = np.bincount(blk[~arr], minlength=n_blocks)[:n_blocks]
    arrivals = np.bincount(blk[arr], minlength=n_blocks)[:n_blocks]
    return behaviours.astype(np.int64), arrivals.astype(np.int64)


def ratio(behaviours, arrivals):
    """Behaviours per arrival, elementwise; NaN where there is no arrival."""
    b = np.asarray(behaviours, dtype=np.float64)
    a = np.asarray(arrivals, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(a > 0, b / np.where(a > 0, a, 1.0), np.nan)


def in_span(table: dict[str, np.ndarray], start: int, end: int) -> np.ndarray:
    """Mask of the records of steps start < step <= end."""
    return (table["step"] > start) & (table["step"] <= end)


def span_counts(table: dict[str, np.ndarray], start: int, end: int) -> tuple[int, int]:
    """(behaviours, arrivals) over steps start < step <= end."""
    arr = table["arrival"][in_span(table, start, end)]
    return int((~arr).sum()), int(arr.sum())


def span_ticks(table: dict[str, np.ndarray], start: int, end: int) -> int:
    """Control ticks spent in the behaviours of steps start < step <= end: the time a
    learner takes, where behaviour steps of different stop rules are not comparable (a grid
    learner's behaviour ends at every cell change)."""
    return int(table["ticks"][in_span(table, start, end)].sum())


def behaviours_to_goal(table: dict[str, np.ndarray], start: int, end: int) -> float:
    b, a = span_counts(table, start, end)
    return float(ratio(b, a))


def pooled_curve(tables: list[dict[str, np.ndarray]], block_size: int, n_steps: int
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Pooled behaviours to goal per block, per-set curves, and pooled counts.

    Returns (curve, per_set[n_sets, n_blocks], behaviours_sum, arrivals_sum).
    """
    n_blocks = math.ceil(n_steps / block_size)
    bs = np.zeros((len(tables), n_blocks), dtype=np.int64)
    ar = np.zeros((len(tables), n_blocks), dtype=np.int64)
    for i, t in enumerate(tables):
        bs[i], ar[i] = block_counts(t, block_size, n_steps)
    return ratio(bs.sum(0), ar.sum(0)), ratio(bs, ar), bs.sum(0), ar.sum(0)


def convergence_block(curve, final_level: float, block_size: int, tol: float = 0.1
                      ) -> int | None:
    """Block rule: steps before the first block from which every block is within tol."""
    curve = np.asarray(curve, dtype=np.float64)
    if not np.isfinite(final_level) or len(curve) == 0:
        return None
    ok = np.isfinite(curve) & (np.abs(curve - final_level) <= tol * final_level * (1 + 1e-9))
    if not ok[-1]:
        return None
    bad = np.nonzero(~ok)[0]
    first = 0 if len(bad) == 0 else int(bad[-1]) + 1
    return first * block_size


def trailing_curve(behaviours, arrivals, block_size: int, window: int) -> np.ndarray:
    """Behaviours to goal over the trailing ``window`` steps at each block end (NaN before)."""
    k = max(1, window // block_size)
    b = np.asarray(behaviours, dtype=np.float64)
    a = np.asarray(arrivals, dtype=np.float64)
    cb = np.concatenate([[0.0], np.cumsum(b)])
    ca = np.concatenate([[0.0], np.cumsum(a)])
    out = np.full(len(b), np.nan)
    for j in range(k - 1, len(b)):
        out[j] = float(ratio(cb[j + 1] - cb[j + 1 - k], ca[j + 1] - ca[j + 1 - k]))
    return out


def convergence_trailing(behaviours, arrivals, final_level: float, block_size: int,
                         window: int = 500, tol: float = 0.1) -> int | None:
    """Trailing rule: the first block end from which the trailing window stays within tol."""
    tr = trailing_curve(behaviours, arrivals, block_size, window)
    if not np.isfinite(final_level) or len(tr) == 0:
        return None
    ok = np.isfinite(tr) & (np.abs(tr - final_level) <= tol * final_level * (1 + 1e-9))
    if not ok[-1]:
        return None
    bad = np.nonzero(~ok)[0]
    first = 0 if len(bad) == 0 else int(bad[-1]) + 1
    first = max(first, max(1, window // block_size) - 1)
    return (first + 1) * block_size


def first_reaching(behaviours, arrivals, level: float, block_size: int, window: int = 500,
                   tol: float = 0.1) -> int | None:
    """First block end from which the trailing window stays at or below ``(1+tol)*level``."""
    tr = trailing_curve(behaviours, arrivals, block_size, window)
    ok = np.isfinite(tr) & (tr <= (1.0 + tol) * level * (1 + 1e-9))
    if len(ok) == 0 or not ok[-1]:
        return None
    bad = np.nonzero(~ok)[0]
    first = 0 if len(bad) == 0 else int(bad[-1]) + 1
    first = max(first, max(1, window // block_size) - 1)
    return (first + 1) * block_size


def first_block_at_or_below(curve, level: float, block_size: int, tol: float = 0.1
                            ) -> int | None:
    """Steps before the first block from which every block is at or below (1+tol)*level."""
    curve = np.asarray(curve, dtype=np.float64)
    ok = np.isfinite(curve) & (curve <= (1.0 + tol) * level * (1 + 1e-9))
    if len(ok) == 0 or not ok[-1]:
        return None
    bad = np.nonzero(~ok)[0]
    first = 0 if len(bad) == 0 else int(bad[-1]) + 1
    return first * block_size


def success_counts(table: dict[str, np.ndarray], kind: str, start: int, end: int,
                   situations=None) -> tuple[int, int]:
    """(successes, planned behaviours with a known outcome) from ``kind`` situations."""
    sel = (in_span(table, start, end) & table["planned"] & (table["kind"] == kind)
           & ~table["arrival"] & np.isfinite(table["success"]))
    if situations is not None:
        sel &= np.isin(table["situation"], np.asarray(list(situations), dtype=np.int64))
    s = table["success"][sel]
    return int((s > 0.5).sum()), int(len(s))


def trial_lengths(table: dict[str, np.ndarray], start: int, end: int) -> np.ndarray:
    """Behaviours needed by each trial that started and reached the goal in (start, end]."""
    step, trial, arr = table["step"], table["trial"], table["arrival"]
    out = []
    if len(step) == 0:
        return np.zeros(0, dtype=np.int64)
    # Trials are contiguous runs of equal trial ids ending with an arrival record.
    change = np.nonzero(np.diff(trial) != 0)[0] + 1
    starts = np.concatenate([[0], change])
    ends = np.concatenate([change, [len(step)]])
    for s, e in zip(starts, ends, strict=True):
        if step[s] <= start or step[e - 1] > end or not arr[e - 1]:
            continue
        out.append(int((~arr[s:e]).sum()))
    return np.asarray(out, dtype=np.int64)


def within_counts(table: dict[str, np.ndarray], start: int, end: int, k: int = 2
                  ) -> tuple[int, int]:
    """(trials needing at most k behaviours, complete trials) in (start, end]."""
    lengths = trial_lengths(table, start, end)
    return int((lengths <= k).sum()), int(len(lengths))


def frac(num: int, den: int) -> float | None:
    return None if den == 0 else num / den


def arrivals_per_100(table: dict[str, np.ndarray]) -> float | None:
    n = len(table["step"])
    return None if n == 0 else 100.0 * float(table["arrival"].sum()) / n


def finite_or_none(v) -> float | None:
    """JSON-friendly float: None for NaN/inf/None."""
    if v is None:
        return None
    v = float(v)
    return v if math.isfinite(v) else None


def percentile_band(per_set: np.ndarray, lo: float = 25.0, hi: float = 75.0
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Inter-quartile band over trial sets per block, ignoring blocks without arrival."""
    per_set = np.asarray(per_set, dtype=np.float64)
    n = per_set.shape[1] if per_set.ndim == 2 else 0
    low, high = np.full(n, np.nan), np.full(n, np.nan)
    for j in range(n):
        col = per_set[:, j]
        col = col[np.isfinite(col)]
        if len(col):
            low[j], high[j] = np.percentile(col, [lo, hi])
    return low, high
