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
