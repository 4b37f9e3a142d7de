import pytest

from rover_sim import RoverWorld, WorldConfig


@pytest.fixture
def make_world():
    worlds = []

    def make(task="exp1", seed=0, **overrides):
        world = RoverWorld(WorldConfig.preset(task, **overrides), seed=seed)
        worlds.append(world)
        return world

    yield make
    for world in worlds:
        world.close()
