"""rosbag2-compatible bag directories in MCAP: the one module that knows the format.

Layout written (what rosbag2 Jazzy with ``--storage mcap`` writes, so ``ros2 bag info/play`` and
Foxglove open it)::

    BAG_DIR/
      metadata.yaml          # rosbag2_bagfile_information, version 9
      BAG_DIR_0.mcap         # MCAP, profile "ros2"

MCAP content: one ``ros2msg`` schema per type, its text the type's ``.msg`` followed by every
dependency as rosbag2's message-definition cache concatenates them
(``\\n`` + 80 ``=`` + ``\\nMSG: pkg/Type\\n`` + text, depth first, each once); channels with message
encoding ``cdr`` and metadata ``offered_qos_profiles`` (YAML of the publishers' QoS, metadata v9
names) and ``topic_type_hash`` (RIHS01); zstd-compressed chunks with message indexes; a summary
with statistics; and a ``rosbag2`` metadata record holding ``serialized_metadata`` (the same
content as metadata.yaml), as rosbag2_storage_mcap writes it.

Type hashes come from the ``share/<pkg>/msg/<Type>.json`` type descriptions installed with the
messages; ``tf2_msgs/msg/TFMessage`` (not in the wheels here) has its definition and type
description embedded below and its hash computed with the RIHS01 algorithm.

Flush policy: the file is written unbuffered; a chunk reaches the OS as soon as it is closed
(``chunk_size`` bytes of messages, or :meth:`BagWriter.flush`).  A SIGKILL loses at most the open
chunk; :class:`BagReader` reads such a truncated file up to its last complete chunk
(``truncated=True``) and :func:`recover` rewrites it as a valid bag with a metadata.yaml.
"""
from __future__ import annotations

import copy
import dataclasses
import functools
import hashlib
import json
import os
import re
import struct
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Iterator, Sequence

import yaml
from mcap.exceptions import McapError
from mcap.records import Channel, Message, Schema
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer

from bb2_sim.yaml_files import load as load_yaml

__all__ = ["BagError", "BagWriter", "BagReader", "RawMessage", "TopicInfo", "message_definition",
           "type_hash", "qos_entry", "qos_yaml", "read_metadata", "recover", "Gap", "SequenceGaps", "bag_gaps",
           "PUBLICATION_COUNTS_FILE", "read_publication_counts", "unrecorded_losses",
           "RECORDER_STATUS_NAME", "PublicationCounts", "read_publication_count_file",
           "gaps_by_topic", "GAPS_KEY", "SEQUENCE_KEY", "METADATA_VERSION", "ROS_DISTRO"]

METADATA_VERSION = 9
ROS_DISTRO = "jazzy"
MCAP_MAGIC = b"\x89MCAP0\r\n"
SEPARATOR = "=" * 80 + "\n"
INFINITE_NS = 0x7FFFFFFFFFFFFFFF
"""rmw's RMW_DURATION_INFINITE in nanoseconds (sec 9223372036, nsec 854775807)."""


class BagError(ValueError):
    """A bag that cannot be written or read as asked (with what is wrong)."""


# ----------------------------------------------------------------------------------------- definitions
EMBEDDED_DEFINITIONS: dict[str, str] = {
    # tf2_msgs/msg/TFMessage.msg (ROS 2 Jazzy); the package is not in the wheels here.
    "tf2_msgs/TFMessage": "geometry_msgs/TransformStamped[] transforms\n",
}
_EMBEDDED_DESCRIPTIONS: dict[str, list[tuple[str, int, str]]] = {
    # type name -> fields (name, rosidl type_id, nested type); 145 = unbounded sequence of nested type
    "tf2_msgs/msg/TFMessage": [("transforms", 145, "geometry_msgs/msg/TransformStamped")],
}

_TYPENAME = re.compile(r"^([a-zA-Z][a-zA-Z0-9_]*)/(?:(msg|srv)/)?([a-zA-Z][a-zA-Z0-9_]*)$")
_MSG_FIELD_TYPE = re.compile(r"(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+")
_PRIMITIVES = {"bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16",
               "int32", "uint32", "int64", "uint64", "string"}


def _split_type(type_name: str) -> tuple[str, str]:
    m = _TYPENAME.match(type_name)
    if not m:
        raise BagError(f"not a ROS message type name 'pkg/msg/Type': {type_name!r}")
    return m.group(1), m.group(3)


def _share_dirs() -> list[Path]:
    prefixes = [p for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    import sys

    prefixes.append(sys.prefix)  # the venv itself holds share/<pkg>/msg here
    return [Path(p) / "share" for p in prefixes]


def _find_share_file(pkg: str, name: str, ext: str) -> Path | None:
    for share in _share_dirs():
        f = share / pkg / "msg" / f"{name}{ext}"
        if f.is_file():
            return f
    return None


def _msg_text(pkg: str, name: str) -> str:
    key = f"{pkg}/{name}"
    if key in EMBEDDED_DEFINITIONS:
        return EMBEDDED_DEFINITIONS[key]
    f = _find_share_file(pkg, name, ".msg")
    if f is None:
        raise BagError(f"no .msg definition for {key} under AMENT_PREFIX_PATH share/{pkg}/msg "
                       f"(set AMENT_PREFIX_PATH to the ROS/venv prefix)")
    return f.read_text(encoding="utf-8")


def _dependencies(text: str, package: str) -> list[str]:
    deps = set()
    for m in _MSG_FIELD_TYPE.finditer(text):
        t = m.group(1)
        if t in _PRIMITIVES:
            continue
        deps.add(t if "/" in t else f"{package}/{t}")
    return sorted(deps)  # std::set order, as rosbag2


def message_definition(type_name: str) -> str:
    """The ``ros2msg`` schema text of a type, dependencies concatenated as rosbag2 does."""
    seen: set[str] = set()

    def append(pkg_type: str, depth: int) -> str:
        if depth <= 0:
            raise BagError(f"definition of {type_name} nests too deep")
        pkg, name = _split_type(pkg_type)
        text = _msg_text(pkg, name)
        out = text
        for dep in _dependencies(text, pkg):
            if dep not in seen:
                seen.add(dep)
                out += "\n" + SEPARATOR + f"MSG: {dep}\n" + append(dep, depth - 1)
        return out

    return append(type_name, 50)


def _rihs01(type_description_msg: dict[str, Any]) -> str:
    """RIHS01 hash of a TypeDescription (rosidl_generator_type_description's algorithm)."""
    d = copy.deepcopy(type_description_msg)
    for f in d["type_description"]["fields"]:
        f.pop("default_value", None)
    for ref in d["referenced_type_descriptions"]:
        for f in ref["fields"]:
            f.pop("default_value", None)
    text = json.dumps(d, ensure_ascii=True, allow_nan=False, indent=None, separators=(", ", ": "),
                      sort_keys=False)
    return "RIHS01_" + hashlib.sha256(text.encode("utf-8")).hexdigest()


def _type_description(type_name: str) -> dict[str, Any]:
    pkg, name = _split_type(type_name)
    full = f"{pkg}/msg/{name}"
    if full in _EMBEDDED_DESCRIPTIONS:
        fields = _EMBEDDED_DESCRIPTIONS[full]
        refs: dict[str, dict] = {}
        for _, _, nested in fields:
            if nested:
                sub = _type_description(nested)
                refs[nested] = sub["type_description"]
                for r in sub["referenced_type_descriptions"]:
                    refs[r["type_name"]] = r
        return {
            "type_description": {"type_name": full, "fields": [
                {"name": n, "type": {"type_id": tid, "capacity": 0, "string_capacity": 0,
                                     "nested_type_name": nested}, "default_value": ""}
                for n, tid, nested in fields]},
            "referenced_type_descriptions": [refs[k] for k in sorted(refs)],
        }
    f = _find_share_file(pkg, name, ".json")
    if f is None:
        raise BagError(f"no type description {pkg}/msg/{name}.json under AMENT_PREFIX_PATH")
    return json.loads(f.read_text(encoding="utf-8"))["type_description_msg"]


def type_hash(type_name: str) -> str:
    """The RIHS01 type hash of a message type (``""`` if no type description is installed)."""
    try:
        return _rihs01(_type_description(type_name))
    except BagError:
        return ""


# ----------------------------------------------------------------------------------------- QoS
def _duration(ns: int) -> dict[str, int]:
    return {"sec": int(ns) // 1_000_000_000, "nsec": int(ns) % 1_000_000_000}


def qos_entry(*, reliability: str = "reliable", durability: str = "volatile", history: str = "unknown",
              depth: int = 0, deadline_ns: int = INFINITE_NS, lifespan_ns: int = INFINITE_NS,
              liveliness: str = "automatic", liveliness_lease_duration_ns: int = INFINITE_NS,
              avoid_ros_namespace_conventions: bool = False) -> dict[str, Any]:
    """One offered QoS profile as rosbag2 metadata version 9 writes it.

    The defaults are what rosbag2 Jazzy records for a discovered publisher with default QoS
    (history unknown and depth 0 because discovery does not carry them; infinite durations).
    """
    names = {"reliability": ("reliable", "best_effort", "system_default", "best_available", "unknown"),
             "durability": ("volatile", "transient_local", "system_default", "best_available", "unknown"),
             "history": ("keep_last", "keep_all", "system_default", "unknown"),
             "liveliness": ("automatic", "manual_by_topic", "system_default", "best_available", "unknown")}
    for key, value in (("reliability", reliability), ("durability", durability), ("history", history),
                       ("liveliness", liveliness)):
        if value not in names[key]:
            raise BagError(f"QoS {key} must be one of {names[key]}, got {value!r}")
    return {"history": history, "depth": int(depth), "reliability": reliability, "durability": durability,
            "deadline": _duration(deadline_ns), "lifespan": _duration(lifespan_ns), "liveliness": liveliness,
            "liveliness_lease_duration": _duration(liveliness_lease_duration_ns),
            "avoid_ros_namespace_conventions": bool(avoid_ros_namespace_conventions)}


def qos_yaml(profiles: list[dict[str, Any]]) -> str:
    """The ``offered_qos_profiles`` channel-metadata string (YAML sequence, as rosbag2 dumps it)."""
    if not profiles:
        return ""
    return yaml.safe_dump(list(profiles), default_flow_style=False, sort_keys=False)


# ----------------------------------------------------------------------------------------- writer
@dataclass
class TopicInfo:
    """A topic of a bag: name, type, offered QoS (list of v9 dicts), type hash, message count."""

    name: str
    type: str
    offered_qos: list[dict[str, Any]] = field(default_factory=list)
    type_hash: str = ""
    message_count: int = 0
    serialization_format: str = "cdr"
    #: the MCAP sequence numbers of its messages are DDS publication sequence numbers (channel metadata
    #: ``bb2_sequence``): gaps in them are lost messages (:func:`bag_gaps`)
    dds_sequence: bool = False


class _UnbufferedSink:
    """A write/tell stream that hands every write to the OS at once (SIGKILL-safe per chunk)."""

    def __init__(self, path: Path):
        self._f = open(path, "wb", buffering=0)
        self._pos = 0

    def write(self, data: bytes) -> int:
        view = memoryview(data)
        while view:
            n = self._f.write(view)
            view = view[n:]
        self._pos += len(data)
        return len(data)

    def tell(self) -> int:
        return self._pos

    def flush(self) -> None:
        pass

    def fsync(self) -> None:
        os.fsync(self._f.fileno())

    def close(self) -> None:
        self._f.close()


def _metadata_dict(*, file_name: str, topics: Iterable[TopicInfo], start_ns: int, end_ns: int,
                   message_count: int, custom_data: dict[str, str] | None) -> dict[str, Any]:
    """The BagMetadata node (without the ``rosbag2_bagfile_information`` key)."""
    duration = max(0, end_ns - start_ns) if message_count else 0
    start = start_ns if message_count else 0
    return {
        "version": METADATA_VERSION,
        "storage_identifier": "mcap",
        "duration": {"nanoseconds": duration},
        "starting_time": {"nanoseconds_since_epoch": start},
        "message_count": message_count,
        "topics_with_message_count": [
            {"topic_metadata": {"name": t.name, "type": t.type,
                                "serialization_format": t.serialization_format,
                                "offered_qos_profiles": list(t.offered_qos),
                                "type_description_hash": t.type_hash},
             "message_count": t.message_count}
            for t in topics],
        "compression_format": "",
        "compression_mode": "",
        "relative_file_paths": [file_name],
        "files": [{"path": file_name, "starting_time": {"nanoseconds_since_epoch": start},
                   "duration": {"nanoseconds": duration}, "message_count": message_count}],
        "custom_data": dict(custom_data) if custom_data else None,  # rosbag2 writes `~` when empty
        "ros_distro": ROS_DISTRO,
    }


class BagWriter:
    """Write a rosbag2 bag directory (storage mcap) from raw CDR messages.

    >>> with BagWriter("bags/run1") as bag:                                # doctest: +SKIP
    ...     bag.add_topic("/bb2/odom", "nav_msgs/msg/Odometry", offered_qos=[qos_entry()])
    ...     bag.write("/bb2/odom", cdr_bytes, log_time_ns=t_ns)

    ``chunk_size``: uncompressed bytes per chunk (the most a SIGKILL can lose).
    ``compression``: ``"zstd"`` (default), ``"lz4"`` or ``""``.
    """

    def __init__(self, bag_dir: str | os.PathLike, *, chunk_size: int = 256 * 1024,
                 compression: str = "zstd", custom_data: dict[str, str] | None = None,
                 overwrite: bool = False):
        self.bag_dir = Path(bag_dir)
        if chunk_size <= 0:
            raise BagError(f"chunk_size must be > 0 bytes, got {chunk_size}")
        comp = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "": CompressionType.NONE}
        if compression not in comp:
            raise BagError(f"compression must be one of {list(comp)}, got {compression!r}")
        if self.bag_dir.exists():
            if not overwrite and any(self.bag_dir.iterdir()):
                raise BagError(f"bag directory {self.bag_dir} exists and is not empty")
        self.bag_dir.mkdir(parents=True, exist_ok=True)
        self.file_name = f"{self.bag_dir.name}_0.mcap"
        self.mcap_path = self.bag_dir / self.file_name
        self._sink = _UnbufferedSink(self.mcap_path)
        self._writer = Writer(self._sink, chunk_size=chunk_size, compression=comp[compression])
        self._writer.start(profile="ros2", library="bb2_tools.bagfile (mcap python)")
        self.custom_data = dict(custom_data or {})
        self.topics: dict[str, TopicInfo] = {}
        self._channel_ids: dict[str, int] = {}
        self._schema_ids: dict[str, int] = {}
        self._encoders: dict[str, Any] = {}
        self._message_count = 0
        self._start_ns: int | None = None
        self._end_ns = 0
        self._closed = False

    def __enter__(self) -> "BagWriter":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def add_topic(self, name: str, type_name: str, *, offered_qos: list[dict[str, Any]] | None = None,
                  type_description_hash: str | None = None, definition: str | None = None,
                  dds_sequence: bool = False) -> int:
        """Register a topic (idempotent for the same type); returns its MCAP channel id.  ``dds_sequence``: the
        messages will be written with their DDS publication sequence numbers (said in the channel metadata)."""
        self._check_open()
        if name in self.topics:
            if self.topics[name].type != type_name:
                raise BagError(f"topic {name} already recorded as {self.topics[name].type}, not {type_name}")
            return self._channel_ids[name]
        _split_type(type_name)
        if type_name not in self._schema_ids:
            text = message_definition(type_name) if definition is None else definition
            self._schema_ids[type_name] = self._writer.register_schema(
                name=type_name, encoding="ros2msg", data=text.encode("utf-8"))
        h = type_hash(type_name) if type_description_hash is None else type_description_hash
        info = TopicInfo(name, type_name, list(offered_qos or []), h, dds_sequence=bool(dds_sequence))
        meta = {"offered_qos_profiles": qos_yaml(info.offered_qos), "topic_type_hash": h}
        if dds_sequence:
            meta[SEQUENCE_KEY] = SEQUENCE_DDS
        self._channel_ids[name] = self._writer.register_channel(
            topic=name, message_encoding="cdr", schema_id=self._schema_ids[type_name], metadata=meta)
        self.topics[name] = info
        return self._channel_ids[name]

    def write(self, topic: str, data: bytes, log_time_ns: int, publish_time_ns: int | None = None,
              sequence: int | None = None) -> None:
        """Append one serialized (CDR) message; ``log_time_ns`` is the receive time (rosbag2).

        ``sequence``: the MCAP message sequence number, the DDS publication sequence number of the sample
        when the recorder knows it (modulo 2**32; what :func:`bag_gaps` reads gaps from), else the message's
        index on its channel."""
        self._check_open()
        if topic not in self._channel_ids:
            raise BagError(f"topic {topic!r} was not added to the bag (add_topic first)")
        if log_time_ns < 0:
            raise BagError(f"log time must be >= 0 ns, got {log_time_ns}")
        info = self.topics[topic]
        self._writer.add_message(channel_id=self._channel_ids[topic], log_time=int(log_time_ns),
                                 data=bytes(data),
                                 sequence=info.message_count if sequence is None else int(sequence) & 0xFFFFFFFF,
                                 publish_time=int(log_time_ns if publish_time_ns is None else publish_time_ns))
        info.message_count += 1
        self._message_count += 1
        self._start_ns = log_time_ns if self._start_ns is None else min(self._start_ns, log_time_ns)
        self._end_ns = max(self._end_ns, log_time_ns)

    def write_dict(self, topic: str, message: dict[str, Any], log_time_ns: int,
                   publish_time_ns: int | None = None) -> None:
        """Encode ``message`` (nested dicts/lists) with mcap_ros2's dynamic CDR encoder and write it.

        For types whose Python package is not installed (``tf2_msgs/msg/TFMessage``).
        """
        from mcap_ros2._dynamic import serialize_dynamic

        type_name = self.topics[topic].type if topic in self.topics else None
        if type_name is None:
            raise BagError(f"topic {topic!r} was not added to the bag (add_topic first)")
        if type_name not in self._encoders:
            self._encoders[type_name] = serialize_dynamic(type_name, message_definition(type_name))[type_name]
        self.write(topic, self._encoders[type_name](message), log_time_ns, publish_time_ns)

    @property
    def message_count(self) -> int:
        return self._message_count

    @property
    def bytes_written(self) -> int:
        """Bytes handed to the OS so far (closed chunks; the open chunk is still in memory)."""
        return self._sink.tell()

    def flush(self) -> None:
        """Close the open chunk and hand it to the OS (a later SIGKILL cannot lose it)."""
        self._check_open()
        self._writer.flush()

    def metadata(self) -> dict[str, Any]:
        """The BagMetadata of what was written so far."""
        return _metadata_dict(file_name=self.file_name, topics=self.topics.values(),
                              start_ns=self._start_ns or 0, end_ns=self._end_ns,
                              message_count=self._message_count, custom_data=self.custom_data)

    def close(self) -> Path:
        """Write the summary, the ``rosbag2`` metadata record and metadata.yaml; returns the bag dir."""
        if self._closed:
            return self.bag_dir
        meta = self.metadata()
        self._writer.add_metadata("rosbag2", {"serialized_metadata": yaml.safe_dump(meta, sort_keys=False)})
        self._writer.finish()
        self._sink.fsync()
        self._sink.close()
        self._closed = True
        write_metadata_yaml(self.bag_dir, meta)
        return self.bag_dir

    def _check_open(self) -> None:
        if self._closed:
            raise BagError(f"bag {self.bag_dir} is closed")


def write_metadata_yaml(bag_dir: str | os.PathLike, meta: dict[str, Any]) -> Path:
    """Write ``metadata.yaml`` (atomically) from a BagMetadata dict."""
    path = Path(bag_dir) / "metadata.yaml"
    tmp = path.with_suffix(".yaml.tmp")
    tmp.write_text(yaml.safe_dump({"rosbag2_bagfile_information": meta}, sort_keys=False,
                                  default_flow_style=False), encoding="utf-8")
    os.replace(tmp, path)
    return path


def read_metadata(bag_dir: str | os.PathLike) -> dict[str, Any]:
    """The ``rosbag2_bagfile_information`` of a bag directory's metadata.yaml."""
    path = Path(bag_dir) / "metadata.yaml"
    try:
        doc = load_yaml(path.read_text(encoding="utf-8"))
        return doc["rosbag2_bagfile_information"]
    except UnicodeDecodeError as exc:
        raise BagError(f"cannot read {path}: not valid UTF-8 text (byte {exc.start})") from None
    except (OSError, yaml.YAMLError, KeyError, TypeError) as exc:
        raise BagError(f"cannot read {path}: {exc}") from None


# ----------------------------------------------------------------------------------------- reader
@dataclass(frozen=True)
class RawMessage:
    """One serialized message of a bag."""

    topic: str
    log_time_ns: int
    publish_time_ns: int
    data: bytes
    type: str
    sequence: int = 0  #: the MCAP sequence number (our recorder: the DDS publication sequence number)


class BagReader:
    """Read a bag directory (metadata.yaml + .mcap) or a bare .mcap file, complete or truncated.

    A file without a valid footer and summary (the recorder was killed) is read linearly up to its
    last complete chunk; :attr:`truncated` is then ``True`` and :attr:`problem` says what ended it.

    A fleet's bag (one recorder for several boats: ``/boat1/bb2/odom``, ``/boat2/bb2/odom``, one ``/tf``) is read
    one boat at a time with ``vehicle``: its topics under the contract's names (``/bb2/odom``), beside the bag's
    global ones (``/tf``, ``/tf_static``, ``/diagnostics``), the other boats' left out; :attr:`vehicles` lists them.
    """

    def __init__(self, path: str | os.PathLike, vehicle: str | None = None):
        p = Path(path)
        self.metadata: dict[str, Any] | None = None
        if p.is_dir():
            if (p / "metadata.yaml").is_file():
                self.metadata = read_metadata(p)
                files = [p / f for f in self.metadata.get("relative_file_paths", [])]
            else:
                files = sorted(p.glob("*.mcap"))
            files = [f for f in files if f.is_file()]
            if len(files) != 1:
                raise BagError(f"{p}: expected one .mcap file, found {[f.name for f in files]}")
            self.mcap_path = files[0]
        elif p.is_file():
            self.mcap_path = p
        else:
            raise BagError(f"no bag at {p}")
        self.truncated = False
        self.problem = ""
        self._schemas: dict[int, Schema] = {}
        self._channels: dict[int, Channel] = {}
        self._counts: dict[int, int] = {}
        self._summary = None
        self._scan_structure()
        self.vehicle = ""
        self._real: dict[str, str] = {}  # a vehicle's view: its topic name -> the name in the bag
        out = set()
        for c in self._channels.values():
            for t in ("/bb2/state_native", "/bb2/odom"):
                if c.topic.endswith(t) and len(c.topic) > len(t) + 1:
                    out.add(c.topic[:-len(t)].strip("/"))
        self.vehicles: list[str] = sorted(out)
        """The boats of a fleet's bag (namespaces with a ``/NS/bb2/state_native`` or ``/NS/bb2/odom``), sorted; ``[]``
        for a one-boat bag."""
        if vehicle is not None and vehicle.strip("/"):
            self._view(vehicle.strip("/"))

    def _view(self, vehicle: str) -> None:
        """Keep ``vehicle``'s channels (renamed to the contract's names) and the global ones."""
        others = [f"/{v}/" for v in self.vehicles]
        if f"/{vehicle}/" not in others:
            raise BagError(f"{self.mcap_path}: no vehicle {vehicle!r} in the bag (it has {self.vehicles or 'none'})")
        self.vehicle = vehicle
        view: dict[int, Channel] = {}
        for cid, c in self._channels.items():
            if c.topic.startswith(f"/{vehicle}/"):
                name = c.topic[len(vehicle) + 1:]
                self._real[name] = c.topic
                view[cid] = dataclasses.replace(c, topic=name)
            elif not any(c.topic.startswith(o) for o in others):
                view[cid] = c
        self._channels = view

    def view_topic(self, bag_topic: str) -> str | None:
        """The name a topic of the bag has in this reader (None: another boat's)."""
        if not self.vehicle:
            return bag_topic
        if bag_topic.startswith(f"/{self.vehicle}/"):
            return bag_topic[len(self.vehicle) + 1:]
        return None if any(bag_topic.startswith(f"/{v}/") for v in self.vehicles) else bag_topic

    # -- structure
    def _scan_structure(self) -> None:
        from mcap.reader import make_reader

        with open(self.mcap_path, "rb") as f:
            head = f.read(len(MCAP_MAGIC))
            if head != MCAP_MAGIC[:len(head)] or not head:  # (a recorder killed at once may leave part of it)
                raise BagError(f"{self.mcap_path}: " + ("an empty file (0 bytes): nothing was recorded" if not head
                               else "not an MCAP file (it does not begin with the MCAP magic bytes)"))
            f.seek(0, os.SEEK_END)
            size = f.tell()
            if size >= 8:
                f.seek(size - 8)
                complete = f.read(8) == MCAP_MAGIC
            else:
                complete = False
            summary = None
            if complete:
                f.seek(0)
                try:
                    summary = make_reader(f).get_summary()
                except (McapError, struct.error, ValueError, EOFError) as exc:
                    complete, self.problem = False, f"unreadable summary: {exc}"
        if complete and summary is not None and summary.statistics is not None:
            self._summary = summary
            self._schemas = dict(summary.schemas)
            self._channels = dict(summary.channels)
            self._counts = dict(summary.statistics.channel_message_counts)
            return
        # linear scan: schemas, channels and counts of every complete chunk
        self.truncated = not complete
        for rec in self._linear_records():
            if isinstance(rec, Schema):
                self._schemas[rec.id] = rec
            elif isinstance(rec, Channel):
                self._channels[rec.id] = rec
            elif isinstance(rec, Message):
                self._counts[rec.channel_id] = self._counts.get(rec.channel_id, 0) + 1

    def _linear_records(self) -> Iterator[Any]:
        with open(self.mcap_path, "rb") as f:
            try:
                for rec in StreamReader(f, emit_chunks=False).records:
                    yield rec
            except (McapError, struct.error, ValueError, EOFError, MemoryError) as exc:
                self.truncated = True
                self.problem = self.problem or f"file ends inside a record ({type(exc).__name__}: {exc})"

    @property
    def topics(self) -> dict[str, str]:
        """Topic name -> type name."""
        return {c.topic: self._schemas[c.schema_id].name if c.schema_id in self._schemas else ""
                for c in self._channels.values()}

    @property
    def message_counts(self) -> dict[str, int]:
        """Topic name -> number of (readable) messages."""
        out: dict[str, int] = {}
        for cid, c in self._channels.items():
            out[c.topic] = out.get(c.topic, 0) + self._counts.get(cid, 0)
        return out

    @property
    def message_count(self) -> int:
        return sum(self._counts.values())

    def end_time_ns(self) -> int:
        """The last log time of the bag (0 when it holds no message)."""
        if self._summary is not None and self._summary.statistics is not None:
            return int(self._summary.statistics.message_end_time) if self.message_count else 0
        return max((m.log_time_ns for m in self.raw_messages(file_order=True)), default=0)

    def topic_infos(self) -> list[TopicInfo]:
        """Topics with their offered QoS and type hash from the channel metadata."""
        out = []
        for cid, c in self._channels.items():
            qos_text = c.metadata.get("offered_qos_profiles", "")
            qos = load_yaml(qos_text) if qos_text else []
            out.append(TopicInfo(c.topic, self.topics[c.topic], list(qos or []),
                                 c.metadata.get("topic_type_hash", ""), self._counts.get(cid, 0),
                                 c.message_encoding, c.metadata.get(SEQUENCE_KEY) == SEQUENCE_DDS))
        return out

    def vehicle_frame_prefix(self) -> str:
        """The prefix of the recorded vehicle's frame ids (``""``; ``"boat1/"`` for a boat of a fleet): from the
        first ``/bb2/odom`` (its child frame) or ``/bb2/planes/state`` (its frame), ``""`` without either.  Its
        commands and odometry are read against ``<prefix>base_link`` (:meth:`vehicle_base_link`)."""
        from bb2_msgs_py.contract import FRAME_BASE_LINK

        for topic in ("/bb2/odom", "/bb2/planes/state"):
            if self.message_counts.get(topic, 0):
                _t, _log, msg = next(iter(self.messages(topic)))
                frame = msg.child_frame_id if topic == "/bb2/odom" else msg.header.frame_id
                if frame.endswith(FRAME_BASE_LINK):
                    return frame.removesuffix(FRAME_BASE_LINK)
        return ""

    def vehicle_base_link(self) -> str:
        """The recorded vehicle's body frame: ``base_link``, ``boat1/base_link`` in a fleet boat's bag."""
        from bb2_msgs_py.contract import FRAME_BASE_LINK

        return self.vehicle_frame_prefix() + FRAME_BASE_LINK

    # -- messages
    def _select(self, topics: Iterable[str] | str | None) -> set[str] | None:
        if topics is None:
            return None
        sel = {topics} if isinstance(topics, str) else set(topics)
        unknown = sel - set(self.topics)
        if unknown:
            raise BagError(f"topics not in the bag: {sorted(unknown)} (bag has {sorted(self.topics)})")
        return {self._real.get(t, t) for t in sel}

    def _selected(self, sel: set[str] | None) -> set[str] | None:
        """What to read of the file: ``sel`` (names in the bag), or every channel of this reader's view."""
        if sel is None and self.vehicle:
            return {self._real.get(c.topic, c.topic) for c in self._channels.values()}
        return sel

    def raw_messages(self, topics: Iterable[str] | str | None = None, *,
                     file_order: bool = False) -> Iterator[RawMessage]:
        """Serialized messages (log-time order for a complete bag unless ``file_order``, the order they were
        written in; file order for a truncated one)."""
        sel = self._selected(self._select(topics))
        name = self.view_topic
        if self._summary is not None:
            from mcap.reader import make_reader

            with open(self.mcap_path, "rb") as f:
                for schema, channel, msg in make_reader(f).iter_messages(
                        topics=None if sel is None else sorted(sel), log_time_order=not file_order):
                    yield RawMessage(name(channel.topic), msg.log_time, msg.publish_time, msg.data,
                                     schema.name if schema else "", msg.sequence)
            return
        channels: dict[int, Channel] = {}
        schemas: dict[int, Schema] = {}
        for rec in self._linear_records():
            if isinstance(rec, Schema):
                schemas[rec.id] = rec
            elif isinstance(rec, Channel):
                channels[rec.id] = rec
            elif isinstance(rec, Message):
                ch = channels.get(rec.channel_id)
                if ch is None or (sel is not None and ch.topic not in sel):
                    continue
                sc = schemas.get(ch.schema_id)
                yield RawMessage(name(ch.topic), rec.log_time, rec.publish_time, rec.data, sc.name if sc else "",
                                 rec.sequence)

    def messages(self, topics: Iterable[str] | str | None = None) -> Iterator[tuple[str, int, Any]]:
        """``(topic, log_time_ns, decoded message)`` decoded with mcap_ros2 (dynamic classes)."""
        for m, msg in self.decoded_messages(topics):
            yield m.topic, m.log_time_ns, msg

    def last_statuses(self, topic: str = "/bb2/status") -> dict[str, dict[str, str]]:
        """Each node's last status on ``topic`` (``diagnostic_msgs/DiagnosticArray``): status name -> its key/values
        (a node's statuses come in the order it sent them: one writer, one reader)."""
        return {st.name: {kv.key: kv.value for kv in st.values} for _t, _lt, msg in self.messages(topic)
                for st in msg.status}

    def decoded_messages(self, topics: Iterable[str] | str | None = None) -> Iterator[tuple[RawMessage, Any]]:
        """``(raw message, decoded message)``: with the publication time (our recorder's: the DDS source
        timestamp) and sequence number the decoded message lacks."""
        from mcap_ros2.decoder import DecoderFactory

        factory = DecoderFactory()
        decoders: dict[str, Any] = {}
        schemas_by_name = {s.name: s for s in self._schemas.values()}
        for m in self.raw_messages(topics):
            dec = decoders.get(m.type)
            if dec is None:
                schema = schemas_by_name.get(m.type)
                if schema is None:
                    raise BagError(f"no schema for type {m.type!r} of topic {m.topic}")
                dec = decoders[m.type] = factory.decoder_for("cdr", schema)
            yield m, dec(m.data)


# ----------------------------------------------------------------------------------------- recovery
@dataclass(frozen=True)
class RecoveryReport:
    """What :func:`recover` did."""

    bag_dir: Path
    was_truncated: bool
    message_count: int
    message_counts: dict[str, int]
    problem: str


def recover(path: str | os.PathLike, out_dir: str | os.PathLike | None = None, *,
            chunk_size: int = 1024 * 1024) -> RecoveryReport:
    """Rewrite a (possibly truncated) bag as a valid bag directory with summary and metadata.yaml.

    ``path``: a bag directory or .mcap.  ``out_dir``: where to write; ``None`` rewrites in place
    (the original file is replaced only after the new one is complete).  Every message of every
    complete chunk is kept, with its channel's QoS and type hash.
    """
    src = BagReader(path)
    in_place = out_dir is None
    if in_place and not Path(path).is_dir():
        raise BagError(f"{path} is a bare .mcap: give out_dir to write a recovered bag directory")
    src_dir = Path(path) if Path(path).is_dir() else Path(path).parent
    target = Path(out_dir) if out_dir is not None else src_dir.with_name(src_dir.name + ".recovering")
    custom = dict((src.metadata or {}).get("custom_data") or {})  # None (`~`) when empty
    with BagWriter(target, chunk_size=chunk_size, custom_data=custom) as w:
        if in_place:
            w.file_name = src.mcap_path.name  # keep the original file name in metadata.yaml
        infos = {t.name: t for t in src.topic_infos()}
        definitions = {s.name: s.data.decode("utf-8") for s in src._schemas.values()}
        for t in infos.values():
            w.add_topic(t.name, t.type, offered_qos=t.offered_qos, type_description_hash=t.type_hash,
                        definition=definitions.get(t.type), dds_sequence=t.dds_sequence)
        # the recorder's gaps were lost with its metadata: found again from the sequence numbers, in the same pass
        gaps = SequenceGaps() if GAPS_KEY not in custom and any(t.dds_sequence for t in infos.values()) else None
        for m in src.raw_messages(file_order=True):
            w.write(m.topic, m.data, m.log_time_ns, m.publish_time_ns, sequence=m.sequence)
            if gaps is not None and infos[m.topic].dds_sequence:
                gaps.observe_message(m)
        if gaps is not None:
            w.custom_data[GAPS_KEY] = gaps.to_json()
    result_dir = target
    if in_place:
        os.replace(w.mcap_path, src.mcap_path)
        write_metadata_yaml(src_dir, w.metadata())
        (target / "metadata.yaml").unlink(missing_ok=True)
        target.rmdir()
        result_dir = src_dir
    return RecoveryReport(result_dir, src.truncated, w.message_count,
                          {n: t.message_count for n, t in w.topics.items()}, src.problem)


# ----------------------------------------------------------------------------------------- gaps
GAPS_KEY = "bb2_gaps"
"""``custom_data`` key of the gaps a recording has (JSON list of :class:`Gap` dicts; "[]": none)."""
SEQUENCE_KEY = "bb2_sequence"
"""Channel metadata key saying what the channel's MCAP message sequence numbers are (:data:`SEQUENCE_DDS`)."""
SEQUENCE_DDS = "dds_publication_sequence_number"


@dataclass(frozen=True)
class Gap:
    """Messages of a topic that the publisher sent and the bag does not hold: the publication sequence numbers
    ``after_sequence`` and ``before_sequence`` were received, the ``missing`` ones between them were not
    (``after_sequence`` 0: the first ones the publisher sent, before the first one recorded).  Times are the
    bag's log times (receive times: sim time with ``use_sim_time``; a stalled recorder logs its backlog at the time
    it resumes) and publish times (the DDS source timestamps, wall clock) of the two received messages, s (None
    before a head gap).  ``source``: the publisher, where a topic has several (the status name of a
    ``/bb2/status``), else ''.

    ``kind`` ``"unrecorded"``: messages the publishers counted (:data:`PUBLICATION_COUNTS_FILE`) that are neither in
    the bag nor in a gap its sequence numbers show -- lost after the last message recorded (a writer gone silent
    towards the recorder, a recorder stopped early or killed); ``after_*`` is the last recorded message of the
    topic (0 / None: none recorded), ``before_sequence`` the number of messages published, ``before_log_s`` the
    bag's last log time."""

    topic: str
    missing: int
    after_sequence: int
    before_sequence: int
    after_log_s: float | None
    before_log_s: float
    source: str = ""
    after_publish_s: float | None = None
    before_publish_s: float | None = None
    kind: str = "gap"

    @property
    def head(self) -> bool:
        """Lost before the first message recorded (the publisher started before the recorder matched it)."""
        return self.after_sequence == 0 and not self.unrecorded

    @property
    def unrecorded(self) -> bool:
        """Counted by the publishers, placed by no sequence number (see the class)."""
        return self.kind == UNRECORDED

    @property
    def duration_s(self) -> float:
        """Wall seconds between the publication of the messages either side (0 for a head gap)."""
        if self.after_publish_s is None or self.before_publish_s is None:
            return 0.0
        return self.before_publish_s - self.after_publish_s

    def as_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    def describe(self) -> str:
        who = f" (from {self.source})" if self.source else ""
        if self.unrecorded:
            last = ("none was recorded" if self.after_log_s is None else
                    f"the last recorded at log time {self.after_log_s:.3f} s")
            return (f"{self.topic}: {self.missing} of the {self.before_sequence} message(s) its publishers counted "
                    f"were never recorded and no later message shows the gap ({last}; the bag ends at "
                    f"{self.before_log_s:.3f} s)")
        if self.head:
            return (f"{self.topic}{who}: the first {self.missing} message(s) published were not recorded (the first "
                    f"recorded, publication sequence number {self.before_sequence}, at log time "
                    f"{self.before_log_s:.3f} s)")
        return (f"{self.topic}{who}: {self.missing} message(s) missing between log times {self.after_log_s:.3f} s "
                f"and {self.before_log_s:.3f} s (published over {self.duration_s:.3f} s of wall time; publication "
                f"sequence numbers {self.after_sequence + 1}..{self.before_sequence - 1})")


UNRECORDED = "unrecorded"  # Gap.kind of a loss found from the publishers' counts

PUBLICATION_COUNTS_FILE = "publication_counts.json"
"""In a bag directory: the messages the graph's node processes published per topic, counted by each process as it
exited (``{"published": {topic: n}, "processes": [...], "uncounted": [...], "uncounted_sources": [...]}``,
written by ``bb2-launch``).  :func:`bag_gaps` compares them with the bag: what the bag holds plus what its sequence
numbers show lost must add up to what was published.  ``uncounted_sources`` (optional) names the publishers
(:func:`stream_source`) of :data:`MULTI_PUBLISHER_TYPES` topics whose messages are in the bag but in no count (a
SIGKILLed recorder's own statuses): they are left out of the bag's side."""

RECORDER_STATUS_NAME = "bb2/recorder"
"""The recorder's own status name on ``bb2/status`` and ``/diagnostics`` (its statuses come back into its bag)."""


@dataclasses.dataclass(frozen=True)
class PublicationCounts:
    """:data:`PUBLICATION_COUNTS_FILE`'s figures: ``published`` per topic, and the ``uncounted_sources`` whose
    messages in the bag are in no count."""

    published: dict[str, int]
    uncounted_sources: tuple[str, ...] = ()


def read_publication_counts(bag_dir: Path) -> dict[str, int] | None:
    """The ``published`` counts of :data:`PUBLICATION_COUNTS_FILE` in ``bag_dir``; None when there is no such
    file (:class:`BagError` when it is not a count table)."""
    counts = read_publication_count_file(bag_dir)
    return None if counts is None else counts.published


def read_publication_count_file(bag_dir: Path) -> PublicationCounts | None:
    """:data:`PUBLICATION_COUNTS_FILE` in ``bag_dir``; None when there is no such file (:class:`BagError` when it
    is not a count table)."""
    path = Path(bag_dir) / PUBLICATION_COUNTS_FILE
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        return None
    except (OSError, ValueError) as exc:
        raise BagError(f"{path}: not readable as publication counts: {exc}") from None
    counts = doc.get("published") if isinstance(doc, dict) else None
    if not isinstance(counts, dict) or not all(isinstance(k, str) and isinstance(v, int) and v >= 0
                                               for k, v in counts.items()):
        raise BagError(f"{path}: 'published' must map topic names to message counts")
    sources = doc.get("uncounted_sources", [])
    if not isinstance(sources, list) or not all(isinstance(x, str) and x for x in sources):
        raise BagError(f"{path}: 'uncounted_sources' must be a list of publisher names")
    return PublicationCounts(counts, tuple(sources))


def unrecorded_losses(reader: "BagReader", published: dict[str, int], gaps: Sequence[Gap],
                      uncounted_sources: Sequence[str] = ()) -> list[Gap]:
    """Losses the sequence numbers cannot show: for each topic, the messages ``published`` (counted by the
    publishers) less those the bag holds and those ``gaps`` already account for; one ``unrecorded``
    :class:`Gap` per topic where that is positive.  On :data:`MULTI_PUBLISHER_TYPES` topics the bag's messages
    from ``uncounted_sources`` (:func:`stream_source`; counted by nobody) are left out of what it holds."""
    infos = {t.name: t for t in reader.topic_infos()}
    seen: dict[str, int] = {}
    for g in gaps:
        seen[g.topic] = seen.get(g.topic, 0) + g.missing
    end_ns = reader.end_time_ns() if infos else 0
    skip = set(uncounted_sources)
    out = []
    for name, n in sorted(published.items()):
        recorded = infos[name].message_count if name in infos else 0
        last = None
        if skip and recorded and infos[name].type in MULTI_PUBLISHER_TYPES:  # the counted publishers' messages only
            recorded, last = _counted_messages(reader, name, infos[name].type, skip)
        lost = int(n) - recorded - seen.get(name, 0)
        if lost <= 0:
            continue
        if last is None and recorded:
            last = _counted_messages(reader, name, infos[name].type, set())[1]
        out.append(Gap(name, lost, 0 if last is None else int(last.sequence), int(n),
                       None if last is None else last.log_time_ns * 1e-9, end_ns * 1e-9,
                       after_publish_s=None if last is None else last.publish_time_ns * 1e-9, kind=UNRECORDED))
    return out


def _counted_messages(reader: "BagReader", topic: str, type_name: str, skip: set[str]
                      ) -> tuple[int, "RawMessage | None"]:
    """The messages of ``topic`` in the bag but those of the publishers in ``skip`` (:func:`stream_source`): their
    number and the last logged (one pass over the topic)."""
    n, last = 0, None
    for m in reader.raw_messages([topic], file_order=True):
        if skip and stream_source(type_name, m.data) in skip:
            continue
        n += 1
        if last is None or m.log_time_ns >= last.log_time_ns:
            last = m
    return n, last


MULTI_PUBLISHER_TYPES = ("diagnostic_msgs/msg/DiagnosticArray",)
"""Types whose topics have a publisher per node (``/bb2/status``, ``/diagnostics``): their sequence numbers are
followed per publisher, told apart by the status names in the message and the namespace of the node that sent
them (:func:`stream_source`)."""


@functools.cache
def _diagnostics_decoder():
    from mcap_ros2._dynamic import generate_dynamic

    name = "diagnostic_msgs/msg/DiagnosticArray"
    return generate_dynamic(name, message_definition(name))[name]


def stream_source(type_name: str, data: bytes) -> str:
    """Which publisher a message of a :data:`MULTI_PUBLISHER_TYPES` topic comes from, else '' (the message info
    does not carry the publisher's id): its status names, each under the namespace of the node that sent it when
    that is not the root (the status's ``hardware_id``, the node's path: ``boat1/bb2/simulator`` from
    ``/boat1/simulator``), so the same node of two boats on the global ``/diagnostics`` are two publishers."""
    if type_name not in MULTI_PUBLISHER_TYPES:
        return ""
    try:
        msg = _diagnostics_decoder()(data)
        return ",".join(sorted({status_source(str(st.name), str(st.hardware_id)) for st in msg.status}))
    except Exception:  # undecodable: followed as one more publisher
        return "?"


def status_source(name: str, hardware_id: str) -> str:
    """The publisher :func:`stream_source` names for a status ``name`` sent by the node ``hardware_id`` (its
    fully qualified name): ``boat1/bb2/simulator`` for ``bb2/simulator`` from ``/boat1/simulator``."""
    namespace = hardware_id.rsplit("/", 1)[0].strip("/") if hardware_id.startswith("/") else ""
    return f"{namespace}/{name}" if namespace else name


class SequenceGaps:
    """Gaps in the publication sequence numbers of each topic, fed in the order messages were received.

    DDS numbers every sample of a writer 1, 2, 3, ...; a reader that receives ``k`` after ``j < k - 1`` lost the
    ones between (a best-effort sample dropped, a reliable one pushed out of a keep-last history, a reader
    stopped).  A topic may have several writers (a restarted node, two publishers) and the message info does not
    say which: each received number extends the stream it follows (the one whose last number is just below
    it); a number below every stream's last starts a new stream (a new writer: not a loss).  Numbers 0 (the
    middleware does not number samples) are ignored.  Messages lost after the last one received cannot be
    seen.  Sequence numbers are compared modulo 2**32 (what an MCAP message holds)."""

    def __init__(self) -> None:
        # (topic, source) -> [[last sequence, its log time ns, its publish time ns], ...]
        self._streams: dict[tuple[str, str], list[list[int]]] = {}
        self.gaps: list[Gap] = []

    def observe(self, topic: str, sequence: int, log_time_ns: int, source: str = "",
                publish_time_ns: int | None = None) -> Gap | None:
        """One received message (``source``: :func:`stream_source`); the gap it closes, if any.  The first
        message of a topic with a number above 1 closes a head gap (the first ones were not received)."""
        seq = int(sequence) & 0xFFFFFFFF
        if seq == 0:
            return None
        streams = self._streams.setdefault((topic, source), [])
        below = [s for s in streams if s[0] < seq]
        gap = None
        pub = None if publish_time_ns is None else int(publish_time_ns)
        if not below:
            if not streams and seq > 1:
                gap = Gap(topic, seq - 1, 0, seq, None, int(log_time_ns) * 1e-9, source, None,
                          None if pub is None else pub * 1e-9)
                self.gaps.append(gap)
            streams.append([seq, int(log_time_ns), pub])
            return gap
        s = max(below, key=lambda s: s[0])
        if seq > s[0] + 1:
            gap = Gap(topic, seq - s[0] - 1, s[0], seq, s[1] * 1e-9, int(log_time_ns) * 1e-9, source,
                      None if s[2] is None else s[2] * 1e-9, None if pub is None else pub * 1e-9)
            self.gaps.append(gap)
        s[0], s[1], s[2] = seq, int(log_time_ns), pub
        return gap

    def observe_message(self, m: "RawMessage") -> Gap | None:
        """:meth:`observe` for a message read back from a bag (its MCAP sequence, log and publish times)."""
        return self.observe(m.topic, m.sequence, m.log_time_ns, stream_source(m.type, m.data), m.publish_time_ns)

    @property
    def missing(self) -> int:
        return sum(g.missing for g in self.gaps)

    def to_json(self) -> str:
        return json.dumps([g.as_dict() for g in self.gaps])

    @classmethod
    def from_reader(cls, reader: "BagReader") -> "SequenceGaps":
        """The gaps of a bag whose sequence numbers are publication sequence numbers, from its messages in the
        order they were written."""
        g = cls()
        dds = [t.name for t in reader.topic_infos() if t.dds_sequence]
        if dds:
            for m in reader.raw_messages(dds, file_order=True):
                g.observe_message(m)
        return g


def gaps_by_topic(gaps: Iterable[Gap]) -> dict[str, list[Gap]]:
    """Gaps grouped by topic, in the order the topics first lost a message."""
    out: dict[str, list[Gap]] = {}
    for g in gaps:
        out.setdefault(g.topic, []).append(g)
    return out


def bag_gaps(reader: "BagReader") -> list[Gap] | None:
    """The gaps of a bag: those its recorder wrote into the metadata (``custom_data`` :data:`GAPS_KEY`), else
    those its sequence numbers show when they are publication sequence numbers; None when the bag cannot tell
    (another recorder's bag)."""
    custom = dict((reader.metadata or {}).get("custom_data") or {})
    if GAPS_KEY in custom:
        try:
            gaps = [Gap(**d) for d in json.loads(custom[GAPS_KEY])]
        except (ValueError, TypeError) as exc:
            raise BagError(f"{reader.mcap_path}: custom_data {GAPS_KEY} is not a gap list: {exc}") from None
        if reader.vehicle:  # one boat of a fleet's bag: its gaps, under its reader's names
            gaps = [dataclasses.replace(g, topic=reader.view_topic(g.topic)) for g in gaps
                    if reader.view_topic(g.topic) is not None]
    elif any(t.dds_sequence for t in reader.topic_infos()):
        gaps = SequenceGaps.from_reader(reader).gaps
    else:
        return None
    counts = read_publication_count_file(reader.mcap_path.parent)
    return gaps if counts is None else gaps + unrecorded_losses(reader, counts.published, gaps,
                                                                counts.uncounted_sources)
