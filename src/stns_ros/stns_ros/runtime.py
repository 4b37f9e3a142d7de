"""Spinning the nodes: the executor is chosen once for every node of the suite.

rclpy's experimental EventsExecutor (C++) costs far less per callback than the Python
SingleThreadedExecutor, which matters in lockstep where every tick is a DDS round trip.
``STNS_EXECUTOR=single`` selects the classic executor.
"""

from __future__ import annotations

import os
from collections.abc import Callable

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

EXECUTORS = ("events", "single")


def make_executor():
    kind = os.environ.get("STNS_EXECUTOR", "events")
    if kind == "events":
        from rclpy.experimental import EventsExecutor

        return EventsExecutor()
    if kind == "single":
        return SingleThreadedExecutor()
    raise ValueError(f"STNS_EXECUTOR must be one of {', '.join(EXECUTORS)}, got {kind!r}")


def spin(node: Node, done: Callable[[], bool] = lambda: False) -> None:
    """Spin `node` until the context shuts down (Ctrl-C, SIGTERM) or `done()` is true."""
    executor = make_executor()
    executor.add_node(node)
    try:
        while rclpy.ok() and not done():
            executor.spin_once(timeout_sec=0.2)
    finally:
        executor.remove_node(node)
