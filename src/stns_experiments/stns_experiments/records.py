"""Per-step records as columns: conversion from StepRecord objects and CSV (gzip) files.

A trial set's records are kept as a dict of numpy columns (a "table"), one row per behaviour
step, in the order the agent produced them. The column ``step`` numbers the rows 1, 2, ...
within the phase that produced them (for Exp. 2: from the fault on), so block ``b`` (0-based)
of size ``B`` holds the rows with ``b * B < step <= (b + 1) * B``.
"""

from __future__ import annotations

import csv
import gzip
import math
from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np

#: Columns of the per-step CSV, in order (the input vector follows as x0, x1, ...).
COLUMNS = (
    "step", "index", "trial", "situation", "kind", "behaviour", "target", "planned",
    "reward", "next_situation", "success", "ticks", "arrival",
)


def _opt_int(value) -> int:
    return -1 if value is None else int(value)


def _opt_bool(value) -> float:
    return math.nan if value is None else float(bool(value))


def to_table(records: Sequence, first_step: int = 1) -> dict[str, np.ndarray]:
    """Columns of a list of StepRecord-like objects (attribute access only).

    Missing optional values become -1 (integers) or NaN (``success``).
    """
    n = len(records)
    dim = len(np.atleast_1d(records[0].x)) if n else 0
    table = {
        "step": np.arange(first_step, first_step + n, dtype=np.int64),
        "index": np.array([int(r.index) for r in records], dtype=np.int64),
        "trial": np.array([int(r.trial) for r in records], dtype=np.int64),
        "situation": np.array([_opt_int(r.situation) for r in records], dtype=np.int64),
        "kind": np.array([str(r.kind) for r in records], dtype="<U1"),
        "behaviour": np.array([_opt_int(r.behaviour) for r in records], dtype=np.int64),
        "target": np.array([_opt_int(r.target) for r in records], dtype=np.int64),
        "planned": np.array([bool(r.planned) for r in records], dtype=bool),
        "reward": np.array([float(r.reward) for r in records], dtype=np.float64),
        "next_situation": np.array([_opt_int(r.next_situation) for r in records], dtype=np.int64),
        "success": np.array([_opt_bool(r.success) for r in records], dtype=np.float64),
        "ticks": np.array([int(r.ticks) for r in records], dtype=np.int64),
        "arrival": np.array([bool(r.arrival) for r in records], dtype=bool),
    }
    xs = np.array([np.atleast_1d(np.asarray(r.x, dtype=np.float64)) for r in records])
    table["x"] = xs.reshape(n, dim)
    return table


def empty_table(dim: int = 2) -> dict[str, np.ndarray]:
    return to_table([]) | {"x": np.zeros((0, dim))}


def concat(tables: Iterable[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    tables = [t for t in tables if len(t["step"])]
    if not tables:
        return empty_table()
    return {k: np.concatenate([t[k] for t in tables]) for k in tables[0]}


def head(table: dict[str, np.ndarray], n: int) -> dict[str, np.ndarray]:
    """The first ``n`` rows."""
    return {k: v[:n] for k, v in table.items()}


def write_csv(table: dict[str, np.ndarray], path: Path) -> None:
    """Write a table as CSV; gzip when the name ends in .gz."""
    path = Path(path)
    dim = table["x"].shape[1] if table["x"].ndim == 2 else 0
    opener = gzip.open if path.suffix == ".gz" else open
    with opener(path, "wt", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(list(COLUMNS) + [f"x{i}" for i in range(dim)])
        n = len(table["step"])
        for i in range(n):
            row = []
            for c in COLUMNS:
                v = table[c][i]
                if c == "success":
                    row.append("" if math.isnan(v) else int(v))
                elif c in ("planned", "arrival"):
                    row.append(int(v))
                elif c == "reward":
                    row.append(repr(float(v)))
                else:
                    row.append(v.item() if hasattr(v, "item") else v)
            row.extend(repr(float(v)) for v in table["x"][i])
            w.writerow(row)


def read_csv(path: Path) -> dict[str, np.ndarray]:
    """Read a table written by :func:`write_csv`."""
    path = Path(path)
    opener = gzip.open if path.suffix == ".gz" else open
    with opener(path, "rt", newline="") as fh:
        rows = list(csv.reader(fh))
    header, body = rows[0], rows[1:]
    cols = {name: [r[i] for r in body] for i, name in enumerate(header)}
    xnames = [h for h in header if h.startswith("x") and h[1:].isdigit()]
    table = {
        "step": np.array(cols["step"], dtype=np.int64),
        "index": np.array(cols["index"], dtype=np.int64),
        "trial": np.array(cols["trial"], dtype=np.int64),
        "situation": np.array(cols["situation"], dtype=np.int64),
        "kind": np.array(cols["kind"], dtype="<U1"),
        "behaviour": np.array(cols["behaviour"], dtype=np.int64),
        "target": np.array(cols["target"], dtype=np.int64),
        "planned": np.array(cols["planned"], dtype=np.int64).astype(bool),
        "reward": np.array(cols["reward"], dtype=np.float64),
        "next_situation": np.array(cols["next_situation"], dtype=np.int64),
        "success": np.array([math.nan if v == "" else float(v) for v in cols["success"]]),
        "ticks": np.array(cols["ticks"], dtype=np.int64),
        "arrival": np.array(cols["arrival"], dtype=np.int64).astype(bool),
    }
    table["x"] = np.array([[float(c) for c in col] for col in zip(*(cols[x] for x in xnames), strict=True)]
                          ).reshape(len(body), len(xnames))
    return table
