"""Shared helpers: a learner fed records by hand, with labels under the test's control."""

import numpy as np
import pytest
from stns_core.categorical import Learner
from stns_core.config import StnsConfig


def make_learner(dim=2, n_behaviours=4, **overrides):
    base = dict(n_init_r=3, n_min_r=3, n_init_t=5, n_min_t=3, adjust_interval=10**6,
                history_size=200)
    base.update(overrides)
    return Learner(StnsConfig(**base), dim, n_behaviours)


def ring(center, radius=2.0, n=8):
    ang = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    return np.stack([center[0] + radius * np.cos(ang), center[1] + radius * np.sin(ang)], 1)


@pytest.fixture
def learner_factory():
    return make_learner
