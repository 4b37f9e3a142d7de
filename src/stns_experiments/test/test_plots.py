"""The situation map's legend (stns_experiments.plots) on a small synthetic learner."""

from __future__ import annotations

import numpy as np

from stns_experiments import plots

SITUATIONS = [{"id": 1, "kind": "R", "behaviour": 0},
              {"id": 2, "kind": "T", "behaviour": 2, "parent": 1}]


def test_a_situation_without_a_cell_is_named_so_in_the_legend():
    labels = plots.situation_labels(np.array([[0, 1], [1, 1]]), SITUATIONS)
    assert labels == {1: "1: R \u2191 forward",
                      2: "2: T \u21bb clockwise -> 1 (nowhere on this map)"}


def test_the_map_of_a_learner_with_two_situations_is_drawn(tmp_path):
    # forward R ahead of the rover, the clockwise T to its left: both own cells
    def classify(v):
        return 1 if v[0] > 0 and abs(v[1]) < 20 else 2 if v[1] > 20 else 0

    labels = plots.situation_labels(
        np.array([[classify(np.array([x, y])) for x in (-50, 50)] for y in (0, 50)]), SITUATIONS)
    assert not any(s.endswith("(no cell of this map)") for s in labels.values())
    path = plots.situation_map(tmp_path / "map.png", classify, SITUATIONS, "t", resolution=21)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
