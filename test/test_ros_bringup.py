"""A short bring-up: its bag opens in both readers, holds every topic, agrees with summary.json,
and makes the same behaviours as the headless loop with the same seeds."""

import json

import pytest

from stns_ros import topics as T

EXPECTED = {T.CLOCK, T.GOAL, T.RANGES, T.REWARD, T.ODOM, T.CMD_VEL, T.STEPS, T.PLAN,
            T.SITUATION, T.SITUATIONS, T.RUN_CONFIG, T.PARAMETER_EVENTS}


def test_run_folder(plain_run):
    for name in ("summary.json", "learning_curve.png", "trajectory.png", "params.yaml",
                 "bag/metadata.yaml", "bag/bag.mcap", "learner_state"):
        assert (plain_run / name).exists(), name
    summary = json.loads((plain_run / "summary.json").read_text())
    assert summary["steps"] == 150
    assert summary["ticks_per_second"] > 0


def test_bag_opens_in_rosbags_and_mcap_ros2_with_counts_of_the_summary(plain_run):
    summary = json.loads((plain_run / "summary.json").read_text())
    from rosbags.highlevel import AnyReader

    with AnyReader([plain_run / "bag"]) as reader:
        counts = {}
        for c in reader.connections:
            counts[c.topic] = counts.get(c.topic, 0) + c.msgcount
        n_steps = 0
        for conn, _, raw in reader.messages(connections=[c for c in reader.connections
                                                         if c.topic == T.STEPS]):
            json.loads(reader.deserialize(raw, conn.msgtype).data)
            n_steps += 1
    assert EXPECTED <= set(counts), EXPECTED - set(counts)
    assert counts == summary["topic_counts"]
    assert n_steps == summary["steps"] == 150
    assert counts[T.GOAL] == counts[T.REWARD] == counts[T.CLOCK] == counts[T.ODOM] == summary["frames"]
    assert counts[T.CMD_VEL] == summary["frames"] - 1  # the last frame is not answered

    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    mcounts = {}
    with open(plain_run / "bag" / "bag.mcap", "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for _, channel, message, msg in reader.iter_decoded_messages():
            mcounts[channel.topic] = mcounts.get(channel.topic, 0) + 1
            if channel.topic == T.REWARD:
                assert msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec == message.log_time
    assert mcounts == {k: v for k, v in counts.items() if v}


def test_lockstep_ros_run_makes_the_headless_decisions(plain_run):
    """The headless tick loop of docs/INTERFACES.md with the run's seeds, side by side."""
    from stns_ros.driver import record_to_dict
    from stns_ros.summary import load_run

    from rover_sim import RoverWorld, WorldConfig
    from stns_core import StnsAgent, StnsConfig

    run = load_run(plain_run / "bag")
    cfg = run.config
    world = RoverWorld(WorldConfig.preset("exp1"), seed=cfg["world"]["seed"])
    agent = StnsAgent(StnsConfig.preset("exp1", seed=cfg["learner"]["seed"]), obs_dim=2,
                      n_behaviours=4)
    obs, _ = world.reset()
    reward, term = 0.0, False
    records = []
    ticks = 0
    while agent.behaviour_steps < 150:
        a = agent.step(obs, reward, term)
        records.extend(agent.pop_records())
        if a is None:
            obs, _ = world.reset()
            reward, term = 0.0, False
            continue
        obs, reward, term, _, _ = world.step(a)
        ticks += 1
    records.extend(agent.pop_records())
    world.close()
    headless = [json.loads(json.dumps(record_to_dict(r))) for r in records]
    ros = [{k: v for k, v in r.items() if k not in ("stamp_ns", "run_step")} for r in run.steps]
    assert [r["behaviour"] for r in ros] == [r["behaviour"] for r in headless]
    assert ros == headless
    summary = json.loads((plain_run / "summary.json").read_text())
    assert summary["ticks"] == ticks


def test_same_records_as_the_headless_experiment_runner(plain_run):
    """stns_experiments' own tick loop, trial set 0 of seed 3, against the ROS run."""
    runner = pytest.importorskip("stns_experiments.runner")
    from stns_ros.driver import record_to_dict
    from stns_ros.summary import load_run

    from rover_sim import RoverWorld, WorldConfig
    from stns_core import StnsAgent, StnsConfig

    seeds = runner.set_seeds(3, 1)[0]
    world = RoverWorld(WorldConfig.preset("exp1"), seed=seeds["world_seed"])
    agent = StnsAgent(StnsConfig.preset("exp1", seed=seeds["agent_seed"]), obs_dim=2,
                      n_behaviours=4)
    records, _ = runner.run_loop(world, agent, 150)
    world.close()
    run = load_run(plain_run / "bag")
    ros = [{k: v for k, v in r.items() if k not in ("stamp_ns", "run_step")} for r in run.steps]
    assert ros == [json.loads(json.dumps(record_to_dict(r))) for r in records]
