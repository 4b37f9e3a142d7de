"""rosbag2 directories with MCAP storage: writing (chunked, compressed, indexed) and reading.

`BagWriter` writes ``<dir>/<dir>.mcap`` with the `mcap` library (ros2 profile, complete
``ros2msg`` schemas from the rosbags Jazzy typestore, ``cdr`` messages, zstd or lz4
chunks, message indexes, statistics and summary) and, on `close()`, ``metadata.yaml`` in
the rosbag2 format (version 9) that ``ros2 bag info/play`` and rosbags read.

The file is opened unbuffered and chunks are flushed on a size limit and on `flush()`:
every write reaches the OS as whole records, so a recorder killed with SIGKILL leaves a
file whose complete chunks `read_messages` (and rosbags' AnyReader) still read.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import struct
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml
from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.records import Channel, Message, Schema
from mcap.stream_reader import StreamReader
from mcap.writer import MCAP0_MAGIC as _MCAP_MAGIC
from mcap.writer import CompressionType, Writer

from stns_ros.errors import StnsRosError

_COMPRESSION = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}
_TYPESTORE = None


def _typestore():
    global _TYPESTORE
    if _TYPESTORE is None:
        from rosbags.typesys import Stores, get_typestore

        _TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
    return _TYPESTORE


def normalize_type(msgtype: str) -> str:
    """'geometry_msgs/TwistStamped' or 'geometry_msgs/msg/TwistStamped' -> the latter."""
    parts = msgtype.split("/")
    if len(parts) == 2:
        return f"{parts[0]}/msg/{parts[1]}"
    if len(parts) == 3 and parts[1] == "msg":
        return msgtype
    raise StnsRosError(f"not a ROS message type name: {msgtype!r}")


def message_definition(msgtype: str) -> tuple[str, str]:
    """(complete ros2msg definition with nested types, RIHS01 hash) of a Jazzy message type."""
    name = normalize_type(msgtype)
    ts = _typestore()
    if name not in ts.types:
        raise StnsRosError(f"unknown message type {msgtype!r} (not in the ROS 2 Jazzy typestore)")
    msgdef, _ = ts.generate_msgdef(name, ros_version=2)
    return msgdef, ts.hash_rihs01(name)


def rclpy_type_name(msg_class: type) -> str:
    """'geometry_msgs/msg/TwistStamped' for an rclpy message class."""
    module = msg_class.__module__.split(".")
    return f"{module[0]}/msg/{msg_class.__name__}"


class _RecordStream:
    """A file that hands every write straight to the OS (whole records; no user-space buffer),
    so that a SIGKILL never loses a record the writer has finished."""

    def __init__(self, path: Path) -> None:
        self._fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
        self._pos = 0

    def write(self, data: bytes | memoryview) -> int:
        view = memoryview(data)
        while view:
            n = os.write(self._fd, view)
            view = view[n:]
            self._pos += n
        return len(data)

    def tell(self) -> int:
        return self._pos

    def flush(self) -> None:
        pass

    def close(self) -> None:
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1


class BagWriter:
    """Write a rosbag2 directory holding one MCAP file (``<dir>.mcap`` unless `file_name` is
    given). A context manager; `close()` is idempotent."""

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        compression: str = "zstd",
        chunk_size: int = 256 * 1024,
        custom_data: Mapping[str, str] | None = None,
        file_name: str | None = None,
    ) -> None:
        if compression not in _COMPRESSION:
            raise StnsRosError(
                f"unknown bag compression {compression!r}; known: {', '.join(_COMPRESSION)}"
            )
        if int(chunk_size) < 1024:
            raise StnsRosError(f"chunk_size must be >= 1024 bytes, got {chunk_size!r}")
        self.path = Path(path)
        if self.path.exists():
            raise StnsRosError(f"bag directory {str(self.path)!r} exists already, not overwriting")
        self.path.mkdir(parents=True)
        self.mcap_path = self.path / (file_name or f"{self.path.name}.mcap")
        self._file = _RecordStream(self.mcap_path)
        self._writer = Writer(
            self._file, chunk_size=int(chunk_size), compression=_COMPRESSION[compression]
        )
        self._writer.start(profile="ros2", library="stns_ros")
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, tuple[int, str, str]] = {}
        self._counts: dict[str, int] = {}
        self._start = None
        self._end = 0
        self.compression = compression
        self.custom_data: dict[str, str] = dict(custom_data or {})
        self.closed = False

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def add_topic(self, topic: str, msgtype: str) -> None:
        """Register a topic once (its schema with complete nested definitions)."""
        name = normalize_type(msgtype)
        if topic in self._channels:
            if self._channels[topic][1] != name:
                raise StnsRosError(
                    f"topic {topic!r} registered as {self._channels[topic][1]}, not {name}"
                )
            return
        msgdef, rihs01 = message_definition(name)
        if name not in self._schemas:
            self._schemas[name] = self._writer.register_schema(
                name=name, encoding="ros2msg", data=msgdef.encode()
            )
        cid = self._writer.register_channel(
            topic=topic,
            message_encoding="cdr",
            schema_id=self._schemas[name],
            metadata={"offered_qos_profiles": ""},
        )
        self._channels[topic] = (cid, name, rihs01)
        self._counts[topic] = 0

    def has_topic(self, topic: str) -> bool:
        return topic in self._channels

    def write(self, topic: str, data: bytes, log_time_ns: int) -> None:
        """Append one CDR-serialized message of a registered topic."""
        if self.closed:
            raise StnsRosError(f"bag {str(self.path)!r} is closed")
        try:
            cid = self._channels[topic][0]
        except KeyError:
            raise StnsRosError(f"topic {topic!r} was not registered with add_topic") from None
        t = int(log_time_ns)
        self._writer.add_message(cid, log_time=t, data=bytes(data), publish_time=t,
                                 sequence=self._counts[topic])
        self._counts[topic] += 1
        if self._start is None or t < self._start:
            self._start = t
        self._end = max(self._end, t)

    def flush(self) -> None:
        """Finish the chunk in progress: everything so far is readable even if we are killed."""
        if not self.closed:
            self._writer.flush()

    @property
    def counts(self) -> dict[str, int]:
        return dict(self._counts)

    def close(self) -> None:
        """Write summary, footer and metadata.yaml. Safe to call twice."""
        if self.closed:
            return
        self.closed = True
        self._writer.finish()
        self._file.close()
        start = self._start or 0
        info = {
            "version": 9,
            "storage_identifier": "mcap",
            "relative_file_paths": [self.mcap_path.name],
            "duration": {"nanoseconds": max(0, self._end - start)},
            "starting_time": {"nanoseconds_since_epoch": start},
            "message_count": sum(self._counts.values()),
            "topics_with_message_count": [
                {
                    "topic_metadata": {
                        "name": topic,
                        "type": name,
                        "serialization_format": "cdr",
                        "offered_qos_profiles": [],
                        "type_description_hash": rihs01,
                    },
                    "message_count": self._counts[topic],
                }
                for topic, (_, name, rihs01) in self._channels.items()
            ],
            "compression_format": "",
            "compression_mode": "",
            "files": [
                {
                    "path": self.mcap_path.name,
                    "starting_time": {"nanoseconds_since_epoch": start},
                    "duration": {"nanoseconds": max(0, self._end - start)},
                    "message_count": sum(self._counts.values()),
                }
            ],
            "custom_data": self.custom_data or None,
            "ros_distro": "jazzy",
        }
        tmp = self.path / "metadata.yaml.tmp"
        tmp.write_text(yaml.safe_dump({"rosbag2_bagfile_information": info}, sort_keys=False))
        tmp.replace(self.path / "metadata.yaml")


@dataclass(frozen=True)
class BagMessage:
    topic: str
    msgtype: str
    log_time: int
    data: bytes


def mcap_file(bag: str | os.PathLike[str]) -> Path:
    """The .mcap file of a rosbag2 directory (or the path itself if it is a file)."""
    p = Path(bag)
    if p.is_file():
        return p
    if not p.is_dir():
        raise StnsRosError(f"no bag at {str(p)!r}")
    files = sorted(p.glob("*.mcap"))
    if not files:
        raise StnsRosError(f"no .mcap file in {str(p)!r}")
    return files[0]


def bag_dir(bag: str | os.PathLike[str]) -> Path | None:
    """The rosbag2 directory a bag path names: the path itself if it is a directory, the
    folder of an .mcap file if that folder is a bag (it has metadata.yaml, or the file is
    named after it as rosbag2 and `BagWriter` name it, as a killed recorder leaves it);
    None for a bare .mcap file."""
    p = Path(bag)
    if p.is_dir():
        return p
    folder = p.parent
    named = re.fullmatch(rf"{re.escape(folder.name)}(_\d+)?\.mcap", p.name)
    return folder if named or (folder / "metadata.yaml").is_file() else None


def read_messages(bag: str | os.PathLike[str], topics: set[str] | None = None) -> Iterator[BagMessage]:
    """Messages of a bag in file order. Reads a complete file through its summary, and the
    complete records of a truncated one (a killed recorder) in a linear scan. A file that is
    not MCAP, or a complete one with a damaged chunk (chunk CRCs are checked), raises
    `StnsRosError` naming the file."""
    path = mcap_file(bag)
    with open(path, "rb") as f:
        reader = _complete_reader(f)
        if reader is not None:
            n = 0
            try:
                for schema, channel, message in reader.iter_messages(
                    topics=list(topics) if topics else None, log_time_order=False
                ):
                    n += 1
                    yield BagMessage(channel.topic, schema.name if schema else "",
                                     message.log_time, bytes(message.data))
            except Exception as e:  # noqa: BLE001 - a CRC, decompression or record error
                raise StnsRosError(
                    f"{str(path)!r} is corrupt after {n} messages read: {type(e).__name__}: {e}"
                ) from None
            return
    yield from _scan_prefix(path, topics)


def _complete_reader(f: Any) -> Any:
    """A CRC-checking reader of an MCAP file that ends with its summary and footer, as a
    closed writer leaves it; None for any other file (cut short, or not MCAP at all:
    `_scan_prefix` tells which). `make_reader` reads the magic, so it is guarded too."""
    try:
        reader = make_reader(f, validate_crcs=True)
        return reader if reader.get_summary() is not None else None
    except (McapError, EOFError, ValueError, AssertionError, struct.error):
        return None


def has_summary(bag: str | os.PathLike[str]) -> bool:
    """Whether the bag's MCAP file ends with its summary and footer (only those are read)."""
    with open(mcap_file(bag), "rb") as f:
        return _complete_reader(f) is not None


def _scan_prefix(path: Path, topics: set[str] | None) -> Iterator[BagMessage]:
    schemas: dict[int, Schema] = {}
    channels: dict[int, Channel] = {}
    with open(path, "rb") as f:
        # A killed recording still starts with the magic the writer puts first; without it
        # the file is not MCAP at all, and reading it as an empty bag would hide that.
        head = f.read(len(_MCAP_MAGIC))
        if head != _MCAP_MAGIC:
            raise StnsRosError(
                f"{str(path)!r} is not an MCAP file (starts with {head!r}, not the MCAP magic "
                f"{_MCAP_MAGIC!r})")
        f.seek(0)
        it = iter(StreamReader(f, skip_magic=False, emit_chunks=False).records)
        while True:
            try:
                rec = next(it)
            except StopIteration:
                return
            except Exception:  # noqa: BLE001 - the truncated tail of a killed recording
                return
            if isinstance(rec, Schema):
                schemas[rec.id] = rec
            elif isinstance(rec, Channel):
                channels[rec.id] = rec
            elif isinstance(rec, Message):
                ch = channels.get(rec.channel_id)
                if ch is None or (topics and ch.topic not in topics):
                    continue
                schema = schemas.get(ch.schema_id)
                yield BagMessage(ch.topic, schema.name if schema else "", rec.log_time,
                                 bytes(rec.data))


def decode(message: BagMessage) -> Any:
    """Deserialize a BagMessage into an rclpy message object."""
    from rclpy.serialization import deserialize_message

    return deserialize_message(message.data, message_class(message.msgtype))


def message_class(msgtype: str) -> type:
    """The rclpy class of 'pkg/msg/Type' (rosidl_runtime_py is not on PyPI)."""
    import importlib

    pkg, _, name = normalize_type(msgtype).split("/")
    try:
        return getattr(importlib.import_module(f"{pkg}.msg"), name)
    except (ImportError, AttributeError):
        raise StnsRosError(f"message type {msgtype!r} is not installed") from None


def read_metadata(bag: str | os.PathLike[str]) -> dict[str, Any]:
    """metadata.yaml of a rosbag2 directory as plain data."""
    p = Path(bag) / "metadata.yaml"
    if not p.is_file():
        raise StnsRosError(f"no metadata.yaml in {str(bag)!r} (was the recording closed?)")
    try:
        info = yaml.safe_load(p.read_text())["rosbag2_bagfile_information"]
    except (yaml.YAMLError, UnicodeDecodeError, OSError) as e:
        raise StnsRosError(f"{str(p)!r} is not readable YAML: {e}") from None
    except (KeyError, TypeError):
        info = None
    if not isinstance(info, dict):
        raise StnsRosError(f"{str(p)!r} holds no rosbag2_bagfile_information mapping")
    return info


def json_custom(value: Any) -> str:
    return json.dumps(value, sort_keys=True, separators=(",", ":"))


def _recorded(bag: str | os.PathLike[str]) -> tuple[int, dict[str, tuple[str, int]]]:
    """(message_count, {topic: (type, message_count)}) as the bag's metadata.yaml lists them;
    `StnsRosError` naming the file when it does not."""
    info = read_metadata(bag)
    try:
        topics = {t["topic_metadata"]["name"]: (str(t["topic_metadata"]["type"]),
                                                int(t["message_count"]))
                  for t in info["topics_with_message_count"]}
        return int(info["message_count"]), topics
    except (KeyError, TypeError, ValueError):
        raise StnsRosError(
            f"{str(Path(bag) / 'metadata.yaml')!r} does not list message_count and, for every "
            "topic, its name, type and message_count (topics_with_message_count)") from None


def _count(bag: str | os.PathLike[str]) -> dict[str, int]:
    counts: dict[str, int] = {}
    for m in read_messages(bag):
        counts[m.topic] = counts.get(m.topic, 0) + 1
    return counts


def check_complete(bag: str | os.PathLike[str], counts: Mapping[str, int] | None = None
                   ) -> str | None:
    """None when the bag's MCAP file has its summary and holds what metadata.yaml lists;
    else why not, with the readable and recorded message counts (per topic where they
    differ). `counts` are the readable messages per topic if the caller has read them."""
    counts = _count(bag) if counts is None else counts
    n = sum(counts.values())
    name = mcap_file(bag).name
    complete = has_summary(bag)
    if not (Path(bag) / "metadata.yaml").is_file():
        if complete:
            return None  # a bare .mcap file: nothing to compare with
        return (f"bag {str(bag)!r} is cut short: {name} has no MCAP summary and there is no "
                f"metadata.yaml (the recorder was killed); {n} messages readable, how many "
                "were recorded is unknown; `stns_replay BAG --recover` rewrites them as a "
                "complete bag")
    total, topics = _recorded(bag)
    short = ", ".join(f"{t} {counts.get(t, 0)} of {c}" for t, (_, c) in topics.items()
                      if counts.get(t, 0) != c)
    detail = f" ({short})" if short else ""
    if not complete:
        # metadata.yaml is written after the summary: the file was cut after the bag was closed
        return (f"bag {str(bag)!r} is truncated: {name} has lost its MCAP summary and footer; "
                f"{n} of {total} messages readable{detail}; `stns_replay BAG --recover` "
                f"rewrites the readable part as a complete bag and keeps the original as "
                f"{name}{_ORIGINAL}")
    if n != total or short:
        return f"bag {str(bag)!r}: {n} of {total} messages readable{detail}"
    return None


_ORIGINAL = ".orig"


@dataclass(frozen=True)
class Recovery:
    """What `recover` found and did: `kept` messages are in the bag now, of `recorded` (the
    metadata.yaml count; None when the recorder was killed before writing it); `originals`
    hold the bytes as recorded (the MCAP file and metadata.yaml, from this or an earlier
    recovery); `rewritten` is False for a complete bag, which is left alone."""

    kept: int
    recorded: int | None
    originals: tuple[Path, ...] = ()
    rewritten: bool = False


def recover(bag: str | os.PathLike[str]) -> Recovery:
    """Rewrite the readable records of a bag cut short into a complete rosbag2 directory in
    place. Cut short: its MCAP file has no summary (a killed recorder, which leaves no
    metadata.yaml either, or a file truncated after the bag was closed) or metadata.yaml is
    missing. The original file and metadata.yaml are renamed to ``<name>.orig`` beside the
    new ones, never overwritten (an earlier recovery's are refused); the topics and custom
    data of the old metadata.yaml are kept. A complete bag is left alone."""
    path = Path(bag)
    if not path.is_dir():
        raise StnsRosError(f"--recover rewrites a rosbag2 directory; {str(path)!r} is not one "
                           "(put a bare .mcap file in a folder of its own first)")
    meta = path / "metadata.yaml"
    recorded = _recorded(path) if meta.is_file() else None
    src = mcap_file(path)
    originals = (src.with_name(src.name + _ORIGINAL), meta.with_name(meta.name + _ORIGINAL))
    if recorded is not None and has_summary(path):
        return Recovery(recorded[0], recorded[0], tuple(p for p in originals if p.exists()))
    if recorded is None:
        originals = originals[:1]
    tmp = path.with_name(path.name + ".recovering")
    for p in (*originals, tmp):
        if p.exists():  # never overwrite what an earlier recovery kept
            raise StnsRosError(f"{str(p)!r} exists (from an earlier recovery): move it away first")
    try:
        n = _rewrite(src, tmp, recorded, read_metadata(path).get("custom_data") if recorded else None)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)  # only our own half-written copy
        raise
    # the original bytes are renamed, never deleted; metadata.yaml comes last, so an
    # interruption leaves a bag that is again recoverable (and its originals refused)
    src.rename(originals[0])
    if recorded is not None:
        meta.rename(originals[1])
    (tmp / src.name).rename(src)
    (tmp / meta.name).rename(meta)
    tmp.rmdir()
    return Recovery(n, recorded[0] if recorded else None, originals, rewritten=True)


def _rewrite(src: Path, tmp: Path, recorded: tuple[int, dict[str, tuple[str, int]]] | None,
             custom: Any) -> int:
    """Write the readable messages of `src` as a complete bag `tmp` (file named as `src`);
    return how many."""
    n = 0
    with BagWriter(tmp, file_name=src.name) as w:
        for topic, (msgtype, _) in (recorded[1] if recorded else {}).items():
            w.add_topic(topic, msgtype)  # topics recorded but cut away stay listed (0)
        for m in _scan_prefix(src, None):
            w.add_topic(m.topic, m.msgtype)
            w.write(m.topic, m.data, m.log_time)
            n += 1
        if isinstance(custom, dict):
            w.custom_data.update({str(k): str(v) for k, v in custom.items()})
        of = f" of {recorded[0]}" if recorded else ""
        w.custom_data["stns_recovered_from"] = (
            f"{src.name}{_ORIGINAL}: a recording cut short, {n}{of} messages kept")
    return n
