import os
import random

import pytest

# In-process rclpy tests get a domain of their own (colcon runs packages in parallel).
os.environ["ROS_DOMAIN_ID"] = str(random.Random(os.getpid()).randint(150, 200) % 102)


@pytest.fixture
def rclpy_context():
    import rclpy

    rclpy.init()
    try:
        yield
    finally:
        rclpy.try_shutdown()


@pytest.fixture
def repo_config():
    from pathlib import Path

    here = Path(__file__).resolve()
    for parent in here.parents:
        if (parent / "config" / "default.yaml").exists():
            return parent / "config"
    pytest.skip("the workspace config/ folder is not reachable from here")
