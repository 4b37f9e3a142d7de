"""Shared helpers: synthetic StepRecord-like records with known answers."""

from __future__ import annotations

import numpy as np
from stns_experiments.agents import Record


def make_trials(lengths, kinds=None, success=None, planned=True, dim=2):
    """Records of consecutive trials: trial k has lengths[k] behaviours then an arrival.

    kinds[k][j] / success[k][j] give the situation kind and the outcome of behaviour j of
    trial k (default "0" and None).
    """
    recs = []
    for t, n in enumerate(lengths, start=1):
        for j in range(n):
            kind = kinds[t - 1][j] if kinds else "0"
            succ = success[t - 1][j] if success else None
            recs.append(Record(index=len(recs) + 1, x=np.zeros(dim), situation=1 if kind != "0" else 0,
                               kind=kind, behaviour=0, target=None, planned=planned,
                               reward=0.0, next_situation=0, success=succ, ticks=3,
                               arrival=False, trial=t))
        recs.append(Record(index=len(recs) + 1, x=np.zeros(dim), situation=-1, kind="0",
                           behaviour=None, target=None, planned=False, reward=0.0,
                           next_situation=None, success=None, ticks=0, arrival=True, trial=t))
    return recs
