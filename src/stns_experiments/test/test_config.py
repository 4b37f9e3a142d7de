"""Parameters: presets, YAML files, validation errors naming the value, CLI exit codes."""

from __future__ import annotations

from pathlib import Path

import pytest
from stns_experiments.cli import main
from stns_experiments.config import (
    DEFAULTS,
    EXPERIMENTS,
    ExperimentError,
    parse_set,
    resolve,
    validate,
)

WS_CONFIG = Path(__file__).resolve().parents[3] / "config"


@pytest.mark.parametrize("exp", EXPERIMENTS)
def test_workspace_yaml_files_are_valid_and_match_the_presets(exp):
    path = WS_CONFIG / f"{exp}.yaml"
    assert path.is_file(), path
    p = resolve(exp, path)
    d = validate(exp, DEFAULTS[exp])
    for key, value in d.items():
        assert p[key] == value, key


def test_paper_numbers_in_presets():
    assert DEFAULTS["exp1"]["trial_sets"] == 20 and DEFAULTS["exp1"]["steps"] == 10000
    assert DEFAULTS["exp2-sensor"]["levels"] == [10, 15, 20, 25, 90, 180]
    assert DEFAULTS["exp2-actuator"]["levels"] == [5, 10, 15]
    assert DEFAULTS["exp2-sensor"]["block_size"] == 250
    assert DEFAULTS["exp3"]["steps"] == 28000


@pytest.mark.parametrize(("text", "match"), [
    ("trial_sets: 0\n", r"trial_sets must be in \[1, 10000\], got 0"),
    ("steps: ten\n", r"steps must be an integer, got 'ten'"),
    ("steps: 1.5\n", r"steps must be an integer, got 1.5"),
    ("seed: -3\n", r"seed must be in .*got -3"),
    ("bogus: 1\n", r"unknown key\(s\) \['bogus'\]"),
    ("world: exp1\n", r"world must be a mapping"),
    ("agent: {preset: exp1, extra: 1}\n", r"unknown key\(s\) \['extra'\] in agent"),
    ("experiment: exp3\n", r"the file is for 'exp3', not 'exp1'"),
    ("convergence_tol: 0\n", r"convergence_tol must be > 0.0, got 0"),
    ("- a\n- b\n", r"must hold a mapping, got list"),
    # PyYAML keeps the last of two: the first, maybe the one meant, was silently dropped
    ("steps: 5\nseed: 1\nsteps: 6\n", r"bad.yaml' is not valid YAML: key 'steps' is given "
                                       r"twice at line 3, column 1$"),
    ("agent:\n  overrides: {gamma: 0.5, gamma: 0.6}\n", r"key 'gamma' is given twice at line 2"),
    ("steps: [1, \n", r"bad.yaml' is not valid YAML: expected the node content, but found '<stream end>' at "
                        r"line 2, column 1$"),
])
def test_bad_yaml_values_name_the_value(tmp_path, text, match):
    f = tmp_path / "bad.yaml"
    f.write_text(text)
    with pytest.raises(ExperimentError, match=match) as e:
        resolve("exp1", f)
    assert "<unicode string>" not in str(e.value)  # a YAML error points into the file itself


def test_a_config_file_that_is_not_text_is_named(tmp_path):
    f = tmp_path / "bin.yaml"
    f.write_bytes(b"\xff\xfe\x00steps: 5\n")  # a UTF-16 file, or a binary one by mistake
    with pytest.raises(ExperimentError, match=r"config file '.*bin.yaml' is not UTF-8 text: "
                                              r"byte 0xff at offset 0"):
        resolve("exp1", f)


def test_exp2_and_grid_values_are_checked(tmp_path):
    f = tmp_path / "x.yaml"
    f.write_text("levels: [5, 120]\n")
    with pytest.raises(ExperimentError, match=r"a slowdown must be in \[0, 100\) %, got 120"):
        resolve("exp2-actuator", f)
    f.write_text("fault: wheel\n")
    with pytest.raises(ExperimentError, match=r"fault must be one of .* got 'wheel'"):
        resolve("exp2-sensor", f)
    f.write_text("grids: [hex]\n")
    with pytest.raises(ExperimentError, match=r"grids must be .* got \['hex'\]"):
        resolve("grid", f)
    f.write_text("gamma: 1.5\n")
    with pytest.raises(ExperimentError, match=r"gamma must be <= 1.0, got 1.5"):
        resolve("grid", f)


def test_missing_file_and_overrides(tmp_path):
    with pytest.raises(ExperimentError, match=r"cannot read config file .*nope.yaml"):
        resolve("exp1", tmp_path / "nope.yaml")
    p = resolve("exp1", None, use_workspace_file=False,
                overrides={"steps": 50, "agent": {"overrides": {"gamma": 0.5}}})
    assert p["steps"] == 50 and p["agent"] == {"preset": "exp1", "overrides": {"gamma": 0.5}}
    assert p["final_window"] == 50  # clipped to the run length
    assert parse_set("agent.overrides.p_min=0.2") == (["agent", "overrides", "p_min"], 0.2)
    assert parse_set("agent.overrides.miss_stop=never")[1] == "never"
    with pytest.raises(ExperimentError, match=r"--set expects KEY=VALUE, got 'oops'"):
        parse_set("oops")


@pytest.mark.parametrize(("argv", "match"), [
    (["exp9"], "invalid choice: 'exp9'"),
    (["exp1", "--trial-sets", "0"], "--trial-sets must be >= 1, got '0'"),
    (["exp1", "--steps", "abc"], "--steps must be an integer, got 'abc'"),
    (["exp1", "--seed", "-1"], "--seed must be >= 0, got '-1'"),
    (["exp1", "--config", "/nonexistent.yaml"], "--config: no such file '/nonexistent.yaml'"),
    (["exp1", "--from", "/tmp"], "--from applies to exp2-sensor, exp2-actuator and grid"),
    (["exp1", "--set", "steps=0"], "steps must be in|steps must be >= 1, got 0"),
    (["exp1", "--set", "agent.overrides.gamma=7"], "agent: "),
    (["exp1", "--set", "world.overrides.room_size=-1"], "world: "),
    (["exp1", "--set", "agent.overrides.miss_stop=off"], "got the boolean False .in YAML, quote"),
    (["exp2-sensor", "--from", "/nonexistent"], "--from: no such directory '/nonexistent'"),
    # each trial set's learner seed comes from the root seed: this one was silently replaced
    (["exp1", "--set", "agent.overrides.seed=5"],
     r"agent.overrides.seed is not used: each trial set's learner seed comes from the root "
     r"seed \(--seed\); drop it"),
    (["exp1", "--set", "steps=abc", "--steps", "100"],
     r"steps is given twice: --set steps='abc' and --steps; give one"),
    (["exp1", "--set", "figures=maybe", "--no-figures"], r"figures is given twice: .*--no-figures"),
    (["exp2-sensor", "--levels", "10", "10", "15"],
     r"levels: 10 given more than once in \[10, 10, 15\]"),
])
def test_cli_bad_arguments_exit_2_with_message(argv, match, capsys):
    with pytest.raises(SystemExit) as exc:
        code = main(argv)
        raise SystemExit(code)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    import re
    assert re.search(match, err), err


def test_exp1_improved_yaml_is_exp1_plus_the_seven_readings():
    p = resolve("exp1", WS_CONFIG / "exp1-improved.yaml")
    d = validate("exp1", DEFAULTS["exp1"])
    assert p["agent"]["overrides"] == {
        "target_stop": "deepest", "target_lookahead_ticks": 1, "plan_stop": "higher_utility",
        "t_result": "unpunished", "margin_plan": "nearest_r_bitten", "margin_plan_reach": 2.5,
        "margin_plan_window": 0, "miss_stop": "all",
        "pending_r_try": "planned_nearest_success", "pending_t_try": "planned_nearest_success"}
    assert {k: v for k, v in p.items() if k not in ("agent", "config_source")} == {
        k: v for k, v in d.items() if k not in ("agent", "config_source")}


def test_exp3_improved_yaml_is_exp3_plus_the_best_measured_options():
    """config/exp3-improved.yaml: the best learner of the Exp. 3 runs in docs/RESULTS.md (the
    runs gave its options with --set), on the paper's Exp. 3 file, with §7.3's p_min."""
    p = resolve("exp3", WS_CONFIG / "exp3-improved.yaml")
    base = resolve("exp3", WS_CONFIG / "exp3.yaml")
    assert p["agent"]["overrides"] == {
        "exploration": "greedy_goal", "greedy_prob": 1.0, "greedy_align_deg": 5.0,
        "t_result": "unpunished", "plan_stop": "higher_utility", "target_stop": "deepest",
        "target_lookahead_ticks": 1, "useless": "no_positive_plan", "no_plan": "margin_plan",
        "p_min": 0.2}
    assert p["agent"]["preset"] == "exp3" and p["trial_sets"] == 4
    assert {k: v for k, v in p.items() if k not in ("agent", "config_source")} == {
        k: v for k, v in base.items() if k not in ("agent", "config_source")}


@pytest.mark.parametrize("exp", ["exp2-sensor", "exp2-actuator"])
def test_exp2_improved_yaml_is_the_exp2_file_plus_the_readings(exp):
    """config/exp2-*-improved.yaml: the paper's Exp. 2 file, 4000 steps after the fault (as
    the runs of docs/RESULTS.md), and the readings of config/exp1-improved.yaml but
    miss_stop (measured in Exp. 2 on one seed only) and pending_t_try (not in the runs of
    docs/RESULTS.md's Exp. 2 rows) plus the NN window and the blank restart on an
    R-situation whose last 20 uses all missed."""
    p = resolve(exp, WS_CONFIG / f"{exp}-improved.yaml")
    base = resolve(exp, WS_CONFIG / f"{exp}.yaml")
    e1 = dict(resolve("exp1", WS_CONFIG / "exp1-improved.yaml")["agent"]["overrides"])
    assert e1.pop("miss_stop") == "all"
    assert e1.pop("pending_t_try") == "planned_nearest_success"
    assert p["agent"]["overrides"] == {**e1, "nn_window": 300,
                                       "r_break_window": 20, "r_break_fraction": 0.95,
                                       "r_break_forget": "history"}
    assert p["steps"] == 4000 and base["steps"] == 5000
    assert {k: v for k, v in p.items() if k not in ("agent", "config_source", "steps")} == {
        k: v for k, v in base.items() if k not in ("agent", "config_source", "steps")}
