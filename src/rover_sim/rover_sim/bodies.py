"""The pybullet bodies: ground, walls, box obstacles and the two-wheeled rover.

pybullet works in metres (1 u = `UNIT_M` m). The rover: a 1.0 x 0.75 m (16 x 12 u) body
on two velocity-controlled wheels (spheres, radius `WHEEL_RADIUS_M`) on the centre axle,
`TRACK_M` apart, and two frictionless caster spheres fore and aft. Collision between
the rover and every wall and obstacle is switched off pair by pair
(``setCollisionFilterPair``): walls never exert a contact force on the rover, so rotation
in place is never stopped by a wall; collision *events* are computed geometrically by the
world from the base pose. Range rays are cast at `RAY_HEIGHT_M`, above the rover's top,
so they only hit walls and obstacles.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from rover_sim.config import UNIT_M, WorldConfig

WHEEL_RADIUS_M = 0.1
TRACK_M = 0.6
WALL_HEIGHT_M = 0.6
WALL_THICKNESS_U = 4.0
RAY_HEIGHT_M = 0.4
MOTOR_FORCE = 200.0
WHEEL_FRICTION = 5.0
LEFT_WHEEL = 0
RIGHT_WHEEL = 1


@dataclass(frozen=True)
class SceneIds:
    """pybullet body ids of one scene."""

    ground: int
    walls: tuple[int, ...]
    obstacles: tuple[int, ...]
    rover: int


def quat_from_yaw(yaw: float) -> tuple[float, float, float, float]:
    """Quaternion (x, y, z, w) of a rotation about z."""
    return (0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0))


def yaw_from_quat(q: tuple[float, float, float, float]) -> float:
    """Heading (rotation about z) of a quaternion (x, y, z, w)."""
    x, y, z, w = q
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def _static_box(
    client: Any, centre_u: tuple[float, float], half_u: tuple[float, float], height_m: float
) -> int:
    half = [half_u[0] * UNIT_M, half_u[1] * UNIT_M, height_m / 2.0]
    shape = client.createCollisionShape(client.GEOM_BOX, halfExtents=half)
    body = client.createMultiBody(
        baseMass=0.0,
        baseCollisionShapeIndex=shape,
        basePosition=[centre_u[0] * UNIT_M, centre_u[1] * UNIT_M, height_m / 2.0],
    )
    return body


def build_scene(client: Any, config: WorldConfig) -> SceneIds:
    """Create ground, walls, obstacles and rover in an empty pybullet client."""
    client.setGravity(0.0, 0.0, -9.81)
    client.setTimeStep(config.tick_seconds / config.physics_substeps)
    client.setPhysicsEngineParameter(
        numSolverIterations=config.solver_iterations, deterministicOverlappingPairs=1
    )

    plane = client.createCollisionShape(client.GEOM_PLANE)
    ground = client.createMultiBody(baseMass=0.0, baseCollisionShapeIndex=plane)
    client.changeDynamics(ground, -1, lateralFriction=1.0)

    size = config.room_size
    t = WALL_THICKNESS_U
    walls = (
        _static_box(client, (-t / 2, size / 2), (t / 2, size / 2 + t), WALL_HEIGHT_M),
        _static_box(client, (size + t / 2, size / 2), (t / 2, size / 2 + t), WALL_HEIGHT_M),
        _static_box(client, (size / 2, -t / 2), (size / 2 + t, t / 2), WALL_HEIGHT_M),
        _static_box(client, (size / 2, size + t / 2), (size / 2 + t, t / 2), WALL_HEIGHT_M),
    )
    obstacles = tuple(
        _static_box(client, (b.cx, b.cy), (b.sx / 2, b.sy / 2), WALL_HEIGHT_M)
        for b in config.obstacles
    )
    rover = _build_rover(client, config)
    for body in walls + obstacles:
        for link in (-1, LEFT_WHEEL, RIGHT_WHEEL):
            client.setCollisionFilterPair(rover, body, link, -1, enableCollision=0)
    return SceneIds(ground, walls, obstacles, rover)


def _build_rover(client: Any, config: WorldConfig) -> int:
    r = WHEEL_RADIUS_M
    half_l = config.rover_length * UNIT_M / 2.0
    half_w = config.rover_width * UNIT_M / 2.0
    caster_x = half_l - r
    # base frame origin on the wheel axle, r above ground
    base_shape = client.createCollisionShapeArray(
        shapeTypes=[client.GEOM_BOX, client.GEOM_SPHERE, client.GEOM_SPHERE],
        radii=[0.0, r, r],
        halfExtents=[[half_l, half_w, 0.05], [0.0] * 3, [0.0] * 3],
        collisionFramePositions=[[0.0, 0.0, r + 0.06], [caster_x, 0.0, 0.0], [-caster_x, 0.0, 0.0]],
    )
    wheel_shape = client.createCollisionShape(client.GEOM_SPHERE, radius=r)
    rover = client.createMultiBody(
        baseMass=4.0,
        baseCollisionShapeIndex=base_shape,
        basePosition=[0.0, 0.0, r],
        linkMasses=[0.5, 0.5],
        linkCollisionShapeIndices=[wheel_shape, wheel_shape],
        linkVisualShapeIndices=[-1, -1],
        linkPositions=[[0.0, TRACK_M / 2.0, 0.0], [0.0, -TRACK_M / 2.0, 0.0]],
        linkOrientations=[[0, 0, 0, 1], [0, 0, 0, 1]],
        linkInertialFramePositions=[[0, 0, 0], [0, 0, 0]],
        linkInertialFrameOrientations=[[0, 0, 0, 1], [0, 0, 0, 1]],
        linkParentIndices=[0, 0],
        linkJointTypes=[client.JOINT_REVOLUTE, client.JOINT_REVOLUTE],
        linkJointAxis=[[0, 1, 0], [0, 1, 0]],
    )
    # casters (part of the base) slide freely; the wheels grip
    client.changeDynamics(rover, -1, lateralFriction=0.0, rollingFriction=0.0, spinningFriction=0.0)
    for link in (LEFT_WHEEL, RIGHT_WHEEL):
        client.changeDynamics(
            rover,
            link,
            lateralFriction=WHEEL_FRICTION,
            rollingFriction=0.0,
            spinningFriction=0.0,
            frictionAnchor=1,
        )
        client.setJointMotorControl2(
            rover, link, client.VELOCITY_CONTROL, targetVelocity=0.0, force=0.0
        )
    return rover
