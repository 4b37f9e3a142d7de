"""StnsConfig: presets, validation, dict round trip."""

import dataclasses

import pytest

from stns_core import StnsConfig, StnsConfigError


def test_presets_carry_the_papers_parameters():
    e1 = StnsConfig.preset("exp1")
    assert (e1.n_init_r, e1.n_min_r, e1.n_init_t, e1.n_min_t) == (3, 3, 15, 7)
    assert (e1.r_min_r, e1.gamma, e1.p_min, e1.n_max) == (5.0, 0.7, 0.1, 7)
    assert (e1.history_size, e1.adjust_interval) == (1000, 100)
    e3 = StnsConfig.preset("exp3", seed=4)
    assert (e3.n_init_r, e3.n_min_r, e3.n_init_t, e3.n_min_t) == (9, 9, 20, 12)
    assert (e3.p_min, e3.history_size, e3.seed) == (0.2, 10000, 4)


def test_defaults_are_the_readings_that_learn():
    cfg = StnsConfig()
    assert cfg.random_stop == "situation_change"
    assert cfg.majority == "strict"
    assert cfg.boundary_refit == "every_step"
    assert cfg.target_lookahead_ticks == 0
    assert cfg.relabel == "after_modification"
    assert cfg.planner == "iprl"


def test_round_trip_and_replace():
    cfg = StnsConfig.preset("exp1", seed=9, planner="pia")
    assert StnsConfig.from_dict(cfg.to_dict()) == cfg
    assert cfg.replace(gamma=0.5).gamma == 0.5
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.gamma = 0.1  # type: ignore[misc]


@pytest.mark.parametrize("key,value,match", [
    ("gamma", 1.0, "gamma must be in"),
    ("gamma", float("nan"), "gamma must be finite"),
    ("p_min", -0.1, "p_min must be in"),
    ("n_init_r", 0, "n_init_r must be >= 1"),
    ("n_max", 2.5, "n_max must be an int"),
    ("history_size", True, "history_size must be an int"),
    ("planner", "dijkstra", "planner must be one of"),
    ("random_stop", "never", "random_stop must be one of"),
    ("majority", "simple", "majority must be one of"),
    ("boundary_refit", "sometimes", "boundary_refit must be one of"),
    ("relabel", "always", "relabel must be one of"),
    ("target_lookahead_ticks", -1, "target_lookahead_ticks must be >= 0"),
    ("cov_reg", 0.0, "cov_reg must be > 0"),
    ("target_stop", "centre", "target_stop must be one of"),
    ("plan_stop", "any", "plan_stop must be one of"),
    ("t_result", "any", "t_result must be one of"),
    ("margin_plan", "nearest_t", "margin_plan must be one of"),
    ("margin_plan_reach", 0.0, "margin_plan_reach must be > 0, got 0.0"),
    ("margin_plan_reach", float("inf"), "margin_plan_reach must be finite"),
    ("r_break_window", -1, "r_break_window must be >= 0"),
    ("r_break_window", 2.0, "r_break_window must be an int"),
    ("margin_plan_window", -1, "margin_plan_window must be >= 0"),
    ("nn_window", -5, "nn_window must be >= 0"),
    ("nn_window", "200", "nn_window must be an int"),
    ("useless", "zero", "useless must be one of"),
    ("no_plan", "greedy", "no_plan must be one of"),
    ("r_break_forget", "all", "r_break_forget must be one of"),
    ("r_break_fraction", 1.0, "r_break_fraction must be in \\[0, 1\\), got 1.0"),
    ("contradiction_radius", -0.1, "contradiction_radius must be >= 0 \\(0 = off\\), got -0.1"),
    ("contradiction_radius", float("nan"), "contradiction_radius must be finite"),
    ("stn_half_life", -1.0, "stn_half_life must be >= 0 \\(0 = off\\), got -1.0"),
    ("stn_half_life", float("inf"), "stn_half_life must be finite"),
    ("margin_stn", "window", "margin_stn must be one of"),
    ("miss_stop", "closest", "miss_stop must be one of"),
    ("miss_stop", False, "got the boolean False \\(in YAML, quote"),  # YAML's `off`
])
def test_bad_values_raise_named_errors(key, value, match):
    with pytest.raises(StnsConfigError, match=match):
        StnsConfig(**{key: value})


def test_unknown_keys_rejected():
    with pytest.raises(StnsConfigError, match="unknown StnsConfig keys: \\['gama'\\]"):
        StnsConfig.from_dict({"gama": 0.7})
    with pytest.raises(StnsConfigError, match="unknown StnsConfig keys"):
        StnsConfig.preset("exp1", nmax=3)
    with pytest.raises(StnsConfigError, match="unknown preset 'exp2'"):
        StnsConfig.preset("exp2")
    with pytest.raises(StnsConfigError, match="unknown StnsConfig keys"):
        StnsConfig().replace(foo=1)


@pytest.mark.parametrize("name", ["exp1", "exp3"])
def test_yaml_presets_match(name):
    from pathlib import Path

    yaml = pytest.importorskip("yaml")
    path = Path(__file__).resolve().parents[3] / "config" / f"stns_{name}.yaml"
    if not path.exists():
        pytest.skip(f"{path} not in this checkout")
    params = yaml.safe_load(path.read_text())["/**"]["ros__parameters"]
    assert StnsConfig.from_dict(params) == StnsConfig.preset(name)


def test_numpy_scalars_are_accepted_and_normalised():
    import json

    import numpy as np

    cfg = StnsConfig(seed=np.int64(3), gamma=np.float64(0.5), n_max=np.int32(4),
                     iprl_memo=np.bool_(False))
    assert type(cfg.seed) is int and type(cfg.gamma) is float and cfg.iprl_memo is False
    json.dumps(cfg.to_dict())
