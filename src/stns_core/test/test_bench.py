"""The benchmark command runs and builds the 20 situations it claims to time."""

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
