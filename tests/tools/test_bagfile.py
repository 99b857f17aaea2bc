"""Bag writer/reader: checked INDEPENDENTLY with the plain mcap reader and metadata.yaml."""
from __future__ import annotations

import json
import os
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from mcap.reader import make_reader

from bb2_sim.state import VehicleState
from bb2_tools import bagfile
from bb2_tools.bagfile import BagError, BagReader, BagWriter, qos_entry, recover

rclpy = pytest.importorskip("rclpy", reason="rclpy (ROS 2 Jazzy wheels) not installed")
from rclpy.serialization import deserialize_message, serialize_message  # noqa: E402

from bb2_msgs_py import conversions as conv  # noqa: E402
from bb2_msgs_py.contract import message_class  # noqa: E402

SHARE = Path(sys.prefix) / "share"
TF = {"transforms": [{"header": {"stamp": {"sec": 1, "nanosec": 5}, "frame_id": "odom"},
                      "child_frame_id": "base_link",
                      "transform": {"translation": {"x": 1.0, "y": 2.0, "z": -3.0},
                                    "rotation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}}]}


def _state(k: int) -> VehicleState:
    return VehicleState(0.01 * k, np.array([-2.0 * k, 1.0, -30.0]), np.array([0.0, 0.001 * k, 0.1]),
                        np.array([-5.0, 0.1, 0.0]), np.array([0.0, 0.01, 0.02]))


def write_sample_bag(bag_dir: Path, n: int = 300, chunk_size: int = 4096) -> BagWriter:
    w = BagWriter(bag_dir, chunk_size=chunk_size, custom_data={"mission": "unit-test"})
    w.add_topic("/bb2/odom", "nav_msgs/msg/Odometry",
                offered_qos=[qos_entry(reliability="best_effort", history="keep_last", depth=5)])
    w.add_topic("/bb2/planes/cmd", "sensor_msgs/msg/JointState", offered_qos=[qos_entry()])
    w.add_topic("/tf", "tf2_msgs/msg/TFMessage", offered_qos=[qos_entry()])
    for k in range(n):
        t_ns = 1_000_000_000 + 10_000_000 * k
        w.write("/bb2/odom", serialize_message(conv.state_to_odometry(_state(k))), t_ns)
        if k % 3 == 0:
            w.write("/bb2/planes/cmd", serialize_message(conv.planes_message(0.01 * k, [0.01 * k] * 5)), t_ns)
        w.write_dict("/tf", TF, t_ns)
    return w


@pytest.fixture
def sample_bag(tmp_path) -> Path:
    w = write_sample_bag(tmp_path / "run1")
    w.close()
    return tmp_path / "run1"


def test_definition_concatenates_dependencies_like_rosbag2():
    text = bagfile.message_definition("nav_msgs/msg/Odometry")
    assert text.startswith((SHARE / "nav_msgs/msg/Odometry.msg").read_text())
    sep = "\n" + "=" * 80 + "\nMSG: "
    deps = [block.split("\n", 1)[0] for block in text.split(sep)[1:]]
    assert len(deps) == len(set(deps))  # each dependency once
    assert set(deps) == {"std_msgs/Header", "builtin_interfaces/Time", "geometry_msgs/PoseWithCovariance",
                         "geometry_msgs/Pose", "geometry_msgs/Point", "geometry_msgs/Quaternion",
                         "geometry_msgs/TwistWithCovariance", "geometry_msgs/Twist", "geometry_msgs/Vector3"}
    assert deps[0] == "geometry_msgs/PoseWithCovariance"  # std::set order, depth first
    assert "MSG: geometry_msgs/TransformStamped" in bagfile.message_definition("tf2_msgs/msg/TFMessage")


def test_type_hashes_match_the_installed_type_descriptions():
    for f in sorted(SHARE.glob("*/msg/*.json"))[:60]:
        d = json.loads(f.read_text())
        name = d["type_hashes"][0]["type_name"]
        assert bagfile.type_hash(name) == d["type_hashes"][0]["hash_string"], name
    # tf2_msgs is not installed: its hash is computed from the embedded description (Jazzy value)
    assert bagfile.type_hash("tf2_msgs/msg/TFMessage") == \
        "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087"


def test_mcap_read_back_independently(sample_bag):
    mcap_file = sample_bag / "run1_0.mcap"
    with open(mcap_file, "rb") as f:
        reader = make_reader(f)
        assert reader.get_header().profile == "ros2"
        summary = reader.get_summary()
        schemas = {s.name: s for s in summary.schemas.values()}
        assert set(schemas) == {"nav_msgs/msg/Odometry", "sensor_msgs/msg/JointState", "tf2_msgs/msg/TFMessage"}
        assert all(s.encoding == "ros2msg" for s in schemas.values())
        odom_text = schemas["nav_msgs/msg/Odometry"].data.decode()
        assert "MSG: geometry_msgs/PoseWithCovariance" in odom_text
        assert "MSG: builtin_interfaces/Time" in odom_text
        channels = {c.topic: c for c in summary.channels.values()}
        for c in channels.values():
            assert c.message_encoding == "cdr"
            assert set(c.metadata) == {"offered_qos_profiles", "topic_type_hash"}
            assert c.metadata["topic_type_hash"].startswith("RIHS01_")
            qos = yaml.safe_load(c.metadata["offered_qos_profiles"])
            assert qos[0]["deadline"] == {"sec": 9223372036, "nsec": 854775807}
        assert yaml.safe_load(channels["/bb2/odom"].metadata["offered_qos_profiles"])[0]["reliability"] \
            == "best_effort"
        stats = summary.statistics
        counts = {summary.channels[cid].topic: n for cid, n in stats.channel_message_counts.items()}
        assert counts == {"/bb2/odom": 300, "/bb2/planes/cmd": 100, "/tf": 300}
        assert stats.message_count == 700
        assert stats.message_start_time == 1_000_000_000
        assert stats.message_end_time == 1_000_000_000 + 10_000_000 * 299
        assert stats.chunk_count > 1 and len(summary.chunk_indexes) == stats.chunk_count
        assert {ci.compression for ci in summary.chunk_indexes} == {"zstd"}
        assert all(ci.compressed_size < ci.uncompressed_size for ci in summary.chunk_indexes)
        meta = list(reader.iter_metadata())
        assert [m.name for m in meta] == ["rosbag2"]
        assert yaml.safe_load(meta[0].metadata["serialized_metadata"])["version"] == 9
        # payloads decode with the ROS type support to what was written
        for _, _channel, msg in reader.iter_messages(topics=["/bb2/odom"]):
            odom = deserialize_message(msg.data, message_class("nav_msgs/msg/Odometry"))
            k = round((msg.log_time - 1_000_000_000) / 10_000_000)
            np.testing.assert_allclose(conv.odometry_to_state(odom).as_vector(), _state(k).as_vector(),
                                       atol=1e-12)


def test_metadata_yaml_version_9(sample_bag):
    doc = yaml.safe_load((sample_bag / "metadata.yaml").read_text())
    info = doc["rosbag2_bagfile_information"]
    assert info["version"] == 9
    assert info["storage_identifier"] == "mcap"
    assert info["relative_file_paths"] == ["run1_0.mcap"]
    assert info["message_count"] == 700
    assert info["starting_time"] == {"nanoseconds_since_epoch": 1_000_000_000}
    assert info["duration"] == {"nanoseconds": 10_000_000 * 299}
    assert info["compression_format"] == "" and info["compression_mode"] == ""
    assert info["ros_distro"] == "jazzy"
    assert info["custom_data"] == {"mission": "unit-test"}
    assert info["files"] == [{"path": "run1_0.mcap", "starting_time": {"nanoseconds_since_epoch": 1_000_000_000},
                              "duration": {"nanoseconds": 10_000_000 * 299}, "message_count": 700}]
    topics = {t["topic_metadata"]["name"]: t for t in info["topics_with_message_count"]}
    assert {n: t["message_count"] for n, t in topics.items()} == {"/bb2/odom": 300, "/bb2/planes/cmd": 100, "/tf": 300}
    odom = topics["/bb2/odom"]["topic_metadata"]
    assert odom["type"] == "nav_msgs/msg/Odometry" and odom["serialization_format"] == "cdr"
    assert odom["type_description_hash"] == json.loads(
        (SHARE / "nav_msgs/msg/Odometry.json").read_text())["type_hashes"][0]["hash_string"]
    q = odom["offered_qos_profiles"]  # v9: a YAML sequence, not a string
    assert isinstance(q, list) and q[0]["reliability"] == "best_effort" and q[0]["history"] == "keep_last"
    assert set(q[0]) == {"history", "depth", "reliability", "durability", "deadline", "lifespan", "liveliness",
                         "liveliness_lease_duration", "avoid_ros_namespace_conventions"}


def test_reader_iterates_with_topic_filter(sample_bag):
    r = BagReader(sample_bag)
    assert not r.truncated and r.message_counts == {"/bb2/odom": 300, "/bb2/planes/cmd": 100, "/tf": 300}
    cmds = list(r.messages("/bb2/planes/cmd"))
    assert len(cmds) == 100 and {t for t, _, _ in cmds} == {"/bb2/planes/cmd"}
    assert [ts for _, ts, _ in cmds] == sorted(ts for _, ts, _ in cmds)
    np.testing.assert_allclose(list(cmds[5][2].position), [0.15] * 5)
    tf = next(iter(r.messages(["/tf"])))[2]
    assert tf.transforms[0].child_frame_id == "base_link" and tf.transforms[0].transform.translation.z == -3.0
    assert BagReader(sample_bag / "run1_0.mcap").message_count == 700  # a bare .mcap works too
    with pytest.raises(BagError, match="not in the bag"):
        list(r.messages("/bb2/nothing"))
    infos = {t.name: t for t in r.topic_infos()}
    assert infos["/bb2/odom"].offered_qos[0]["depth"] == 5


def test_writer_rejects_bad_input(tmp_path, sample_bag):
    with pytest.raises(BagError, match="not empty"):
        BagWriter(sample_bag)
    with pytest.raises(BagError, match="compression"):
        BagWriter(tmp_path / "x", compression="gzip")
    w = BagWriter(tmp_path / "y")
    with pytest.raises(BagError, match="add_topic first"):
        w.write("/bb2/odom", b"\x00", 0)
    with pytest.raises(BagError, match="no .msg definition"):
        w.add_topic("/x", "nosuch_msgs/msg/Thing")
    w.add_topic("/bb2/odom", "nav_msgs/msg/Odometry")
    with pytest.raises(BagError, match="already recorded"):
        w.add_topic("/bb2/odom", "sensor_msgs/msg/Imu")
    w.close()


def _truncated_copy(src: Path, dst: Path, cut_fraction: float) -> Path:
    """A bag whose .mcap was cut as a SIGKILL leaves it: no summary, no footer, a partial chunk."""
    dst.mkdir(parents=True)
    data = (src / "run1_0.mcap").read_bytes()
    (dst / "run1_0.mcap").write_bytes(data[: int(len(data) * cut_fraction)])
    return dst


def test_truncated_file_is_read_up_to_the_last_complete_chunk(sample_bag, tmp_path):
    with open(sample_bag / "run1_0.mcap", "rb") as f:
        summary = make_reader(f).get_summary()
    cut = _truncated_copy(sample_bag, tmp_path / "cut", 0.6)
    size = (cut / "run1_0.mcap").stat().st_size
    complete = [ci for ci in summary.chunk_indexes if ci.chunk_start_offset + ci.chunk_length <= size]
    r = BagReader(cut)
    assert r.truncated and r.problem
    msgs = list(r.raw_messages())
    # every message of every complete chunk, nothing else
    expected_end = max(ci.message_end_time for ci in complete)
    assert max(m.log_time_ns for m in msgs) == expected_end
    assert 0 < len(msgs) < 700
    odom = [m for m in r.messages("/bb2/odom")]
    assert len(odom) == r.message_counts["/bb2/odom"]


@pytest.mark.parametrize("content, said", [
    (b"", "an empty file (0 bytes): nothing was recorded"),
    (b"garbage, not a recording\n", "not an MCAP file (it does not begin with the MCAP magic bytes)"),
    (b"PK\x03\x04" + bytes(200), "not an MCAP file (it does not begin with the MCAP magic bytes)"),
])
def test_a_file_that_is_no_mcap_is_said_so_not_called_truncated(tmp_path, content, said):
    """(Before 2026-12-07 a text file was read as a truncated bag: "file ends inside a record (InvalidMagic ...)",
    and bb2-replay said it would play it up to its last complete chunk.)"""
    f = tmp_path / "run_0.mcap"
    f.write_bytes(content)
    with pytest.raises(BagError) as e:
        BagReader(tmp_path)
    assert str(e.value) == f"{f}: {said}"


def test_a_bag_cut_inside_its_magic_is_truncated_and_empty(sample_bag, tmp_path):
    f = tmp_path / "run_0.mcap"
    f.write_bytes((sample_bag / "run1_0.mcap").read_bytes()[:5])  # a recorder killed while opening its file
    r = BagReader(f)
    assert r.truncated and r.problem and not r.topics


def test_recover_rewrites_a_valid_bag(sample_bag, tmp_path):
    cut = _truncated_copy(sample_bag, tmp_path / "killed" / "run1", 0.5)
    before = BagReader(cut)
    n = before.message_count
    rep = recover(cut)
    assert rep.was_truncated and rep.message_count == n and rep.bag_dir == cut
    assert sorted(p.name for p in cut.iterdir()) == ["metadata.yaml", "run1_0.mcap"]
    with open(cut / "run1_0.mcap", "rb") as f:
        reader = make_reader(f)
        stats = reader.get_summary().statistics
        assert stats.message_count == n
        channels = {c.topic: c for c in reader.get_summary().channels.values()}
        assert yaml.safe_load(channels["/bb2/odom"].metadata["offered_qos_profiles"])[0]["reliability"] == "best_effort"
    info = bagfile.read_metadata(cut)
    assert info["message_count"] == n and info["relative_file_paths"] == ["run1_0.mcap"]
    assert sum(t["message_count"] for t in info["topics_with_message_count"]) == n
    after = BagReader(cut)
    assert not after.truncated and after.message_counts == before.message_counts
    # recovering a complete bag into another directory keeps everything
    rep2 = recover(sample_bag, tmp_path / "copy")
    assert not rep2.was_truncated and rep2.message_count == 700


def test_sigkill_loses_at_most_the_open_chunk(tmp_path):
    """Chunks reach the OS as soon as they close: a copy of the file mid-recording keeps them."""
    w = write_sample_bag(tmp_path / "live", n=200, chunk_size=2048)
    snapshot = tmp_path / "killed"
    snapshot.mkdir()
    shutil.copy(w.mcap_path, snapshot / "run1_0.mcap")  # what a SIGKILL would leave on disk now
    written = w.message_count
    r = BagReader(snapshot)
    assert r.truncated
    lost = written - r.message_count
    # bound: the messages of the open chunk (<= chunk_size bytes of ~800-byte records)
    assert 0 <= lost <= 2048 // 100
    w.flush()
    shutil.copy(w.mcap_path, snapshot / "run1_0.mcap")
    assert BagReader(snapshot).message_count == written  # after flush() nothing is lost
    w.close()
    os.remove(snapshot / "run1_0.mcap")


# ------------------------------------------------------------------------------------------ gaps
def test_sequence_gaps_find_losses_head_losses_and_new_publishers():
    from bb2_tools.bagfile import SequenceGaps

    g = SequenceGaps()
    for k, seq in enumerate([1, 2, 3, 7, 8]):
        g.observe("/a", seq, k * 10**9, publish_time_ns=100 * 10**9 + k * 10**9)
    assert [(x.topic, x.missing, x.after_sequence, x.before_sequence) for x in g.gaps] == [("/a", 3, 3, 7)]
    assert g.gaps[0].after_log_s == 2.0 and g.gaps[0].before_log_s == 3.0 and g.gaps[0].duration_s == 1.0
    g.observe("/a", 1, 9 * 10**9)                  # a restarted publisher numbers from 1 again: not a loss
    g.observe("/a", 2, 10 * 10**9)
    g.observe("/a", 9, 11 * 10**9)                 # continues the first publisher's stream
    assert g.missing == 3
    g.observe("/b", 5, 0)                          # the first 4 of /b were never received
    assert g.gaps[-1].head and g.gaps[-1].missing == 4 and "first 4" in g.gaps[-1].describe()
    g.observe("/c", 0, 0)                          # 0: the middleware does not number samples
    g.observe("/c", 0, 1)
    # two publishers on one topic, told apart by their source: each numbered on its own
    for seq in (1, 2, 3):
        g.observe("/s", seq, seq, source="bb2/simulator")
        g.observe("/s", seq, seq, source="bb2/mixer")
    g.observe("/s", 6, 9, source="bb2/mixer")
    assert [(x.source, x.missing) for x in g.gaps if x.topic == "/s"] == [("bb2/mixer", 2)]
    assert g.missing == 3 + 4 + 2
    assert json.loads(g.to_json())[0]["missing"] == 3


def test_the_same_node_of_two_boats_on_diagnostics_is_two_publishers():
    """/diagnostics is global: the path_following nodes of /boat1 and /boat2 both publish status
    ``bb2/path_following``, each numbered from 1.  The namespace of the node that sent it (the status's hardware_id)
    tells them apart, so two boats interleaved lose nothing (they once read as a head gap of one publisher:
    the fleet's bag warned of a lost /diagnostics message); the root namespace's sources are the status names."""
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
    from rclpy.serialization import serialize_message

    from bb2_tools.bagfile import SequenceGaps, stream_source

    def cdr(hardware_id: str) -> bytes:
        return serialize_message(DiagnosticArray(status=[DiagnosticStatus(name="bb2/path_following",
                                                                          hardware_id=hardware_id)]))

    t = "diagnostic_msgs/msg/DiagnosticArray"
    assert stream_source(t, cdr("/path_following")) == "bb2/path_following"
    assert stream_source(t, cdr("/boat1/path_following")) == "boat1/bb2/path_following"
    assert stream_source(t, cdr("/fleet/boat2/path_following")) == "fleet/boat2/bb2/path_following"
    assert stream_source(t, cdr("bb2_rom")) == "bb2/path_following"
    g = SequenceGaps()
    for seq, boat in ((2, "boat2"), (1, "boat1"), (1, "boat2"), (2, "boat1"), (3, "boat2"), (3, "boat1")):
        g.observe("/diagnostics", seq, seq, stream_source(t, cdr(f"/{boat}/path_following")))
    assert [(x.source, x.missing) for x in g.gaps] == [("boat2/bb2/path_following", 1)]  # boat2's first: lost
    g = SequenceGaps()  # read as one publisher, the same stream had a gap
    for seq in (2, 1, 1, 2, 3, 3):
        g.observe("/diagnostics", seq, seq, "bb2/path_following")
    assert g.missing == 1


def test_gaps_are_written_with_the_sequence_numbers_and_survive_recovery(tmp_path):
    """A bag written with publication sequence numbers tells its gaps from them (bag_gaps), and recover keeps the
    numbers and writes the gaps into the recovered bag's metadata."""
    from bb2_tools.bagfile import GAPS_KEY, bag_gaps

    bag = tmp_path / "b"
    w = BagWriter(bag, chunk_size=256)
    w.add_topic("/bb2/mission/progress", "std_msgs/msg/Float64", dds_sequence=True)
    msg = message_class("std_msgs/msg/Float64")
    for k, seq in enumerate([1, 2, 5, 6]):
        w.write("/bb2/mission/progress", serialize_message(msg(data=float(k))), k * 10**9, sequence=seq)
    w.flush()
    del w  # never closed: the recorder was killed
    r = BagReader(bag)
    assert r.truncated and [m.sequence for m in r.raw_messages()] == [1, 2, 5, 6]
    assert [(g.missing, g.after_sequence) for g in bag_gaps(r)] == [(2, 2)]
    recover(bag)
    meta = bagfile.read_metadata(bag)
    assert json.loads(meta["custom_data"][GAPS_KEY])[0]["missing"] == 2
    assert [(g.missing, g.before_sequence) for g in bag_gaps(BagReader(bag))] == [(2, 5)]
    # a bag without publication sequence numbers cannot tell
    plain = tmp_path / "p"
    with BagWriter(plain) as w2:
        w2.add_topic("/bb2/mission/progress", "std_msgs/msg/Float64")
        w2.write("/bb2/mission/progress", serialize_message(msg(data=1.0)), 0)
    assert bag_gaps(BagReader(plain)) is None


def test_publication_counts_show_the_losses_sequence_numbers_cannot(tmp_path):
    """A writer whose last messages never reached the recorder leaves no gap in the sequence numbers; the
    publishers' counts (publication_counts.json beside the bag) show it: bag_gaps adds one ``unrecorded`` gap per
    topic, from its last recorded message to the end of the bag, and nothing where the counts add up (what the bag
    holds plus the gaps its numbers show).  A malformed count file is a BagError, not a silent pass."""
    from bb2_tools.bagfile import PUBLICATION_COUNTS_FILE, Gap, bag_gaps

    bag = tmp_path / "b"
    msg = message_class("std_msgs/msg/Float64")
    with BagWriter(bag) as w:
        for name in ("/a", "/b"):
            w.add_topic(name, "std_msgs/msg/Float64", dds_sequence=True)
        for k, seq in enumerate([1, 2, 3, 4]):           # /a: 4 received of 10 published (6 after the last)
            w.write("/a", serialize_message(msg(data=float(k))), k * 10**9, sequence=seq)
        for k, seq in enumerate([1, 2, 5, 6, 7, 8, 9]):  # /b: a gap of 2 the numbers show, nothing after
            w.write("/b", serialize_message(msg(data=float(k))), k * 10**9, sequence=seq)
    # without the counts: only /b's gap is seen
    assert [(g.topic, g.missing, g.kind) for g in bag_gaps(BagReader(bag))] == [("/b", 2, "gap")]
    (bag / PUBLICATION_COUNTS_FILE).write_text(json.dumps({"published": {"/a": 10, "/b": 9, "/c": 3}}))
    gaps = bag_gaps(BagReader(bag))
    unrec = {g.topic: g for g in gaps if g.unrecorded}
    assert sorted(unrec) == ["/a", "/c"], gaps          # /b adds up: 7 recorded + 2 in its gap
    a = unrec["/a"]
    assert (a.missing, a.after_sequence, a.before_sequence, a.after_log_s, a.before_log_s) == (6, 4, 10, 3.0, 6.0)
    assert not a.head and "6 of the 10 message(s) its publishers counted were never recorded" in a.describe()
    c = unrec["/c"]                                      # published, none of it recorded
    assert (c.missing, c.after_log_s) == (3, None) and "none was recorded" in c.describe()
    assert Gap(**json.loads(json.dumps(a.as_dict()))) == a  # survives the metadata's JSON
    assert [(g.topic, g.missing) for g in gaps if not g.unrecorded] == [("/b", 2)]
    (bag / PUBLICATION_COUNTS_FILE).write_text(json.dumps({"published": {"/a": "ten"}}))
    with pytest.raises(BagError, match="message counts"):
        bag_gaps(BagReader(bag))



def test_statuses_counted_by_nobody_do_not_hide_a_nodes_lost_statuses(tmp_path):
    """A SIGKILLed recorder leaves its own statuses in its (recovered) bag but no count: the launcher names it in
    ``uncounted_sources`` and bag_gaps leaves its messages out of the bag's side of /bb2/status, so the node's
    statuses lost after its last recorded one are found exactly; without that the recorder's would make up for
    them.  A malformed ``uncounted_sources`` is a BagError."""
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus

    from bb2_tools.bagfile import PUBLICATION_COUNTS_FILE, RECORDER_STATUS_NAME, bag_gaps

    def array(name, fqn):
        return serialize_message(DiagnosticArray(status=[DiagnosticStatus(name=name, hardware_id=fqn)]))

    bag = tmp_path / "b"
    with BagWriter(bag) as w:
        w.add_topic("/bb2/status", "diagnostic_msgs/msg/DiagnosticArray", dds_sequence=True)
        t = 0
        for seq in (1, 2, 3):  # the simulator published 6: the last 3 never reached the recorder
            w.write("/bb2/status", array("bb2/simulator", "/simulator"), t := t + 10**9, sequence=seq)
        for seq in (1, 2, 3, 4):  # the recorder's own, counted by nobody (it was killed)
            w.write("/bb2/status", array(RECORDER_STATUS_NAME, "/recorder"), t := t + 10**9, sequence=seq)
    counts = {"published": {"/bb2/status": 6}}
    (bag / PUBLICATION_COUNTS_FILE).write_text(json.dumps(counts))
    assert bag_gaps(BagReader(bag)) == []  # 7 in the bag >= 6 published: the loss is hidden
    (bag / PUBLICATION_COUNTS_FILE).write_text(json.dumps({**counts, "uncounted_sources": ["bb2/recorder"]}))
    (gap,) = bag_gaps(BagReader(bag))
    assert (gap.topic, gap.missing, gap.unrecorded) == ("/bb2/status", 3, True)
    assert (gap.after_sequence, gap.before_sequence, gap.after_log_s) == (3, 6, 3.0)  # after the simulator's last
    # another boat's recorder is another source: it does not stand for this one
    (bag / PUBLICATION_COUNTS_FILE).write_text(json.dumps({**counts, "uncounted_sources": ["boat1/bb2/recorder"]}))
    assert bag_gaps(BagReader(bag)) == []
    (bag / PUBLICATION_COUNTS_FILE).write_text(json.dumps({**counts, "uncounted_sources": "bb2/recorder"}))
    with pytest.raises(BagError, match="uncounted_sources"):
        bag_gaps(BagReader(bag))

def test_last_statuses_gives_each_nodes_last_status_by_name(tmp_path):
    """``BagReader.last_statuses``: each status name's key/values from the last array that carried it, whatever
    other nodes sent after it (the benchmarks and the graph tests read a run's final account this way)."""
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

    def array(*statuses):
        return serialize_message(DiagnosticArray(status=[DiagnosticStatus(
            name=name, values=[KeyValue(key=k, value=v) for k, v in vals.items()]) for name, vals in statuses]))

    w = BagWriter(tmp_path / "st")
    w.add_topic("/bb2/status", "diagnostic_msgs/msg/DiagnosticArray", offered_qos=[qos_entry()])
    w.add_topic("/diagnostics", "diagnostic_msgs/msg/DiagnosticArray", offered_qos=[qos_entry()])
    w.write("/bb2/status", array(("bb2/simulator", {"step": "1", "state": "running"})), 1)
    w.write("/bb2/status", array(("bb2/mixer", {"answered": "1"})), 2)
    w.write("/bb2/status", array(("bb2/simulator", {"step": "200"})), 3)  # the last one whole, not merged
    w.write("/bb2/status", array(("bb2/mixer", {"answered": "199"}), ("bb2/extra", {})), 4)
    w.write("/diagnostics", array(("bb2/simulator", {"step": "999"})), 5)
    w.close()
    r = BagReader(tmp_path / "st")
    assert r.last_statuses() == {"bb2/simulator": {"step": "200"}, "bb2/mixer": {"answered": "199"},
                                 "bb2/extra": {}}
    assert r.last_statuses("/diagnostics") == {"bb2/simulator": {"step": "999"}}
