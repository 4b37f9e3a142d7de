"""stns_recorder: a stand-alone recorder node (records topics into a rosbag2/MCAP directory).

The bring-up records inside the simulator process (no second DDS hop for the per-tick
topics); this node records any run or any set of topics from outside, like ``ros2 bag
record``. Topic types come from the run's table (`topics.TYPES`) or ``types``
("topic=pkg/msg/Type" entries). Log times are the node's clock (sim time with
use_sim_time). SIGINT/SIGTERM close the bag after half a second more of recording (what DDS
has delivered is written); a SIGKILL leaves a readable prefix.
"""

from __future__ import annotations

from rclpy.node import Node

from stns_ros import topics as T
from stns_ros.bag import message_class, message_definition
from stns_ros.errors import StnsRosError
from stns_ros.params import NamedRefusals, declare
from stns_ros.recording import TopicRecorder
from stns_ros.runtime import run_node


class RecorderNode(NamedRefusals, Node):
    def __init__(self, **kwargs) -> None:
        super().__init__("stns_recorder", **kwargs)
        output = declare(self, "output", "", "rosbag2 directory to create.", read_only=True)
        topics = declare(self, "topics", list(T.TYPES), "Topics to record.", read_only=True)
        types = declare(self, "types", [""], "Extra 'topic=pkg/msg/Type' entries.",
                        read_only=True)
        compression = declare(self, "compression", "zstd", "MCAP chunk compression.",
                              choices=("zstd", "lz4", "none"), read_only=True)
        chunk = declare(self, "chunk_size", 262144, "MCAP chunk size, bytes.",
                        range=(1024, 2**26), read_only=True)
        if not output:
            raise StnsRosError("parameter output (the bag directory) is required")
        extra = {}
        for entry in types:
            if not entry:
                continue
            topic, sep, msgtype = entry.partition("=")
            if not sep:
                raise StnsRosError(f"types entry must be topic=pkg/msg/Type, got {entry!r}")
            extra[topic] = msgtype
        unknown = [t for t in topics if t not in T.TYPES and t not in extra]
        if unknown:
            raise StnsRosError(f"no type known for topic(s) {unknown}; add them to 'types'")
        _check_types(extra)
        self.recorder = TopicRecorder(self, output, log_time=lambda: self.get_clock().now().nanoseconds,
                                      compression=compression, chunk_size=chunk)
        self.recorder.subscribe(topics, extra)
        self.get_logger().info(f"recording {len(topics)} topics into {output}")

    def close(self) -> None:
        self.recorder.close()


def _check_types(types: dict[str, str]) -> None:
    """Each extra type can be stored and subscribed to, checked before the bag directory is
    made: a failure after it would leave a half-made bag in the way of the next start."""
    for topic, msgtype in types.items():
        try:
            message_definition(msgtype)
            message_class(msgtype)
        except StnsRosError as e:
            raise StnsRosError(f"types: {topic}={msgtype}: {e}") from None


def main(args=None) -> None:
    run_node("stns_recorder", RecorderNode, args, drain_seconds=0.5)


if __name__ == "__main__":
    main()
