"""Stopping a run (Ctrl-C or SIGTERM) keeps the finished trial sets and writes summary.json."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import pytest

pytest.importorskip("rover_sim")
pytest.importorskip("stns_core")


@pytest.mark.parametrize("jobs", ["1", "2"])
def test_sigterm_keeps_finished_trial_sets(tmp_path, jobs):
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "stns_experiments.cli", "exp1", "--trial-sets", "6",
           "--steps", "250", "--jobs", jobs, "--out", str(out), "--no-figures",
           "--set", "random_steps=0"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            env=dict(os.environ, MPLBACKEND="Agg"))
    deadline = time.monotonic() + 90
    while time.monotonic() < deadline and not list((out / "sets").glob("set*.json")):
        time.sleep(0.2)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err.decode()[-2000:]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["interrupted"] is True
    assert 1 <= summary["trial_sets_finished"] < 6
    assert len(list((out / "records").glob("set*.csv.gz"))) >= summary["trial_sets_finished"]


def test_a_set_finished_as_the_stop_came_is_kept_but_not_an_older_file(tmp_path):
    """A worker writes its result file last; a stop can fall before the parent hears of it.
    Such a file, written since the run began, is that set's result and is kept; a file left
    from an earlier run in the same folder is not taken for this run's."""
    from stns_experiments.run import Run, _results_on_disk  # after the importorskips

    run = Run({"experiment": "exp1"}, tmp_path, jobs=1, command="test", progress=False)
    (tmp_path / "sets").mkdir()
    tasks = [{"fn": "random", "key": k, "out": str(tmp_path)} for k in ("a", "b", "c", "d")]
    for k in ("b", "c", "d"):
        (tmp_path / "sets" / f"{k}.json").write_text(json.dumps({"key": k, "steps": 7}))
    old = run.started - 3600
    os.utime(tmp_path / "sets" / "c.json", (old, old))
    found = run._finished_during_stop(tasks, res={"d": {"key": "d"}}, err={})
    assert found == {"b": {"key": "b", "steps": 7}}
    assert set(_results_on_disk(tasks)) == {"b", "c", "d"}  # --resume takes every file
