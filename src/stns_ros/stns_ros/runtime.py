"""Spinning the nodes: the executor is chosen once for every node of the suite.

rclpy's experimental EventsExecutor (C++) costs far less per callback than the Python
SingleThreadedExecutor, which matters in lockstep where every tick is a DDS round trip.
``STNS_EXECUTOR=single`` selects the classic executor.
"""

from __future__ import annotations

import os
import signal
import sys
import time
from collections.abc import Callable

import rclpy
from rclpy._rclpy_pybind11 import RCLError
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node

from stns_ros.errors import StnsRosError

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


def _rcl_reason(e: Exception) -> str:
    """rcl's message without its C source locations (", at /project/src/parse.c:841")."""
    text = " ".join(str(e).split())
    return text.split(", at /")[0].rstrip()


def run_node(name: str, make_node: Callable[[], Node], args: list[str] | None = None,
             done: Callable[[Node], bool] = lambda node: False,
             drain_seconds: float = 0.0,
             unfinished: Callable[[Node], str | None] = lambda node: None) -> None:
    """The ``main`` of every node: init, spin until Ctrl-C/SIGTERM or ``done``, clean up.

    ``drain_seconds`` > 0 (the recorder): Ctrl-C/SIGTERM only ask the node to stop; it spins
    on for that long first, so messages DDS has already delivered (and acknowledged to their
    publishers) still reach the callbacks before ``close``. rclpy's own handler would shut
    the context down at once and drop them.
    A configuration error (bad parameter, bad scenario) exits with its message, no traceback.
    A node stopped (Ctrl-C, SIGTERM) before ``done`` for which ``unfinished`` names what was
    left undone exits with 130 and that text: a run cut short must not look finished.
    """
    stop: list[int] = []
    try:
        if drain_seconds > 0.0:
            from rclpy.signals import SignalHandlerOptions

            rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
            for sig in (signal.SIGINT, signal.SIGTERM):
                signal.signal(sig, lambda signum, frame: stop.append(signum))
        else:
            rclpy.init(args=args)
    except RCLError as e:  # a --params-file rcl cannot parse, a bad --ros-args
        sys.exit(f"{name}: cannot start: {_rcl_reason(e)}")
    node = None
    cut_short = None
    try:
        node = make_node()
        spin(node, lambda: bool(stop) or done(node))
        if stop:
            end = time.monotonic() + drain_seconds
            spin(node, lambda: time.monotonic() >= end)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (StnsRosError, ParameterException) as e:
        sys.exit(f"{name}: {e}")
    finally:
        if node is not None:
            if not done(node):
                cut_short = unfinished(node)
            close = getattr(node, "close", None)
            if close is not None:
                close()
            node.destroy_node()
        rclpy.try_shutdown()
    if cut_short:
        sys.stderr.write(f"{name}: stopped before the end: {cut_short}\n")
        sys.exit(130)
