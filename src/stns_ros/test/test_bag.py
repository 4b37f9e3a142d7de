import shutil
from pathlib import Path

import pytest
from geometry_msgs.msg import TwistStamped
from mcap.reader import make_reader
from rclpy.serialization import serialize_message
from std_msgs.msg import String
from stns_ros.bag import (
    BagWriter,
    Recovery,
    bag_dir,
    check_complete,
    decode,
    has_summary,
    message_definition,
    read_messages,
    read_metadata,
    recover,
)
from stns_ros.errors import StnsRosError
from stns_ros.summary import load_run

from stns_ros import topics as T


def _write(path, n=500, flush_at=None, close=True):
    w = BagWriter(path, chunk_size=4096, custom_data={"k": "v"})
    w.add_topic("/cmd_vel", "geometry_msgs/msg/TwistStamped")
    w.add_topic("/note", "std_msgs/String")
    m = TwistStamped()
    for i in range(n):
        m.twist.linear.x = float(i)
        w.write("/cmd_vel", serialize_message(m), 1000 + i)
        if i % 100 == 0:
            w.write("/note", serialize_message(String(data=f"n{i}")), 1000 + i)
        if flush_at is not None and i == flush_at:
            w.flush()
    if close:
        w.close()
        w.close()  # idempotent
    return w


def test_complete_schemas():
    msgdef, rihs = message_definition("nav_msgs/Odometry")
    assert "MSG: std_msgs/Header" in msgdef and "MSG: geometry_msgs/PoseWithCovariance" in msgdef
    assert rihs.startswith("RIHS01_")
    with pytest.raises(StnsRosError, match="unknown message type 'nope_msgs/msg/X'"):
        message_definition("nope_msgs/msg/X")


def test_round_trip_with_three_readers(tmp_path):
    _write(tmp_path / "b")
    msgs = list(read_messages(tmp_path / "b"))
    assert len(msgs) == 505
    assert decode(msgs[-1]).twist.linear.x == 499.0
    meta = read_metadata(tmp_path / "b")
    assert meta["message_count"] == 505 and meta["storage_identifier"] == "mcap"
    assert meta["custom_data"] == {"k": "v"}

    from rosbags.highlevel import AnyReader

    with AnyReader([tmp_path / "b"]) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
        assert counts == {"/cmd_vel": 500, "/note": 5}
        last = None
        for conn, _, raw in reader.messages():
            last = reader.deserialize(raw, conn.msgtype) if conn.topic == "/cmd_vel" else last
        assert last.twist.linear.x == 499.0

    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    with open(tmp_path / "b" / "b.mcap", "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        got = [msg for *_, msg in reader.iter_decoded_messages(topics=["/note"])]
    assert [m.data for m in got] == [f"n{i}" for i in range(0, 500, 100)]


def test_killed_writer_leaves_a_readable_prefix(tmp_path):
    w = _write(tmp_path / "b", n=500, flush_at=300, close=False)
    killed = tmp_path / "killed"
    shutil.copytree(tmp_path / "b", killed)  # the state a SIGKILL would leave
    w.close()
    assert not (killed / "metadata.yaml").exists()
    msgs = [m for m in read_messages(killed) if m.topic == "/cmd_vel"]
    assert len(msgs) >= 301  # everything up to the flush, at least
    assert [decode(m).twist.linear.x for m in msgs] == [float(i) for i in range(len(msgs))]

    as_killed = (killed / "b.mcap").read_bytes()
    r = recover(killed)  # rewrite the prefix as a complete bag that every reader opens
    n = r.kept
    assert n == len(list(read_messages(killed))) and (killed / "metadata.yaml").exists()
    assert r == Recovery(n, None, (killed / "b.mcap.orig",), rewritten=True)
    assert (killed / "b.mcap.orig").read_bytes() == as_killed  # nothing recorded is lost
    from rosbags.highlevel import AnyReader

    with AnyReader([killed]) as reader:
        assert sum(1 for _ in reader.messages()) == n
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b", "killed"]
    assert recover(killed) == Recovery(n, n, (killed / "b.mcap.orig",))  # complete: left alone
    assert (killed / "b.mcap.orig").read_bytes() == as_killed


def _truncated(path, keep=0.6):
    """A closed bag whose MCAP file lost its tail afterwards (metadata.yaml still there)."""
    _write(path, n=500, flush_at=300)
    f = path / f"{path.name}.mcap"
    f.write_bytes(f.read_bytes()[:int(f.stat().st_size * keep)])
    return f


def test_a_file_truncated_after_closing_is_reported_with_its_counts(tmp_path):
    _write(tmp_path / "ok", n=500, flush_at=300)
    assert has_summary(tmp_path / "ok") and check_complete(tmp_path / "ok") is None
    _truncated(tmp_path / "b")
    n = len(list(read_messages(tmp_path / "b")))
    assert 0 < n < 505 and not has_summary(tmp_path / "b")
    why = check_complete(tmp_path / "b")
    assert f"{n} of 505 messages readable" in why and "b.mcap has lost its MCAP summary" in why
    assert "/note " in why and "--recover" in why


def test_recover_a_truncated_bag_keeps_the_originals_and_never_overwrites_them(tmp_path):
    bag = tmp_path / "b"
    f = _truncated(bag)
    as_found = f.read_bytes(), (bag / "metadata.yaml").read_text()
    n = len(list(read_messages(bag)))
    r = recover(bag)
    assert r == Recovery(n, 505, (bag / "b.mcap.orig", bag / "metadata.yaml.orig"), True)
    assert ((bag / "b.mcap.orig").read_bytes(), (bag / "metadata.yaml.orig").read_text()) == as_found
    assert check_complete(bag) is None and has_summary(bag)
    meta = read_metadata(bag)
    assert meta["message_count"] == n and meta["relative_file_paths"] == ["b.mcap"]
    assert meta["custom_data"]["k"] == "v"  # the run's own custom data stays
    assert f"{n} of 505 messages kept" in meta["custom_data"]["stns_recovered_from"]
    from rosbags.highlevel import AnyReader

    with AnyReader([bag]) as reader:
        assert sum(1 for _ in reader.messages()) == n
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b"]  # no temporary folder left
    again = recover(bag)  # now complete: left alone, the originals untouched
    assert again == Recovery(n, n, r.originals) and not again.rewritten
    assert ((bag / "b.mcap.orig").read_bytes(), (bag / "metadata.yaml.orig").read_text()) == as_found
    f.write_bytes(f.read_bytes()[:-100])  # cut again: the first originals must not be replaced
    with pytest.raises(StnsRosError, match=r"b\.mcap\.orig' exists \(from an earlier recovery"):
        recover(bag)
    assert ((bag / "b.mcap.orig").read_bytes(), (bag / "metadata.yaml.orig").read_text()) == as_found


def test_bag_dir_of_a_file_inside_a_bag(tmp_path):
    _write(tmp_path / "b", n=5)
    assert bag_dir(tmp_path / "b") == bag_dir(tmp_path / "b" / "b.mcap") == tmp_path / "b"
    (tmp_path / "b" / "metadata.yaml").unlink()  # a killed recorder: the file's name tells
    assert bag_dir(tmp_path / "b" / "b.mcap") == tmp_path / "b"
    (tmp_path / "b" / "b.mcap").rename(tmp_path / "loose.mcap")
    assert bag_dir(tmp_path / "loose.mcap") is None
    with pytest.raises(StnsRosError, match=r"loose\.mcap' is not one"):
        recover(tmp_path / "loose.mcap")


@pytest.mark.parametrize("content", [b"", b"not a bag", b"\x89MCAP"])
def test_a_file_that_is_not_mcap_is_refused_by_name(tmp_path, content):
    bag = tmp_path / "fake"
    bag.mkdir()
    (bag / "fake.mcap").write_bytes(content)
    with pytest.raises(StnsRosError, match=r"fake\.mcap' is not an MCAP file"):
        list(read_messages(bag))
    with pytest.raises(StnsRosError, match=r"fake\.mcap' is not an MCAP file"):
        recover(bag)
    assert (bag / "fake.mcap").read_bytes() == content  # left as it was
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fake"]  # no half-written copy


def test_a_complete_bag_with_a_damaged_chunk_is_reported_not_raised_raw(tmp_path):
    _write(tmp_path / "b", n=500, flush_at=300)  # two chunks, summary written
    f = tmp_path / "b" / "b.mcap"
    data = bytearray(f.read_bytes())
    good = [m for m in read_messages(tmp_path / "b") if m.topic == "/cmd_vel"]
    assert len(good) == 500
    with open(f, "rb") as fh:
        chunk = make_reader(fh).get_summary().chunk_indexes[1]
    mid = chunk.chunk_start_offset + chunk.chunk_length // 2
    data[mid:mid + 64] = bytes(64)  # zeros inside the second chunk's compressed data
    f.write_bytes(bytes(data))
    with pytest.raises(StnsRosError, match=r"b\.mcap' is corrupt after \d+ messages read"):
        list(read_messages(tmp_path / "b"))


def test_refuses_to_overwrite_and_unknown_topic(tmp_path):
    w = BagWriter(tmp_path / "b")
    with pytest.raises(StnsRosError, match="was not registered"):
        w.write("/x", b"", 0)
    w.close()
    with pytest.raises(StnsRosError, match="exists already"):
        BagWriter(tmp_path / "b")
    with pytest.raises(StnsRosError, match="unknown bag compression 'gzip'"):
        BagWriter(tmp_path / "c", compression="gzip")
    with pytest.raises(StnsRosError, match="no bag at"):
        list(read_messages(Path(tmp_path / "none")))


@pytest.mark.parametrize("text, message", [
    ("rosbag2_bagfile_information: [1\n", "is not readable YAML"),
    ("other: 1\n", "holds no rosbag2_bagfile_information mapping"),
    ("- 1\n", "holds no rosbag2_bagfile_information mapping"),
])
def test_damaged_metadata_is_named(tmp_path, text, message):
    _write(tmp_path / "b", n=5)
    (tmp_path / "b" / "metadata.yaml").write_text(text)
    with pytest.raises(StnsRosError, match="metadata.yaml") as err:
        read_metadata(tmp_path / "b")
    assert message in str(err.value)
    with pytest.raises(StnsRosError, match=message):
        recover(tmp_path / "b")  # a complete bag's count comes from its metadata


@pytest.mark.parametrize("data, message", [
    ("{not json", "is not a JSON object (Expecting property name"),
    ("[1, 2]", "is not a JSON object ([1, 2])"),
    ('{"trial": 1}', 'has no integer "index"'),
])
def test_run_summary_names_a_damaged_step_message(tmp_path, data, message):
    w = BagWriter(tmp_path / "b")
    w.add_topic(T.STEPS, "std_msgs/String")
    w.write(T.STEPS, serialize_message(String(data='{"index": 0, "trial": 0}')), 1000)
    w.write(T.STEPS, serialize_message(String(data=data)), 2000)
    w.close()
    with pytest.raises(StnsRosError) as err:
        load_run(tmp_path / "b")
    assert f"the {T.STEPS} message at 2000 ns" in str(err.value) and message in str(err.value)
