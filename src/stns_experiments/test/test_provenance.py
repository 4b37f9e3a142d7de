"""What a run records about the code it ran on (summary.json's code_version), and pool's
refusal of runs whose libraries came from outside their workspace."""

from __future__ import annotations

import json
import shutil
import subprocess

import pytest
from conftest import synthetic_run as _write_run
from conftest import synthetic_set as _set
from stns_experiments.config import ExperimentError
from stns_experiments.run import code_version
from stns_experiments.runner import outside_libraries, workspace_root

from stns_experiments import pool as P


def _git(cwd, *args):
    out = subprocess.run(["git", "-c", "user.name=t", "-c", "user.email=t@t", *args],
                         cwd=cwd, capture_output=True, text=True, check=True)
    return out.stdout.strip()


def test_a_library_from_another_checkout_is_named_with_its_own_commit(tmp_path):
    if shutil.which("git") is None:
        pytest.skip("git is not installed")
    other = tmp_path / "other"
    core = other / "src" / "stns_core" / "stns_core"
    core.mkdir(parents=True)
    (core / "__init__.py").write_text("A = 1\n")
    _git(other, "init", "-q")
    _git(other, "add", ".")
    _git(other, "commit", "-qm", "one")
    (core / "__init__.py").write_text("A = 2\n")  # the option being tried, uncommitted
    ws = tmp_path / "ws"
    sim = ws / "src" / "rover_sim" / "rover_sim"
    sim.mkdir(parents=True)
    loose = tmp_path / "site" / "stns_experiments"
    loose.mkdir(parents=True)
    out = outside_libraries(ws, {"stns_core": core, "rover_sim": sim,
                                 "stns_experiments": loose})
    assert set(out) == {"stns_core", "stns_experiments"}  # rover_sim is the workspace's
    assert out["stns_core"] == {"path": str(core.resolve()),
                                "commit": _git(other, "rev-parse", "--short", "HEAD"),
                                "uncommitted": ["src/stns_core/stns_core/__init__.py"]}
    assert out["stns_experiments"] == {"path": str(loose.resolve())}  # no git to ask


def test_this_workspace_runs_its_own_libraries():
    if workspace_root() is None or shutil.which("git") is None:
        pytest.skip("not running from a git workspace")
    cv = code_version()
    assert cv["commit"] and "outside" not in cv


def test_pool_refuses_runs_on_libraries_from_outside_unless_asked(tmp_path, monkeypatch):
    monkeypatch.setattr(P, "library_changes", lambda commits, cwd=None: [])
    a = _write_run(tmp_path / "a", 0, [_set("set00", [4] * 4, [2] * 4)])
    b = _write_run(tmp_path / "b", 1, [_set("set00", [4] * 4, [2] * 4)])
    summ = json.loads((b / "summary.json").read_text())
    summ["code_version"]["outside"] = {"stns_core": {
        "path": "/tmp/wt/src/stns_core/stns_core", "commit": "59bc05c",
        "uncommitted": ["src/stns_core/stns_core/categorical.py"]}}
    (b / "summary.json").write_text(json.dumps(summ))
    assert "OUTSIDE" not in P.pool([a])["pooled_from"]["code"]
    with pytest.raises(ExperimentError, match=r"outside its workspace .*stns_core from "
                                              r"/tmp/wt/src/stns_core/stns_core \(commit "
                                              r"59bc05c, uncommitted .*categorical\.py\)"):
        P.pool([a, b])
    s = P.pool([a, b], any_code=True)
    assert "LIBRARIES FROM OUTSIDE THE WORKSPACE" in s["pooled_from"]["code"]
    assert str(b) in s["pooled_from"]["code"] and str(a) not in s["pooled_from"]["code"]
