"""Recording a run into a rosbag2 directory (MCAP) from inside a node's process.

`TopicRecorder` owns a `BagWriter`. The owning node writes the messages it publishes or
receives anyway as the very CDR bytes that go on the wire (`write`), and the recorder
subscribes with ``raw=True`` to the other topics it is told to record (`subscribe`):
the simulator process records its high-rate topics without a second DDS hop, and the
low-rate topics of the other nodes arrive as CDR bytes that are stored unchanged.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping

from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from stns_ros import topics as T
from stns_ros.bag import BagWriter, message_class

RECORD_QOS = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
LATCHED_QOS = QoSProfile(
    depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
)


class TopicRecorder:
    """A bag being recorded by `node`; `close()` is idempotent and leaves a complete bag."""

    def __init__(
        self,
        node: Node,
        path: str,
        *,
        log_time: Callable[[], int],
        compression: str = "zstd",
        chunk_size: int = 256 * 1024,
        flush_period: float = 2.0,
        custom_data: Mapping[str, str] | None = None,
    ) -> None:
        self._node = node
        self._log_time = log_time
        self.bag = BagWriter(path, compression=compression, chunk_size=chunk_size,
                             custom_data=custom_data)
        self._subs = []
        self._timer = None
        if flush_period > 0:
            self._timer = node.create_timer(
                flush_period, self.bag.flush, clock=Clock(clock_type=ClockType.STEADY_TIME)
            )

    def add(self, topic: str, msgtype: str | None = None) -> None:
        self.bag.add_topic(topic, msgtype or T.TYPES[topic])

    def write(self, topic: str, data: bytes, t_ns: int | None = None) -> None:
        if not self.bag.closed:
            self.bag.write(topic, data, self._log_time() if t_ns is None else t_ns)

    def subscribe(self, topics: Iterable[str], types: Mapping[str, str] | None = None) -> None:
        """Record these topics as received (raw CDR) from other processes."""
        types = dict(T.TYPES, **(types or {}))
        for topic in topics:
            msgtype = types[topic]
            self.add(topic, msgtype)
            qos = LATCHED_QOS if topic == T.RUN_CONFIG else RECORD_QOS
            self._subs.append(
                self._node.create_subscription(
                    message_class(msgtype), topic,
                    lambda data, topic=topic: self.write(topic, data), qos, raw=True,
                )
            )

    def close(self) -> None:
        if self._timer is not None:
            self._timer.cancel()
        self.bag.close()
