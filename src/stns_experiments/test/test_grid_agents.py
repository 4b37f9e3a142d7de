"""The grid baselines of §7.5: cells of the 2-D and 8-D grids, and the model-based learner's
sparse form against its dense one."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from stns_experiments.agents import GridAgent, range_code
from stns_experiments.config import DEFAULTS, ExperimentError, resolve, validate

WS_CONFIG = Path(__file__).resolve().parents[3] / "config"


def _agent(grid: str, learner: str = "q", **kw) -> GridAgent:
    return GridAgent(grid, learner, np.random.default_rng(0), **kw)


def test_8d_orthogonal_grid_has_the_papers_state_count():
    # §7.5: "the number of states is ... 321489 with the representation shown in Fig. 13b"
    assert _agent("orthogonal", range_edges=(20.0, 32.0)).n_cells == 321489
    assert _agent("polar", range_edges=(20.0, 32.0)).n_cells == 96 * 3 ** 6
    assert _agent("orthogonal").n_cells == 441


def test_range_code_counts_levels_in_base_three():
    # levels 0, 1, 2, 0, 1, 2 (an edge belongs to the level above it)
    ranges = np.array([10.0, 25.0, 40.0, 19.99, 20.0, 32.0])
    assert range_code(ranges, (20.0, 32.0)) == 0 + 1 * 3 + 2 * 9 + 0 * 27 + 1 * 81 + 2 * 243
    assert range_code(np.full(6, 100.0), (20.0, 32.0)) == 3 ** 6 - 1


def test_8d_state_splits_a_goal_cell_by_ranges_and_2d_ignores_them():
    far = np.array([30.0, 0.0, 50, 50, 50, 50, 50, 50])
    near_front = far.copy()
    near_front[2] = 5.0
    a8, a2 = _agent("polar", range_edges=(20.0, 32.0)), _agent("polar")
    assert a8.state(far) != a8.state(near_front)
    assert a8.state(far) // 3 ** 6 == a2.state(far) == a2.state(near_front)
    assert a8.state(near_front) == a8.state(far) - 2   # sector 0 from level 2 to level 0


def test_sparse_model_matches_the_dense_one():
    rng = np.random.default_rng(5)
    dense = _agent("polar", "model", sparse_model=False)
    sparse = _agent("polar", "model", sparse_model=True)
    assert not dense.sparse and sparse.sparse
    cells = rng.choice(dense.n_cells, size=12, replace=False)   # a few cells, many repeats
    for _ in range(400):
        s, b = int(rng.choice(cells)), int(rng.integers(4))
        terminal = rng.random() < 0.1
        r = 10.0 if terminal else float(rng.choice([0.0, 0.0, -1.0]))
        s2 = None if terminal else int(rng.choice(cells))
        dense.learn(s, b, r, s2, terminal)
        sparse.learn(s, b, r, s2, terminal)
        np.testing.assert_allclose(sparse.q, dense.q, rtol=0, atol=1e-9)
    assert not np.allclose(dense.q, 10.0)   # the model did learn something


def test_large_grids_choose_the_sparse_model():
    assert _agent("orthogonal", "model", range_edges=(20.0, 32.0)).sparse
    assert not _agent("polar", "model").sparse


def test_grid_exp3_file_is_valid():
    p = resolve("grid", WS_CONFIG / "grid-exp3.yaml")
    assert p["range_edges"] == [20.0, 32.0] and p["world"]["preset"] == "exp3"


@pytest.mark.parametrize(("edges", "match"), [
    ([32.0, 20.0], r"range_edges must increase, got \[32.0, 20.0\]"),
    ([0.0], r"range_edges\[\] must be > 0.0, got 0.0"),
    ("20", r"range_edges must be a list of range boundaries in u, got '20'"),
    ([10, 20, 30, 40], r"at most 3 boundaries .*got 4"),
    ([float("nan")], r"range_edges\[\] must be a finite number, got nan"),
])
def test_bad_range_edges_are_named(edges, match):
    with pytest.raises(ExperimentError, match=match):
        validate("grid", {**DEFAULTS["grid"], "range_edges": edges})


def test_range_edges_need_a_world_with_a_range_sensor():
    from stns_experiments.experiments import check_params
    p = validate("grid", {**DEFAULTS["grid"], "range_edges": [20.0, 32.0]})
    with pytest.raises(ExperimentError, match=r"world preset 'exp1' has no range sensor"):
        check_params(p)
    check_params({**p, "world": {"preset": "exp3", "overrides": {}}})
