"""System tests: the real nodes as separate processes, on a ROS domain of this session's own."""

from __future__ import annotations

import os
import random
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

REPO = Path(__file__).resolve().parents[1]
# One domain per test session (colcon runs packages' tests in parallel; others use 10-99).
_theirs = os.environ.get("ROS_DOMAIN_ID")
DOMAIN = random.choice([d for d in range(1, 101) if str(d) != _theirs])
os.environ["ROS_DOMAIN_ID"] = str(DOMAIN)


def command(name: str, module: str) -> list[str]:
    """An entry point by name (on PATH after `source env.sh`), else its module."""
    exe = shutil.which(name)
    return [exe] if exe else [sys.executable, "-m", module]


def run_config(tmp: Path, **sections) -> Path:
    """A run config in tmp: a short exp1 lockstep run, sections replace the defaults."""
    cfg = {
        "run": {"name": "test", "seed": 3, "steps": 150, "mode": "lockstep"},
        "world": {"preset": "exp1"},
        "learner": {"preset": "exp1", "save_state": True},
        "faults": None,
        "recording": {"enabled": True, "chunk_size": 16384},
        "nodes": str(REPO / "config" / "nodes.yaml"),
    }
    cfg.update(sections)
    path = tmp / "run.yaml"
    path.write_text(yaml.safe_dump(cfg))
    return path


def bringup(config: Path, out: Path, *extra: str, timeout: float = 240.0
            ) -> subprocess.CompletedProcess:
    env = dict(os.environ, ROS_DOMAIN_ID=str(DOMAIN))
    return subprocess.run(
        command("stns_bringup", "stns_ros.bringup") + ["--config", str(config), "--out", str(out),
                                                       "--quiet", *extra],
        capture_output=True, text=True, timeout=timeout, env=env)


@pytest.fixture(scope="session")
def plain_run(tmp_path_factory) -> Path:
    """A recorded lockstep run without faults (150 behaviour steps)."""
    tmp = tmp_path_factory.mktemp("plain")
    out = tmp / "run"
    res = bringup(run_config(tmp), out)
    assert res.returncode == 0, res.stdout + res.stderr
    return out


@pytest.fixture(scope="session")
def fault_run(tmp_path_factory) -> Path:
    """A recorded run with a 90-degree goal-sensor rotation injected at behaviour step 60."""
    tmp = tmp_path_factory.mktemp("fault")
    out = tmp / "run"
    cfg = run_config(tmp, faults={"name": "rot90", "faults": [
        {"at_step": 60, "set": {"goal_sensor_rotation_deg": 90.0}}]})
    res = bringup(cfg, out)
    assert res.returncode == 0, res.stdout + res.stderr
    return out
