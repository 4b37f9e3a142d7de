"""A node started with arguments rcl cannot parse exits with one line naming the problem."""

import subprocess
import sys

import pytest


@pytest.mark.parametrize("module", ["sim_node", "agent_node", "fault_injector_node"])
def test_a_params_file_rcl_cannot_parse_is_named_without_a_traceback(tmp_path, module):
    bad = tmp_path / "nodes.yaml"
    bad.write_text("rover_sim: [\n")
    r = subprocess.run([sys.executable, "-m", f"stns_ros.{module}", "--ros-args",
                        "--params-file", str(bad)], capture_output=True, text=True, timeout=60)
    assert r.returncode == 1
    assert "Traceback" not in r.stderr
    (line,) = [x for x in r.stderr.splitlines() if ": cannot start: " in x]
    assert f"Couldn't parse params file: '--params-file {bad}'" in line
    assert not line.endswith(" ") and "/project/src" not in line
