"""Save / load: round trip, identical continuation, refusal of bad files, atomic writes."""

import copy
import json
import os

import numpy as np
import pytest
from stns_core.toyworld import KinematicRover

from stns_core import StnsAgent, StnsConfig, StnsStateError


def drive(agent, world, state, ticks, until_steps=None):
    """Run ``ticks`` control ticks (or until ``until_steps`` records); actions and loop state."""
    obs, reward, terminated = state
    actions = []
    while len(actions) < ticks or (until_steps and agent.behaviour_steps < until_steps):
        if until_steps and agent.behaviour_steps >= until_steps:
            break
        a = agent.step(obs, reward, terminated)
        actions.append(a)
        if a is None:
            obs, reward, terminated = world.reset(), 0.0, False
        else:
            obs, reward, terminated = world.step(a)
    return actions, (obs, reward, terminated)


@pytest.mark.parametrize("planner,extra", [
    ("iprl", {}), ("pia", {}), ("iprl", {"nn_window": 100}),
    ("iprl", {"contradiction_radius": 0.3, "contradiction_window": 10})])
def test_loaded_agent_continues_with_identical_decisions(tmp_path, planner, extra):
    agent = StnsAgent(StnsConfig.preset("exp1", seed=11, planner=planner, **extra), 2, 4)
    world = KinematicRover(seed=11)
    _, state = drive(agent, world, (world.reset(), 0.0, False), 0, until_steps=700)
    assert agent.learner.order, "expected situations after 12000 ticks"
    if extra.get("contradiction_window"):  # a change point saved and restored
        agent.learner._change_at = agent.learner.hist.total - 50
    path = tmp_path / "learner.npz"
    agent.save(path)
    clone = StnsAgent.load(path)
    assert clone.explain() == agent.explain()
    world2 = copy.deepcopy(world)
    a1, _ = drive(agent, world, state, 6000)
    a2, _ = drive(clone, world2, state, 6000)
    assert a1 == a2
    assert [r.to_dict() for r in agent.pop_records()] == [r.to_dict() for r in clone.pop_records()]
    assert clone.config == agent.config and clone.behaviour_steps == agent.behaviour_steps
    assert clone.learner._change_at == agent.learner._change_at


def rewriter(good, tmp_path):
    """A writer of copies of the learner file ``good``, each edited by ``edit(meta, arrays)``."""
    def rewrite(name, edit):
        with np.load(good) as data:
            arrays = {k: data[k].copy() for k in data.files}
        meta = json.loads(str(arrays["meta"]))
        edit(meta, arrays)
        arrays["meta"] = np.array(json.dumps(meta))
        path = tmp_path / name
        np.savez(path, **arrays)
        return path

    return rewrite


def test_corrupt_or_incompatible_files_are_refused(tmp_path):
    agent = StnsAgent(StnsConfig(), 2, 4)
    agent.step(np.zeros(2) + 30.0, 0.0, False)
    good = tmp_path / "good.npz"
    agent.save(good)
    garbage = tmp_path / "garbage.npz"
    garbage.write_bytes(b"not a zip file at all")
    with pytest.raises(StnsStateError, match="garbage.npz: not a readable learner file") as e:
        StnsAgent.load(garbage)
    # random bytes are not offered to the pickle loader: the message says what the file is
    assert "not an .npz archive: it starts with b'not '" in str(e.value)
    assert "pickle" not in str(e.value)
    truncated = tmp_path / "truncated.npz"
    truncated.write_bytes(good.read_bytes()[:200])
    with pytest.raises(StnsStateError, match="truncated.npz"):
        StnsAgent.load(truncated)
    with pytest.raises(StnsStateError, match="missing.npz: no such file"):
        StnsAgent.load(tmp_path / "missing.npz")

    rewrite = rewriter(good, tmp_path)

    def future(meta, arrays):
        meta["version"] = 99

    with pytest.raises(StnsStateError, match="format version 99 unsupported"):
        StnsAgent.load(rewrite("future.npz", future))

    def other(meta, arrays):
        meta["format"] = "something.else"

    with pytest.raises(StnsStateError, match="format 'something.else'"):
        StnsAgent.load(rewrite("other.npz", other))

    def bad_config(meta, arrays):
        meta["config"]["gamma"] = 3.0

    with pytest.raises(StnsStateError, match="bad_config.npz: .*gamma must be in"):
        StnsAgent.load(rewrite("bad_config.npz", bad_config))

    def wrong_dim(meta, arrays):
        meta["obs_dim"] = 8

    with pytest.raises(StnsStateError, match="wrong_dim.npz: history shape"):
        StnsAgent.load(rewrite("wrong_dim.npz", wrong_dim))

    def future_change(meta, arrays):
        meta["change_at"] = 10**6

    with pytest.raises(StnsStateError, match="change_at 1000000 outside"):
        StnsAgent.load(rewrite("future_change.npz", future_change))


def _learned_state(tmp_path):
    """A writer of edited copies of a saved learner that has situations."""
    agent = StnsAgent(StnsConfig.preset("exp1", seed=11), 2, 4)
    world = KinematicRover(seed=11)
    drive(agent, world, (world.reset(), 0.0, False), 0, until_steps=700)
    assert agent.learner.order, "expected situations after 700 steps"
    good = tmp_path / "good.npz"
    agent.save(good)
    return rewriter(good, tmp_path)


@pytest.mark.parametrize("name,edit,message", [
    ("nan_mean", lambda m, a: a["sit0_mean"].__setitem__(0, np.nan),
     r"situation \d+: mean holds a non-finite value \(nan\)"),
    ("inf_cov", lambda m, a: a["sit0_cov"].__setitem__((1, 1), np.inf),
     r"situation \d+: covariance holds a non-finite value \(inf\)"),
    ("nan_input", lambda m, a: a["hist_x"].__setitem__((3, 1), np.nan),
     r"history x holds a non-finite value \(nan\) in slot 3"),
    ("inf_reward", lambda m, a: a["hist_reward"].__setitem__(5, -np.inf),
     r"history reward holds a non-finite value \(-inf\) in slot 5"),
    ("bad_behaviour_record", lambda m, a: a["hist_b"].__setitem__(2, 9),
     r"history behaviour 9 in slot 2 is not -1 \(arrival\) or 0..3"),
    ("bad_label", lambda m, a: a["hist_s"].__setitem__(4, 10**6),
     r"history situation label 1000000 in slot 4 is not 0..\d+"),
    ("nan_boundary", lambda m, a: m["situations"][0].__setitem__("boundary", float("nan")),
     r"situation \d+: boundary nan is not a finite number >= 0"),
    ("inf_utility", lambda m, a: m["situations"][0].__setitem__("utility", float("inf")),
     r"situation \d+: utility inf is not finite"),
    ("bad_behaviour", lambda m, a: m["situations"][0].__setitem__("behaviour", 17),
     r"situation \d+: behaviour 17 is not 0..3"),
    ("bad_current", lambda m, a: m.__setitem__("current", 12345),
     r"current situation 12345 is not 0..\d+"),
    ("nan_plan_utility", lambda m, a: m.__setitem__("plan_utility", float("nan")),
     r"plan_utility nan is not finite"),
    ("bad_plan", lambda m, a: m.__setitem__("plan", [[7, 0]]),
     r"plan step \[7, 0\]: behaviour 7 is not 0..3"),
])
def test_a_state_with_impossible_values_is_refused(tmp_path, name, edit, message):
    # a hand-edited or bit-flipped file that still unzips must not load into a learner that
    # classifies with NaN shapes or plans an unknown behaviour later
    rewrite = _learned_state(tmp_path)
    StnsAgent.load(rewrite("unchanged.npz", lambda m, a: None))  # the writer itself is sound
    with pytest.raises(StnsStateError, match=f"{name}.npz: {message}"):
        StnsAgent.load(rewrite(f"{name}.npz", edit))


def test_failed_save_keeps_the_previous_file(tmp_path, monkeypatch):
    agent = StnsAgent(StnsConfig(), 2, 4)
    path = tmp_path / "learner.npz"
    agent.save(path)
    before = path.read_bytes()
    agent.step(np.zeros(2) + 30.0, 0.0, False)

    def boom(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(np, "savez_compressed", boom)
    with pytest.raises(OSError, match="disk full"):
        agent.save(path)
    assert path.read_bytes() == before
    assert os.listdir(tmp_path) == ["learner.npz"]  # no temporary file left behind
