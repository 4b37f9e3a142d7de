"""What a run records about the code it ran on (summary.json's code_version), and pool's
refusal of runs whose libraries came from outside their workspace or changed while they ran."""

from __future__ import annotations

import json
import shutil
import subprocess

import pytest
from conftest import PARAMS
from conftest import synthetic_run as _write_run
from conftest import synthetic_set as _set
from stns_experiments.config import ExperimentError
from stns_experiments.run import code_version
from stns_experiments.runner import changed_files, library_hashes, outside_libraries, workspace_root

from stns_experiments import pool as P
from stns_experiments import run as R


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


def _package(root, files):
    pkg = root / "stns_core"
    for rel, text in files.items():
        (pkg / rel).parent.mkdir(parents=True, exist_ok=True)
        (pkg / rel).write_text(text)
    return pkg


def test_library_hashes_tell_which_files_were_edited_added_or_removed(tmp_path):
    pkg = _package(tmp_path, {"a.py": "A = 1\n", "sub/b.py": "B = 1\n", "c.py": "C = 1\n",
                              "notes.txt": "not code\n"})
    before = library_hashes({"stns_core": pkg})
    assert sorted(before) == ["stns_core/a.py", "stns_core/c.py", "stns_core/sub/b.py"]
    assert changed_files(before, library_hashes({"stns_core": pkg})) == []
    (pkg / "sub" / "b.py").write_text("B = 2\n")
    (pkg / "c.py").unlink()
    (pkg / "d.py").write_text("D = 1\n")
    (pkg / "notes.txt").write_text("edited\n")
    assert changed_files(before, library_hashes({"stns_core": pkg})) == [
        "stns_core/c.py", "stns_core/d.py", "stns_core/sub/b.py"]


def test_a_run_records_the_code_at_its_start_and_what_changed_before_its_end(tmp_path,
                                                                               monkeypatch):
    pkg = _package(tmp_path / "lib", {"categorical.py": "X = 1\n", "agent.py": "Y = 1\n"})
    monkeypatch.setattr(R, "library_packages", lambda: {"stns_core": pkg})
    calls = iter([{"commit": "aaa1111", "uncommitted": []},
                  {"commit": "bbb2222", "uncommitted": ["x"]}])
    monkeypatch.setattr(R, "code_version", lambda: next(calls))
    params = dict(PARAMS, seed=0, trial_sets=1)
    run = R.Run(params, tmp_path / "out", jobs=1, command="stns-experiment exp1",
                progress=False)
    (pkg / "categorical.py").write_text("X = 2\n")  # edited while the trial sets ran
    summ = run.finish({}, [])
    assert summ["code_version"] == {"commit": "aaa1111", "uncommitted": [],
                                    "changed_during_run": ["stns_core/categorical.py"]}
    on_disk = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert on_disk["code_version"]["changed_during_run"] == ["stns_core/categorical.py"]


def test_pool_refuses_a_run_whose_library_changed_while_it_ran_unless_asked(tmp_path,
                                                                            monkeypatch):
    monkeypatch.setattr(P, "library_changes", lambda commits, cwd=None: [])
    a = _write_run(tmp_path / "a", 0, [_set("set00", [4] * 4, [2] * 4)])
    b = _write_run(tmp_path / "b", 1, [_set("set00", [4] * 4, [2] * 4)])
    summ = json.loads((b / "summary.json").read_text())
    summ["code_version"]["changed_during_run"] = ["stns_experiments/pool.py"]  # report only
    (b / "summary.json").write_text(json.dumps(summ))
    assert "CHANGED DURING" not in P.pool([a, b])["pooled_from"]["code"]
    summ["code_version"]["changed_during_run"] = ["stns_core/categorical.py",
                                                  "stns_experiments/pool.py"]
    (b / "summary.json").write_text(json.dumps(summ))
    with pytest.raises(ExperimentError, match=r"changed while a run was going \(.*b: "
                                              r"stns_core/categorical\.py\)"):
        P.pool([a, b])
    s = P.pool([a, b], any_code=True)
    assert s["pooled_from"]["code"].endswith(
        f"LIBRARY CHANGED DURING A RUN: {b}: stns_core/categorical.py")
