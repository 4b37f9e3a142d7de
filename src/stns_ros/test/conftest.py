import os
import random

import pytest

# In-process rclpy tests get a domain of their own (colcon runs packages in parallel).
_theirs = os.environ.get("ROS_DOMAIN_ID")
os.environ["ROS_DOMAIN_ID"] = str(random.SystemRandom().choice(
    [d for d in range(1, 101) if str(d) != _theirs]))


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
