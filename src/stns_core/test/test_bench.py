"""The benchmark command runs and builds the 20 situations it claims to time."""

import pytest

from stns_core import bench


def test_bench_measure_small():
    res = bench.measure("exp1", 2, ticks=50, steps=20)
    assert res["situations"] == bench.N_SITUATIONS
    assert res["tick_us"] > 0 and res["step_ms_mean"] > 0


def test_bench_learn_cli(capsys):
    assert bench.main(["--learn", "--steps", "300", "--seeds", "1",
                       "--set", "random_stop=reward"]) == 0
    out = capsys.readouterr().out
    assert "seed 0:" in out and "last block mean" in out


@pytest.mark.parametrize("argv, message", [
    (["--steps", "0"], "--steps must be >= 1, got 0"),
    (["--seeds", "0"], "--seeds must be >= 1, got 0"),
    (["--lookahead", "-4"], "--lookahead must be >= 0, got -4"),
    (["--set", "gamma"], "--set takes KEY=VALUE, got 'gamma'"),
    (["--set", "gamma=x"], "--set gamma: 'x' is not a number"),
    (["--set", "n_init_t=1.5"], "--set n_init_t: '1.5' is not an integer"),
    (["--set", "gamma=2"], "gamma must be in [0, 1), got 2.0"),
    (["--set", "nope=3"], "unknown StnsConfig keys: ['nope']"),
    # the options set these two: a --set of them died with a TypeError traceback
    (["--set", "seed=3"], "--set seed: the seeds are 0..N-1 of --seeds; give --seeds"),
    (["--set", "target_lookahead_ticks=2"],
     "--set target_lookahead_ticks: give --lookahead 2 instead"),
    # anything but a yes or no word was read as False
    (["--set", "iprl_memo=ture"], "--set iprl_memo: 'ture' is not true or false"),
])
def test_bench_learn_cli_names_a_bad_value(argv, message, capsys):
    with pytest.raises(SystemExit) as e:
        bench.main(["--learn", *argv])
    assert e.value.code == 2
    assert message in capsys.readouterr().err
