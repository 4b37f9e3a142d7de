"""stns_replay on damaged bags and on a bag's .mcap file (in process; no republishing)."""

import sys

import pytest
from stns_ros.bag import check_complete, read_messages, read_metadata
from stns_ros.replay import main
from test_bag import _truncated, _write


def replay(capsys, *args) -> tuple[int, str, str]:
    """Exit code, stdout and stderr of `stns_replay ARGS`."""
    try:
        main([str(a) for a in args])
        rc = 0
    except SystemExit as e:
        rc = e.code if isinstance(e.code, int) else 1
        if isinstance(e.code, str):
            print(e.code, file=sys.stderr)  # sys.exit("stns_replay: error: ...")
    out, err = capsys.readouterr()
    return rc, out, err


def _files(folder) -> dict:
    return {p.name: p.read_bytes() for p in folder.iterdir()}


def test_verify_fails_on_a_truncated_bag_with_the_counts(tmp_path, capsys):
    bag = tmp_path / "run" / "bag"
    _truncated(bag)
    n = len(list(read_messages(bag)))
    before = _files(bag)
    rc, out, _ = replay(capsys, bag, "--verify")
    assert rc == 1 and f"verify: FAILED: bag '{bag}' is truncated" in out, out
    assert f"{n} of 505 messages readable" in out
    assert _files(bag) == before  # verifying changes nothing


def test_recover_rewrites_a_truncated_bag_and_keeps_the_originals(tmp_path, capsys):
    bag = tmp_path / "run" / "bag"
    _truncated(bag)
    n = len(list(read_messages(bag)))
    before = _files(bag)
    rc, out, err = replay(capsys, bag, "--recover", "--no-publish")
    assert rc == 0, out + err
    assert f"recovered: {n} messages of 505 recorded kept in {bag}" in out
    assert "bag.mcap.orig" in out and "metadata.yaml.orig" in out and "warning" not in err
    kept = {"bag.mcap.orig": before["bag.mcap"], "metadata.yaml.orig": before["metadata.yaml"]}
    assert {k: v for k, v in _files(bag).items() if k in kept} == kept
    assert check_complete(bag) is None and read_metadata(bag)["message_count"] == n
    rc, out, _ = replay(capsys, bag, "--recover", "--no-publish")  # again: nothing to do
    assert rc == 0 and f"recover: {bag} is complete ({n} messages), left alone" in out
    assert {k: v for k, v in _files(bag).items() if k in kept} == kept


def test_recover_leaves_a_complete_bag_alone(tmp_path, capsys):
    bag = tmp_path / "run" / "bag"
    _write(bag)
    before = _files(bag)
    rc, out, err = replay(capsys, bag, "--recover", "--no-publish")
    assert rc == 0 and f"recover: {bag} is complete (505 messages), left alone" in out, out + err
    assert _files(bag) == before


@pytest.mark.parametrize("closed", [True, False])
def test_the_mcap_file_of_a_bag_writes_beside_the_bag_not_inside(tmp_path, capsys, closed):
    bag = tmp_path / "run" / "bag"
    _write(bag, close=closed)  # not closed: a killed recorder, no metadata.yaml
    before = _files(bag)
    rc, out, err = replay(capsys, bag / "bag.mcap", "--no-publish")
    assert rc == 0, out + err
    assert _files(bag) == before  # nothing written into the bag directory
    assert (tmp_path / "run" / "replay" / "summary.json").exists()
    assert ("cut short" in err) != closed  # the unclosed bag is named as such
    rc, _, err = replay(capsys, bag / "bag.mcap", "--no-publish", "--out", bag / "replay")
    assert rc != 0 and "is inside the bag directory" in err
    assert _files(bag) == before


def test_bags_side_by_side_keep_their_own_replay_output(tmp_path, capsys):
    for name in ("a", "b"):
        _write(tmp_path / "bags" / name)
        rc, out, err = replay(capsys, tmp_path / "bags" / name, "--no-publish")
        assert rc == 0, out + err
    assert sorted(p.name for p in (tmp_path / "bags").iterdir()) == ["a", "a.replay", "b",
                                                                     "b.replay"]
    assert all((tmp_path / "bags" / f"{n}.replay" / "summary.json").exists() for n in "ab")


def test_a_damaged_metadata_yaml_fails_verify_but_not_a_replay(tmp_path, capsys):
    bag = tmp_path / "run" / "bag"
    _write(bag)
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: {message_count: x}\n")
    rc, out, _ = replay(capsys, bag, "--verify")
    assert rc == 1 and "verify: FAILED: " in out and "metadata.yaml' does not list" in out
    rc, out, err = replay(capsys, bag, "--no-publish")
    assert rc == 0 and "warning:" in err and "metadata.yaml' does not list" in err, out + err


@pytest.mark.parametrize("sig", ["SIGTERM", "SIGINT"])
def test_sigterm_stops_a_republish_as_ctrl_c_does(tmp_path, sig):
    """`kill PID` (or `timeout`) of a replay: it stops within its pacing sleep, says how many
    messages went out, no traceback (rclpy's own SIGTERM handler only invalidated the context:
    the replay slept on, then its next publish died with an RCLError traceback)."""
    import os
    import select
    import signal
    import subprocess
    import time

    bag = tmp_path / "run" / "bag"
    _write(bag)  # 505 messages over 500 ns of log time: at --rate 1e-9, over 500 s
    p = subprocess.Popen([sys.executable, "-m", "stns_ros.replay", str(bag), "--rate", "1e-9"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         env={**os.environ, "MPLBACKEND": "Agg"})
    try:
        end, err = time.monotonic() + 60, ""
        while "republishing" not in err and time.monotonic() < end and p.poll() is None:
            if select.select([p.stderr], [], [], 1.0)[0]:
                err += p.stderr.readline()
        assert "republishing 505 messages" in err, err
        time.sleep(0.5)  # into the first pacing sleep
        p.send_signal(getattr(signal, sig))
        out, rest = p.communicate(timeout=10)
    finally:
        if p.poll() is None:
            p.kill()
            p.communicate()
    err += rest
    assert p.returncode == 0 and "Traceback" not in err, err
    import re
    sent = re.search(r"republished (\d+) messages", out)
    assert sent and int(sent.group(1)) < 10, out  # stopped at once, not after the 500 s


def _recorded_config(state_in="") -> dict:
    """A run config as the simulator records it on /stns/run_config (the parts verify reads)."""
    return {"run": {"mode": "lockstep"}, "world": {"preset": "exp1", "overrides": {}},
            "learner": {"preset": "exp1", "overrides": {}, "seed": 0, "state_in": state_in}}


def test_verify_names_a_saved_learner_that_cannot_be_read_now(tmp_path):
    # the run's state_in was damaged after the run: a clear failure, not a traceback
    from stns_ros.replay import VerifyError, verify
    from stns_ros.summary import RunData

    state = tmp_path / "learner.npz"
    state.write_bytes(b"PK\x03\x04 cut short")
    with pytest.raises(VerifyError, match=f"the run started from the saved learner '{state}', "
                       "which cannot be read now: .*not a readable learner file"):
        verify(RunData(config=_recorded_config(str(state))))


@pytest.mark.parametrize("edit,message", [
    (lambda c: c.pop("learner"), r"the recorded run config has no 'learner'"),
    (lambda c: c["world"].update(preset="exp9"), r"the recorded run config cannot rebuild the "
     r"agent: .*exp9"),
    (lambda c: c["learner"].update(overrides=[1]), r"the recorded run config cannot rebuild "
     r"the agent"),
])
def test_verify_names_a_recorded_run_config_it_cannot_use(edit, message):
    from stns_ros.replay import VerifyError, verify
    from stns_ros.summary import RunData

    cfg = _recorded_config()
    edit(cfg)
    with pytest.raises(VerifyError, match=message):
        verify(RunData(config=cfg))
