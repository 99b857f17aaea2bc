"""The BB2 recorder: a thin rclpy node writing contract topics into a rosbag2 (mcap) bag.

It subscribes with raw (serialized) subscriptions, so the CDR bytes go into the bag untouched, and
writes them with :mod:`bb2_tools.bagfile`.  From every ``/bb2/odom`` message it also writes a
``/tf`` ``tf2_msgs/TFMessage`` (``odom -> base_link``), so Foxglove shows the vehicle, and from the sensor suite's
``/bb2/sensors/mountings`` a ``/tf_static`` (``base_link -> <sensor>_link``, the DVL's beams), so the bag carries
every sensor frame (tf2_msgs is not in the wheels: the nodes cannot publish either themselves).

Times, as rosbag2 records them: the MCAP log time is the *receive* time on the recorder node's
clock (the simulation time when ``use_sim_time`` is true, i.e. the last /clock received), the
publish time is the DDS source timestamp (wall clock).  The header stamps inside the messages are
untouched.  A topic is added to the bag when its first message arrives, with the QoS the
publishers offer at that moment (``offered_qos_profiles``) and the type's RIHS01 hash.

Spinning: the recorder waits on its raw subscriptions itself (:meth:`Recorder.spin_once`: one rcl wait
set, every ready message taken with its info and written in receive order); rclpy's EventsExecutor does
not pass the message info to callbacks in this rclpy, and the SingleThreadedExecutor rebuilds its wait set
per wake-up, which cost the recorder more CPU than the bag writing on a 2-core machine.  With
``--use-sim-time`` the log time is the last ``/clock`` taken before the message (rclpy's time source
does the same, one callback later).

Nothing lost silently: every message is written with its DDS publication sequence number (the MCAP message
``sequence``; channel metadata ``bb2_sequence``), and every gap in a topic's numbers (messages the publisher sent
that never arrived: a best-effort sample dropped, a reliable one pushed out of the writer's history while the
recorder was stalled) is logged as it is found and written into the bag's ``custom_data`` (``bb2_gaps``, a JSON
list: topic, missing, sequence numbers and log times either side; :class:`bb2_tools.bagfile.Gap`).  After each
batch, the recorder publishes ``/bb2/recorder/ack`` (``std_msgs/Header``): the stamp up to which it holds every
topic the simulator publishes each step (``/bb2/state_native``, ``/clock`` and the simulator's sensor topics: the
oldest of their newest stamps, :class:`StepAcks`).  A lockstep simulator with ``recorder_ack_window`` waits for it,
so a stalled recorder slows the graph instead of losing messages -- on every per-step topic: a reliable topic
whose samples the stall pushed out of the transport comes back only when its writer repairs it (a heartbeat
later), and the simulator must not outrun its writer history meanwhile.

Its own status, as every node's: ``bb2/recorder`` on ``bb2/status`` and ``/diagnostics`` every ``status_period_s``
wall seconds (parameter, default 1; 0 = none): messages and bytes written, topics, gaps and messages lost (warning
level once a message was lost), each boat's step acknowledged, and its process's CPU (``cpu_process_s``, as the
nodes say theirs).  With ``--use-sim-time`` in a boat's graph it is stamped on the boat's simulation time (its
``use_sim_time`` value says true), so its statuses count CPU per simulated step like a node's.

Transport: the recorder's own process talks to the graph over UDP only (Fast DDS ``FASTDDS_BUILTIN_TRANSPORTS``
``UDPv4``, with 4 MiB socket buffers, :data:`RECORDER_TRANSPORTS`, set for its process alone; ``--transports`` or
that variable in its environment choose others); the nodes keep Fast DDS's default shared memory between themselves.
In the shared-memory transport a reader's port that does not answer its health check in time (a recorder at nice +10
starved on a loaded machine) can be replaced under the writers that re-open it, while the reader keeps listening on
the old one: the writers' messages then go where no one reads, for the rest of the run (Fast DDS
``SharedMemGlobal::open_port``).  Over UDP a starved recorder only falls behind, and the reliable writers repair
what it missed from their histories; the large receive buffer keeps bursts from needing that repair.  It discovers
the graph through its domain's multicast discovery port: when another socket holds that port unshared (an ephemeral
port, on domains 102..214) it would hear no one, so it says so and exits 2 (:func:`discovery_blocked`).

Stopping: SIGINT or SIGTERM finish the bag (summary, ``rosbag2`` metadata record, metadata.yaml)
and exit 0.  A SIGKILL loses at most the open chunk (``--chunk-size`` bytes, or
``--flush-period`` seconds of data); ``bb2_tools.bagfile.recover`` repairs such a bag.

A fleet (``--boats boat1 boat2``, parameter ``boats``): one recorder for every boat of one graph, each in its
namespace: the boat's topics are recorded under their resolved names (``/boat1/bb2/odom``, ``/boat1/clock``), one
``/tf`` and ``/tf_static`` for all (the frames are the boats' own, ``boat1/base_link``), each boat's messages logged
on its own clock (``/boat1/clock`` with ``--use-sim-time``) and acknowledged on its ``/boat1/bb2/recorder/ack``
(:class:`Vehicle`).  ``bb2_tools.bagfile.BagReader(bag, "boat1")`` reads one boat of it under the contract's names.

Usage::

    python -m bb2_tools.recorder --out bags/run1 [--topics REGEX ...] [--chunk-size BYTES]
        [--flush-period S] [--use-sim-time] [--no-tf] [--boats NS ...] [--transports UDPv4|DEFAULT|...]
        [--ros-args ...]
"""
from __future__ import annotations

import argparse
import functools
import math
import os
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

from bb2_msgs_py.contract import (FRAME_MAP, FRAME_ODOM, GLOBAL_TOPICS, SCENE_TOPIC, SIM, ContractError, TopicSpec,
                                  check_namespace, message_class, node_topic_name, recorded_in_namespace,
                                  select_topics)
from bb2_tools.bagfile import (GAPS_KEY, MULTI_PUBLISHER_TYPES, RECORDER_STATUS_NAME, BagError, BagWriter,
                                SequenceGaps, qos_entry, status_source, stream_source)
from bb2_ros.discovery_port import TRANSPORTS_ENV, discovery_blocked
from bb2_msgs_py.conversions import leading_stamp_ns, seconds_to_ns
from bb2_ros import heap
from bb2_ros.node_common import (NodeStatus, node_frame, restore_signals, stop_signals, take_all, time_msg,
                                 write_publication_counts)

ODOM_TOPIC = "/bb2/odom"
ODOM_TYPE = "nav_msgs/msg/Odometry"
CLOCK_TOPIC = "/clock"
STATE_TOPIC = "/bb2/state_native"
ACK_TOPIC = "/bb2/recorder/ack"
SEQUENCE_UNSUPPORTED = 2**63  # rmw: RMW_MESSAGE_INFO_SEQUENCE_NUMBER_UNSUPPORTED is UINT64_MAX
TF_TOPIC = "/tf"
TF_TYPE = "tf2_msgs/msg/TFMessage"
# tf2_ros::DynamicBroadcasterQoS: reliable, volatile, keep last 100
TF_QOS = qos_entry(reliability="reliable", durability="volatile", history="keep_last", depth=100)
TF_STATIC_TOPIC = "/tf_static"
# tf2_ros::StaticBroadcasterQoS: reliable, transient local, keep last 1
TF_STATIC_QOS = qos_entry(reliability="reliable", durability="transient_local", history="keep_last", depth=1)
MOUNTINGS_TOPIC = "/bb2/sensors/mountings"
DRAIN_TIMEOUT_S = 5.0  # at the stop, take what the readers hold for at most this long (wall s)


def qos_to_entry(profile) -> dict[str, Any]:
    """An rclpy QoSProfile (e.g. a discovered publisher's) as a rosbag2 v9 offered-QoS entry."""
    def name(policy) -> str:
        n = policy.name.lower()
        return "unknown" if n == "unknown" else n

    def ns(d) -> int:
        return int(d.nanoseconds)

    return qos_entry(reliability=name(profile.reliability), durability=name(profile.durability),
                     history=name(profile.history), depth=int(profile.depth),
                     deadline_ns=ns(profile.deadline), lifespan_ns=ns(profile.lifespan),
                     liveliness=name(profile.liveliness),
                     liveliness_lease_duration_ns=ns(profile.liveliness_lease_duration),
                     avoid_ros_namespace_conventions=bool(profile.avoid_ros_namespace_conventions))


def tf_from_odometry(odom) -> dict[str, Any]:
    """A ``tf2_msgs/TFMessage`` (as nested dicts) with the transform of an ``nav_msgs/Odometry``."""
    p, q = odom.pose.pose.position, odom.pose.pose.orientation
    return {"transforms": [{
        "header": {"stamp": {"sec": odom.header.stamp.sec, "nanosec": odom.header.stamp.nanosec},
                   "frame_id": odom.header.frame_id},
        "child_frame_id": odom.child_frame_id,
        "transform": {"translation": {"x": p.x, "y": p.y, "z": p.z},
                      "rotation": {"x": q.x, "y": q.y, "z": q.z, "w": q.w}}}]}


@functools.cache
def _tf_codec():
    """(rclpy's deserialize_message, the Odometry class, mcap_ros2's encoder of a TFMessage dict)."""
    from mcap_ros2._dynamic import serialize_dynamic
    from rclpy.serialization import deserialize_message

    from bb2_tools.bagfile import message_definition

    encode = serialize_dynamic(TF_TYPE, message_definition(TF_TYPE))[TF_TYPE]
    return deserialize_message, message_class(ODOM_TYPE), encode


def tf_cdr_from_odometry_cdr(data: bytes) -> bytes:
    """The CDR of a ``tf2_msgs/TFMessage`` with the one transform of a serialized ``nav_msgs/Odometry``
    (:func:`tf_from_odometry`: header, child frame, position -> translation, orientation -> rotation).

    The odometry is read with rclpy's standard deserializer; tf2_msgs is not in the wheels (no rclpy type
    support for TFMessage), so the TFMessage is written by mcap_ros2's dynamic CDR encoder from its embedded
    definition, as :meth:`bb2_tools.bagfile.BagWriter.write_dict` does.  Bytes that are not a serialized
    Odometry raise rclpy's ``RuntimeError``."""
    deserialize, odometry, encode = _tf_codec()
    return encode(tf_from_odometry(deserialize(data, odometry)))


def tf_static_from_mountings(doc: dict[str, Any], stamp_ns: int) -> dict[str, Any]:
    """A ``tf2_msgs/TFMessage`` (as nested dicts) with every static transform of a sensor-mountings description
    (format ``bb2_sensor_mountings/1``, :func:`bb2_msgs_py.sensor_conversions.mountings_description`), stamped
    ``stamp_ns``.  :class:`ValueError` when the description is not that format."""
    from bb2_msgs_py.sensor_conversions import MOUNTINGS_FORMAT

    if not isinstance(doc, dict) or doc.get("format") != MOUNTINGS_FORMAT:
        raise ValueError(f"not a {MOUNTINGS_FORMAT} description")
    sec, nanosec = divmod(int(stamp_ns), 1_000_000_000)
    out = []
    for tf in doc.get("transforms", []):
        t, q = [float(v) for v in tf["translation_m"]], [float(v) for v in tf["rotation_xyzw"]]
        if len(t) != 3 or len(q) != 4:
            raise ValueError(f"transform {tf.get('child')!r}: translation_m needs 3 values, rotation_xyzw 4")
        out.append({"header": {"stamp": {"sec": sec, "nanosec": nanosec}, "frame_id": str(tf["parent"])},
                    "child_frame_id": str(tf["child"]),
                    "transform": {"translation": {"x": t[0], "y": t[1], "z": t[2]},
                                  "rotation": {"x": q[0], "y": q[1], "z": q[2], "w": q[3]}}})
    return {"transforms": out}


def tf_static_cdr_from_mountings_cdr(data: bytes, stamp_ns: int) -> bytes:
    """The CDR of a ``/tf_static`` ``tf2_msgs/TFMessage`` from a serialized ``/bb2/sensors/mountings``
    (``std_msgs/String`` JSON; :func:`tf_static_from_mountings`); ValueError on a description it cannot read."""
    import json

    deserialize, _, encode = _tf_codec()
    text = deserialize(data, message_class("std_msgs/msg/String")).data
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(f"not JSON: {exc}") from None
    return encode(tf_static_from_mountings(doc, stamp_ns))


def tf_static_map_odom(stamp_ns: int, odom_frame: str = FRAME_ODOM) -> dict[str, Any]:
    """A ``tf2_msgs/TFMessage`` (as nested dicts) with the identity ``map -> odom_frame`` (the odometry is the
    ground truth: odom is map; ``boat1/odom`` for a boat in ``/boat1``), stamped ``stamp_ns``: it joins what is
    drawn in ``map`` (the path, the terrain, the sea) to the tree of ``odom -> base_link``."""
    sec, nanosec = divmod(int(stamp_ns), 1_000_000_000)
    return {"transforms": [{"header": {"stamp": {"sec": sec, "nanosec": nanosec}, "frame_id": FRAME_MAP},
                            "child_frame_id": odom_frame,
                            "transform": {"translation": {"x": 0.0, "y": 0.0, "z": 0.0},
                                          "rotation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}}]}


DERIVED_TOPICS = {ODOM_TOPIC: TF_TOPIC, MOUNTINGS_TOPIC: TF_STATIC_TOPIC, SCENE_TOPIC: TF_STATIC_TOPIC}
"""Contract topic -> the tf topic derived from it (tf2_msgs is not in the wheels: the nodes cannot publish these):
``/tf`` from the odometry, ``/tf_static`` from the sensor mountings and, with the scene, ``map -> odom``."""


def derived_tf_cdr(topic: str, data: bytes, stamp_ns: int, *, odom_frame: str = FRAME_ODOM) -> bytes:
    """The CDR of the tf topic derived from a message of ``topic`` (:data:`DERIVED_TOPICS`): ``/tf`` from
    ``/bb2/odom``, ``/tf_static`` (stamped ``stamp_ns``) from ``/bb2/sensors/mountings``; ValueError, KeyError or
    TypeError on a mountings description it cannot read; the identity ``map -> odom_frame`` from the scene
    (``/bb2/scene/markers``; the vehicle's odom: ``boat1/odom`` for a reader in ``/boat1``).  What the recorder
    writes into bags and the Foxglove bridge serves."""
    if topic == ODOM_TOPIC:
        return tf_cdr_from_odometry_cdr(data)
    if topic == SCENE_TOPIC:
        return _tf_codec()[2](tf_static_map_odom(stamp_ns, odom_frame))
    return tf_static_cdr_from_mountings_cdr(data, stamp_ns)


def default_topics(namespace: str = "") -> list[TopicSpec]:
    """What the recorder records when no topics are given: every contract topic; in a boat's namespace the global
    ones left out (``/diagnostics``: every boat's statuses; the boat's own are on its ``bb2/status``)."""
    return [s for s in select_topics() if recorded_in_namespace(s.name, namespace)]


def step_topics(topics: Sequence[TopicSpec]) -> set[str]:
    """The topics of ``topics`` the simulator publishes once per step: ``/bb2/state_native``, ``/clock`` and its
    sensor topics (odometry, IMU, depth, altitude, plane and propeller states; not the sensor suite's
    measurements, which come at their own rates)."""
    return {t.name for t in topics if t.name == STATE_TOPIC or (t.publisher == SIM and t.qos in ("sensor", "clock"))}


STEP_START_TOPICS = frozenset({"/bb2/imu", "/bb2/planes/state", "/bb2/propeller/state"})
"""Per-step topics the simulator stamps with the start ``t_n`` of the step they describe and publishes after its
integration, beside the state of ``t_n+1``: they belong to the step of ``t_n+1``."""


class StepAcks:
    """What the recorder acknowledges: the newest step of each per-step topic it received, and the oldest of those
    (the step up to which the bag holds every per-step topic that has begun).  A message of
    :data:`STEP_START_TOPICS` stamped ``t_n`` belongs to the step of ``t_n+1`` (the state it came with), once the
    step is known from two successive states; so the final state of a run is acknowledged when everything of its
    step is held.  Acknowledgements only go forward; a topic counts from its first message on."""

    def __init__(self, topics: set[str]) -> None:
        self.topics = frozenset(topics)
        self.newest_ns: dict[str, int] = {}
        self.acked_ns: int | None = None
        self.step_ns: int | None = None  #: the smallest positive difference of successive state stamps seen

    def received(self, topic: str, stamp_ns: int) -> None:
        newest = self.newest_ns.get(topic)
        if newest is not None and stamp_ns <= newest:
            return
        if topic == STATE_TOPIC and newest is not None:
            d = int(stamp_ns) - newest
            self.step_ns = d if self.step_ns is None else min(self.step_ns, d)
        self.newest_ns[topic] = int(stamp_ns)

    def _step_of(self, topic: str, stamp_ns: int) -> int:
        return stamp_ns + self.step_ns if topic in STEP_START_TOPICS and self.step_ns is not None else stamp_ns

    def next_ack(self) -> int | None:
        """The stamp to acknowledge now, or None (nothing new since the last)."""
        if not self.newest_ns:
            return None
        ack = min(self._step_of(t, ns) for t, ns in self.newest_ns.items())
        if self.acked_ns is not None and ack <= self.acked_ns:
            return None
        self.acked_ns = ack
        return ack


def subscription_qos(spec: TopicSpec, depth: int, *, best_effort: bool = False):
    """The recorder's request: what the contract's writers offer (reliable where they write reliable, as rosbag2
    subscribes with the publishers' QoS: a stalled recorder gets the samples again from the writers' histories),
    with a deep queue so bursts (lockstep) are not dropped; ``best_effort`` for a topic with a best-effort
    publisher (an external simulator or HIL bench), which a reliable request would not match."""
    from rclpy.qos import HistoryPolicy, ReliabilityPolicy

    from bb2_msgs_py.contract import qos_profile

    q = qos_profile(spec.name)
    if best_effort:
        q.reliability = ReliabilityPolicy.BEST_EFFORT
    q.history = HistoryPolicy.KEEP_LAST
    q.depth = max(int(depth), q.depth)
    return q


@dataclass
class Vehicle:
    """One boat a recorder records: where its topics are on the graph and in the bag, its clock, its acks.

    ``prefix`` ``""``: the boat of the recorder's own namespace (topics named relative to it, written under the
    contract's names: a boat's bag reads as a lone boat's); ``"/boat1"``: a boat of a fleet recorded by one
    recorder (``--boats``), its topics ``/boat1/bb2/...`` and ``/boat1/clock`` on the graph and in the bag."""

    prefix: str
    odom_frame: str
    acks: StepAcks
    ack_pub: Any = None
    sim_ns: int = 0  #: the last of its /clock taken (ROS time 0 until the first, as rclpy's time source)

    def graph_name(self, name: str) -> str:
        """The name the recorder subscribes to (and publishes the boat's ack on)."""
        return self.prefix + name if self.prefix else node_topic_name(name)

    def bag_name(self, name: str) -> str:
        return self.prefix + name


class Recorder:
    """Records ``topics`` into ``bag`` from a node of its own (``self.node``): of the boat in the node's namespace,
    or (``boats``) of every boat of a fleet, each in its namespace."""

    def __init__(self, bag: BagWriter, topics: Sequence[TopicSpec], *, tf_from_odom: bool = True,
                 flush_period_s: float = 1.0, queue_depth: int = 1000, node_name: str = "bb2_recorder",
                 use_sim_time: bool = False, node=None, acknowledge: bool = True, gap_warn_s: float = 1.0,
                 boats: Sequence[str] = (), status_period_s: float = 0.0):
        from rclpy.clock import Clock, ClockType
        from rclpy.node import Node
        from rclpy.serialization import deserialize_message

        self.bag = bag
        # ``node``: a node of the caller's (the `recorder` executable's, with its parameters and parameter
        # services, which spin_once serves from its own wait set); else one without parameter services
        self.node = node if node is not None else Node(node_name, start_parameter_services=False)
        # /tf from the odometry and /tf_static from the sensor mountings and the scene (map -> the vehicle's odom:
        # boat1/odom for a recorder in /boat1, as the boat's simulator names it)
        self.tf_from_odom = tf_from_odom and any(t.name in DERIVED_TOPICS for t in topics)
        self.use_sim_time = bool(use_sim_time)
        self._deserialize = deserialize_message
        self._clock_type = message_class("rosgraph_msgs/msg/Clock")
        self._system_clock = Clock(clock_type=ClockType.SYSTEM_TIME)
        self._lock = threading.Lock()
        self._subs = []  # (subscription, spec or None: /clock for the time only, vehicle)
        self.specs = {t.name: t for t in topics if not t.bag_only}
        self._queue_depth = int(queue_depth)
        from bb2_msgs_py.contract import frame_prefix, qos_profile, vehicle_frame
        # the boat of the node's namespace (map -> boat1/odom for a recorder in /boat1), or each boat of the fleet
        self.vehicles = [Vehicle(f"/{b}", vehicle_frame(FRAME_ODOM, frame_prefix(b)), StepAcks(step_topics(topics)))
                         for b in (x.strip("/") for x in boats)] or \
            [Vehicle("", node_frame(self.node, FRAME_ODOM), StepAcks(step_topics(topics)))]
        self._state_type = message_class("std_msgs/msg/Float64MultiArray")
        self._header_type = message_class("std_msgs/msg/Header")
        for v in self.vehicles:
            for spec in self.specs.values():
                self._subs.append((self._subscribe(spec, v), spec, v))
            if self.use_sim_time and CLOCK_TOPIC not in self.specs:
                self._subs.append((self.node.create_subscription(
                    self._clock_type, v.graph_name(CLOCK_TOPIC), self._unused_callback,
                    qos_profile(CLOCK_TOPIC), raw=True), None, v))
            if acknowledge and STATE_TOPIC in self.specs:
                v.ack_pub = self.node.create_publisher(self._header_type, v.graph_name(ACK_TOPIC),
                                                       qos_profile(ACK_TOPIC))
        self.gaps = SequenceGaps()
        self._gap_warn_s, self._gap_warned_wall, self._gaps_warned = float(gap_warn_s), -math.inf, 0
        self.flush_period_s = float(flush_period_s)
        self._next_flush = time.monotonic() + self.flush_period_s
        self._wait_set = None
        # its own status, as every node's (``bb2/recorder`` on its bb2/status and /diagnostics), published from
        # spin_once (no executor here to run a timer): the first at the first spin
        self.status_period_s = float(status_period_s)
        self._status = NodeStatus(self.node, RECORDER_STATUS_NAME, None, self._status_values) \
            if self.status_period_s > 0 else None
        self._next_status = time.monotonic()
        # its statuses come back to it over DDS and are recorded like any node's; it counts them (bag name -> n) so
        # that at the stop it takes its last ones, and its publication counts match the bag as the nodes' do
        self._own_source = status_source(RECORDER_STATUS_NAME, self.node.get_fully_qualified_name())
        self.own_recorded: dict[str, int] = {}
        self._statuses_stopped = False

    def _subscribe(self, spec: TopicSpec, vehicle: Vehicle, *, best_effort: bool = False):
        return self.node.create_subscription(message_class(spec.type), vehicle.graph_name(spec.name),
                                             self._unused_callback,
                                             subscription_qos(spec, self._queue_depth, best_effort=best_effort),
                                             raw=True)

    def adapt_reliability(self) -> list[str]:
        """Re-subscribe best effort to every topic a best-effort publisher now offers (a reliable request does
        not match it, and the topic would go unrecorded); returns those topics, each said once in a warning."""
        from rclpy.qos import ReliabilityPolicy

        changed = []
        for k, (sub, spec, v) in enumerate(self._subs):
            if spec is None or sub.qos_profile.reliability != ReliabilityPolicy.RELIABLE:  # /clock only, or done
                continue
            try:
                infos = self.node.get_publishers_info_by_topic(v.graph_name(spec.name))
            except Exception:  # discovery hiccup: try again at the next flush
                continue
            if any(i.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT for i in infos):
                self._subs[k] = (self._subscribe(spec, v, best_effort=True), spec, v)
                self.node.destroy_subscription(sub)
                self._wait_set = None
                changed.append(v.bag_name(spec.name))
                self.node.get_logger().warning(
                    f"{changed[-1]}: a publisher offers best effort: recording it best effort from now on (a stalled "
                    "recorder may lose its samples; any gap is still detected and written into the bag)")
        return changed

    def _offered_qos(self, name: str, vehicle: Vehicle) -> list[dict[str, Any]]:
        try:
            return [qos_to_entry(info.qos_profile)
                    for info in self.node.get_publishers_info_by_topic(vehicle.graph_name(name))]
        except Exception as exc:  # discovery hiccup: record without QoS rather than lose data
            self.node.get_logger().warning(f"cannot read offered QoS of {name}: {exc}")
            return []

    @staticmethod
    def _unused_callback(_data) -> None:  # pragma: no cover - spin_once takes the messages itself
        pass

    def spin_once(self, timeout_s: float) -> int:
        """Wait up to ``timeout_s`` for messages, take every one waiting (with its info) and write them
        in the order they were received; flush the open chunk every ``flush_period_s``.  Returns the
        number of messages taken."""
        from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy

        ctx = self.node.context
        if self._wait_set is None:
            self._services = list(self.node.services)  # the parameter services, if the node has them
            self._wait_set = _rclpy.WaitSet(len(self._subs), 0, 0, 0, len(self._services), 0, ctx.handle)
        ws = self._wait_set
        ws.clear_entities()
        for sub, _spec, _v in self._subs:
            ws.add_subscription(sub.handle)
        for srv in self._services:
            ws.add_service(srv.handle)
        ws.wait(max(int(timeout_s * 1e9), 0))
        if self._services:
            self._serve(set(ws.get_ready_entities("service")))
        ready = set(ws.get_ready_entities("subscription"))
        taken = []
        for sub, spec, v in self._subs:
            if sub.handle.pointer not in ready:
                continue
            for data, info in take_all(sub):
                taken.append((int(info.get("received_timestamp", 0)), len(taken), spec, v, data, info))
        taken.sort(key=lambda m: (m[0], m[1]))
        for _recv, _k, spec, v, data, info in taken:
            if self.use_sim_time and (spec is None or spec.name == CLOCK_TOPIC):
                v.sim_ns = leading_stamp_ns(data)
            if spec is not None:
                self._on_message(spec, data, info, v)
        self._acknowledge()
        self._warn_gaps()
        if self.flush_period_s > 0 and time.monotonic() >= self._next_flush:
            self._next_flush = time.monotonic() + self.flush_period_s
            self._flush()
            self.adapt_reliability()
        if self._status is not None and not self._statuses_stopped and time.monotonic() >= self._next_status:
            self._next_status = time.monotonic() + self.status_period_s
            self.publish_status()
        return len(taken)

    def _sim_clock(self) -> bool:
        """Whether the recorder keeps one simulation time (its boat's /clock): not a fleet's, one per boat."""
        return self.use_sim_time and len(self.vehicles) == 1

    def _status_values(self) -> dict[str, str]:
        """What the recorder's status says: the bag so far (messages, bytes, topics), the messages lost before they
        reached it, and each boat's step acknowledged (sim s; ``boat1/acked_step_s`` in a fleet)."""
        g = self.gaps
        vals = {"state": "recording", "bag": str(self.bag.bag_dir), "messages_written": str(self.bag.message_count),
                "bytes_written": str(self.bag.bytes_written),
                "topics_written": str(sum(1 for t in self.bag.topics.values() if t.message_count)),
                "gaps": str(len(g.gaps)), "messages_lost": str(g.missing),
                "log_time": "sim (each boat's /clock)" if self.use_sim_time else "wall",
                "fastdds_transports": os.environ.get(TRANSPORTS_ENV, "")}
        if self._sim_clock():  # its time is the boat's sim time (its /clock, taken here, not by an executor)
            vals["use_sim_time"] = "true"
        for v in self.vehicles:
            if v.ack_pub is not None and v.acks.acked_ns is not None:
                vals[f"{v.prefix.strip('/') + '/' if v.prefix else ''}acked_step_s"] = f"{v.acks.acked_ns * 1e-9:.6f}"
        return vals

    def stop_statuses(self) -> None:
        """Publish no more statuses (at the stop: the last ones are then awaited, :meth:`own_statuses_pending`)."""
        self._statuses_stopped = True

    def own_statuses_pending(self) -> bool:
        """Whether statuses this recorder published on a topic it records have not come back into the bag yet."""
        if self._status is None:
            return False
        bag_names = {sub.topic_name: v.bag_name(spec.name) for sub, spec, v in self._subs if spec is not None}
        for pub in (self._status.pub, self._status.pub_diagnostics):
            name = bag_names.get(pub.topic_name)
            if name is not None and self.own_recorded.get(name, 0) < int(pub.published):
                return True
        return False

    def write_publication_counts(self) -> None:
        """Its publication counts beside the nodes' (where the launcher asked: ``BB2_PUBLISHED_DIR``), so the
        launcher's check that the bag holds everything published covers its statuses too."""
        write_publication_counts(NODE_NAME, [self.node])

    def publish_status(self) -> None:
        """Publish the recorder's status now (warning level once messages were lost before reaching it)."""
        if self._status is None:
            return
        g = self.gaps
        self._status.level, self._status.message = (1, f"{g.missing} message(s) lost before reaching the recorder "
                                                       f"({len(g.gaps)} gap(s))") if g.gaps else (0, "recording")
        self._status.publish(self.vehicles[0].sim_ns if self._sim_clock() else None)

    def _serve(self, ready: set) -> None:
        """Answer the ready service requests (ros2 param list/get/describe/dump/set), as an executor would."""
        for srv in self._services:
            if srv.handle.pointer not in ready:
                continue
            request, header = srv.handle.service_take_request(srv.srv_type.Request)
            if header is not None:
                srv.send_response(srv.callback(request, srv.srv_type.Response()), header)

    def _now_ns(self, vehicle: Vehicle) -> int:
        """The log time: the boat's simulation time (its last /clock) with ``use_sim_time`` -- each boat of a fleet
        logged on its own clock, so the boats play back side by side in simulation time --, else the wall clock."""
        return vehicle.sim_ns if self.use_sim_time else self._system_clock.now().nanoseconds

    def _on_message(self, spec: TopicSpec, data: bytes, info: dict, vehicle: Vehicle) -> None:
        t_ns = self._now_ns(vehicle)
        name = vehicle.bag_name(spec.name)
        pub_ns = int(info.get("source_timestamp", t_ns)) if isinstance(info, dict) else t_ns
        seq = int(info.get("publication_sequence_number", 0)) if isinstance(info, dict) else 0
        seq = 0 if seq >= SEQUENCE_UNSUPPORTED else seq
        with self._lock:
            if name not in self.bag.topics:
                self.bag.add_topic(name, spec.type, offered_qos=self._offered_qos(spec.name, vehicle),
                                   dds_sequence=seq > 0)
            self.bag.write(name, data, t_ns, pub_ns, sequence=seq if self.bag.topics[name].dds_sequence else None)
            source = stream_source(spec.type, data) if spec.type in MULTI_PUBLISHER_TYPES else ""
            if source == self._own_source:
                self.own_recorded[name] = self.own_recorded.get(name, 0) + 1
            if seq > 0:
                self.gaps.observe(name, seq, t_ns, source, pub_ns)
            if vehicle.ack_pub is not None and spec.name in vehicle.acks.topics:
                vehicle.acks.received(spec.name, self._step_stamp_ns(spec.name, data))
            derived = DERIVED_TOPICS.get(spec.name) if self.tf_from_odom else None  # /tf: one tree for every boat
            if derived is not None:
                try:
                    tf = derived_tf_cdr(spec.name, data, t_ns, odom_frame=vehicle.odom_frame)
                except (ValueError, KeyError, TypeError) as exc:  # the mountings are in the bag as they came
                    self.node.get_logger().warning(f"{name}: no {derived} from it ({exc})")
                else:
                    if derived not in self.bag.topics:
                        self.bag.add_topic(derived, TF_TYPE,
                                           offered_qos=[TF_QOS if derived == TF_TOPIC else TF_STATIC_QOS])
                    self.bag.write(derived, tf, t_ns, pub_ns)

    def _step_stamp_ns(self, topic: str, data: bytes) -> int:
        """The step a per-step message belongs to: the state's time (its first element), else the stamp the
        message starts with (header stamp, clock)."""
        if topic == STATE_TOPIC:
            return seconds_to_ns(float(self._deserialize(data, self._state_type).data[0]))
        return leading_stamp_ns(data)

    def _acknowledge(self) -> None:
        """Tell each boat's simulator up to which step the bag holds its every per-step topic (after the batch is
        written)."""
        for v in self.vehicles:
            ack = v.acks.next_ack() if v.ack_pub is not None else None
            if ack is not None:
                v.ack_pub.publish(self._header_type(stamp=time_msg(ack)))

    def _warn_gaps(self, *, final: bool = False) -> None:
        """Log the gaps found since the last warning (at most one warning per ``gap_warn_s`` wall s)."""
        new = self.gaps.gaps[self._gaps_warned:]
        if not new or (not final and time.monotonic() - self._gap_warned_wall < self._gap_warn_s):
            return
        self._gap_warned_wall, self._gaps_warned = time.monotonic(), len(self.gaps.gaps)
        shown = "; ".join(g.describe() for g in new[:3]) + (f"; and {len(new) - 3} more" if len(new) > 3 else "")
        self.node.get_logger().warning(f"messages lost before they reached the recorder ({len(new)} gap(s), "
                                       f"{sum(g.missing for g in new)} message(s)): {shown}")

    def _flush(self) -> None:
        with self._lock:
            self.bag.flush()

    def close(self) -> Path:
        """Finish the bag (its gaps in ``custom_data``) and destroy the node."""
        self._warn_gaps(final=True)
        with self._lock:
            self.bag.custom_data[GAPS_KEY] = self.gaps.to_json()
            path = self.bag.close()
        self.node.destroy_node()
        return path


def _parse(argv: Sequence[str]) -> tuple[argparse.Namespace, list[str]]:
    p = argparse.ArgumentParser(prog="bb2-record", description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", type=Path, default=None,
                   help="bag directory to create (parameter bag_directory; default bags/bb2_YYYYmmdd_HHMMSS)")
    p.add_argument("--topics", nargs="+", default=None, metavar="TOPIC_OR_REGEX",
                   help="contract topics to record (exact names or regular expressions; parameter topics); "
                        "default all")
    p.add_argument("--chunk-size", type=int, default=None,
                   help="uncompressed bytes per MCAP chunk (the most a SIGKILL loses; parameter chunk_size); "
                        "default 262144")
    p.add_argument("--flush-period", type=float, default=None,
                   help="also close the open chunk every S seconds of wall time (0: never; parameter "
                        "flush_period_s); default 1")
    p.add_argument("--depth", type=int, default=None, help="subscription queue depth (parameter queue_depth); "
                                                          "default 1000")
    p.add_argument("--batch-period", type=float, default=None, metavar="S",
                   help="after taking messages, wait this long before the next take, so that messages are "
                        "taken in batches (one wake-up instead of one per message: less CPU taken from the "
                        "graph; must stay well below --depth messages per topic); 0 = take each as it "
                        "arrives (parameter batch_period_s); default 0.005")
    p.add_argument("--boats", nargs="+", default=None, metavar="NAMESPACE",
                   help="record every boat of a fleet in one bag, each in its namespace: /boat1/bb2/odom ... and "
                        "/boat1/clock on the graph and in the bag, one /tf for all, each boat acknowledged on its "
                        "/boat1/bb2/recorder/ack (parameter boats); default: the boat of the recorder's namespace")
    p.add_argument("--use-sim-time", action="store_true", help="log times from /clock (parameter use_sim_time; "
                   "with --boats each boat's messages from its own /boat1/clock)")
    p.add_argument("--no-tf", action="store_true", help="do not derive /tf from /bb2/odom nor /tf_static from "
                   "/bb2/sensors/mountings (parameter tf_from_odom)")
    p.add_argument("--overwrite", action="store_true", help="allow a non-empty --out directory (parameter "
                                                            "overwrite)")
    p.add_argument("--transports", default=None, metavar="FASTDDS_TRANSPORTS",
                   help=f"Fast DDS builtin transports of the recorder's process ({TRANSPORTS_ENV}: UDPv4, DEFAULT = "
                        f"shared memory and UDPv4, SHM, ...; set before ROS starts, so not a parameter); default: "
                        f"the environment's {TRANSPORTS_ENV}, else {RECORDER_TRANSPORTS}")
    from rclpy.utilities import remove_ros_args

    ros_argv = list(argv)
    args = p.parse_args(remove_ros_args(args=["prog", *argv])[1:])
    return args, ros_argv


RECORDER_SOCKETS_SIZE = 4 * 1024 * 1024
"""Bytes asked for the send and receive buffers of the recorder's UDP sockets (Fast DDS ``sockets_size``).  The
kernel caps the request at ``net.core.rmem_max`` and doubles it: 8 MiB where the maximum allows 4 MiB, 416 KiB on a
default Linux (212992), against 208 KiB unasked.  A burst of small messages (each datagram costs a few KiB of the
buffer) that a starved recorder does not drain in time is dropped by the kernel; its reliable readers then hold
everything after the hole until the writer repairs it at a heartbeat (0.1 s after the burst in the test, but not
before the end of the run, 1 s after its burst, that lost commands this way), and a run ending meanwhile takes those
messages with it."""
RECORDER_TRANSPORTS = f"UDPv4?sockets_size={RECORDER_SOCKETS_SIZE}"
"""The recorder's Fast DDS transports when neither ``--transports`` nor its environment name others: UDP only (see
the module docstring: a starved reader on the shared-memory transport can lose writers for good), with large socket
buffers (:data:`RECORDER_SOCKETS_SIZE`)."""


FASTDDS_TRANSPORTS = ("DEFAULT", "DEFAULTv6", "SHM", "UDPv4", "UDPv6", "LARGE_DATA", "LARGE_DATAv6")
"""Fast DDS's builtin transports values a recorder can hear the graph with (``NONE`` cannot); each may carry
Fast DDS's options (``UDPv4?sockets_size=4194304``, ``LARGE_DATA?max_msg_size=1MB``)."""


def recorder_transports(option: str | None, environ: dict[str, str]) -> str:
    """The Fast DDS builtin transports the recorder's process uses: ``--transports``, else the environment's
    ``FASTDDS_BUILTIN_TRANSPORTS``, else :data:`RECORDER_TRANSPORTS`.  A value Fast DDS does not know (it would fall
    back to its default with a log line) or ``NONE`` raises ``ValueError`` naming where it came from."""
    for value, where in ((option, "--transports"), (environ.get(TRANSPORTS_ENV), TRANSPORTS_ENV)):
        if value is not None and value.strip():
            value = value.strip()
            if value.split("?", 1)[0] not in FASTDDS_TRANSPORTS:
                raise ValueError(f"{where} {value!r}: not a Fast DDS builtin transports value a recorder can use "
                                 f"(one of {', '.join(FASTDDS_TRANSPORTS)})")
            return value
    return RECORDER_TRANSPORTS


NODE_NAME = "recorder"
PARAMETERS: dict[str, tuple[Any, str]] = {  # read-only: a bag is configured when it starts
    "bag_directory": ("", "bag directory to create ('' = bags/bb2_YYYYmmdd_HHMMSS, relative to the working "
                          "directory)"),
    "topics": ([""], "contract topics to record, exact names or regular expressions ([] or [''] = every topic)"),
    "batch_period_s": (0.005, "after taking messages, wait this long (wall s) before the next take: one wake-up "
                              "per batch, not per message; 0 = take each as it arrives; in [0, 1]"),
    "queue_depth": (1000, "subscription queue depth per topic (> 0)"),
    "chunk_size": (256 * 1024, "storage: uncompressed bytes per MCAP chunk, the most a SIGKILL loses (> 0)"),
    "flush_period_s": (1.0, "storage: also close the open chunk every this many wall s (0 = never)"),
    "compression": ("zstd", "storage: chunk compression, zstd | lz4 | '' (none)"),
    "storage_id": ("mcap", "storage: rosbag2 storage plugin id; mcap (the only one written here)"),
    "boats": ([""], "a fleet in one bag: the namespaces of its boats, each recorded as /NS/bb2/... and "
                    "/NS/clock, on its own clock ([] or [''] = the boat of the recorder's namespace)"),
    "tf_from_odom": (True, "write /tf (odom -> base_link) from every /bb2/odom and /tf_static from "
                            "/bb2/sensors/mountings"),
    "overwrite": (False, "allow a non-empty bag_directory"),
    "status_period_s": (1.0, "wall period of the recorder's own status (bb2/recorder on bb2/status and /diagnostics: "
                             "messages and bytes written, messages lost, steps acknowledged; 0 = none)"),
}


def _parameters(node) -> dict[str, Any]:
    """Declare the recorder's parameters (read-only, described) and return their values."""
    from rcl_interfaces.msg import ParameterDescriptor

    out = {}
    for name, (default, desc) in PARAMETERS.items():
        d = ParameterDescriptor(description=desc + " [read-only: fixed at start-up]", read_only=True)
        out[name] = node.declare_parameter(name, default, d).value
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point (``ros2 run bb2_tools recorder``): record until SIGINT/SIGTERM, then finish the bag. Returns
    the exit code (0 done, 1 an error while recording (the bag is still finished), 2 bad input or an OS error such
    as a read-only or full bag folder: one line naming the file).  Configured by its ROS parameters
    (:data:`PARAMETERS`, ``--ros-args -p`` or a params file); a command-line option, when given, wins over its
    parameter."""
    from bb2_sim.outputs import run_cli

    return run_cli("bb2-record", lambda: _main(argv))


def _main(argv: Sequence[str] | None) -> int:
    import rclpy
    from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
    from rclpy.node import Node
    from rclpy.signals import SignalHandlerOptions

    from bb2_msgs_py.ros_env import ros_environment_or_error

    if (bad := ros_environment_or_error("bb2-record")) is not None:  # called directly: find ROS itself
        return bad
    argv = list(sys.argv[1:] if argv is None else argv)
    args, ros_argv = _parse(argv)
    try:
        os.environ[TRANSPORTS_ENV] = recorder_transports(args.transports, dict(os.environ))  # before ROS starts
    except ValueError as exc:
        print(f"bb2-record: error: {exc}", file=sys.stderr)
        return 2
    try:
        rclpy.init(args=[NODE_NAME, *ros_argv], signal_handler_options=SignalHandlerOptions.NO)
    except Exception as exc:  # rcl's own message names the bad params file / argument
        print(f"bb2-record: error: cannot start ROS (bad --ros-args or params file?): {exc}", file=sys.stderr)
        return 2
    node = None
    try:
        node = Node(NODE_NAME)  # with parameter services: spin_once serves them
        if (deaf := discovery_blocked(os.environ, node.context.get_domain_id())) is not None:
            raise ContractError(deaf)
        par = _parameters(node)
        use_sim_time = args.use_sim_time or bool(node.get_parameter("use_sim_time").value)
        topics = args.topics if args.topics is not None else [t for t in par["topics"] if t] or None
        chunk = args.chunk_size if args.chunk_size is not None else par["chunk_size"]
        flush = args.flush_period if args.flush_period is not None else par["flush_period_s"]
        depth = args.depth if args.depth is not None else par["queue_depth"]
        batch = args.batch_period if args.batch_period is not None else par["batch_period_s"]
        boats = [check_namespace(b, "a boat's namespace") for b in (args.boats if args.boats is not None
                                                                     else par["boats"]) if b.strip()]
        if len(set(boats)) != len(boats) or "" in boats:
            raise ContractError(f"the boats must be distinct namespaces other than the root, got {boats}")
        fleet_ns = f"/{boats[0]}" if boats else node.get_namespace()  # a fleet: the boats' topics, not the global
        specs = select_topics(topics) if topics is not None else default_topics(fleet_ns)
        if topics is None and fleet_ns != "/":  # a boat's recorder records its boat
            print(f"bb2-record: in {'the fleet ' + ', '.join(boats) if boats else node.get_namespace()}: not "
                  f"recording {', '.join(GLOBAL_TOPICS)} (every boat's statuses; each boat's are in its bb2/status)",
                  flush=True)
        status_period = float(par["status_period_s"])
        for what, value, ok, rule in (
                ("--chunk-size (parameter chunk_size)", chunk, chunk > 0, "> 0 bytes"),
                ("--depth (parameter queue_depth)", depth, depth > 0, "> 0"),
                ("--flush-period (parameter flush_period_s)", flush, math.isfinite(flush) and flush >= 0, ">= 0 s"),
                ("--batch-period (parameter batch_period_s)", batch, 0 <= batch <= 1, "in [0, 1] s"),
                ("parameter status_period_s", status_period, math.isfinite(status_period) and status_period >= 0,
                 ">= 0 s")):
            if not ok:
                raise ContractError(f"{what} must be {rule}, got {value!r}")
        if par["storage_id"] != "mcap":
            raise ContractError(f"parameter 'storage_id' must be mcap, got {par['storage_id']!r}")
        if par["compression"] not in ("zstd", "lz4", ""):
            raise ContractError(f"parameter 'compression' must be zstd, lz4 or '', got {par['compression']!r}")
        out = args.out or (Path(par["bag_directory"]) if par["bag_directory"]
                           else Path("bags") / time.strftime("bb2_%Y%m%d_%H%M%S"))
        bag = BagWriter(out, chunk_size=int(chunk), compression=par["compression"],
                        overwrite=args.overwrite or par["overwrite"],
                        custom_data={"recorder": "bb2_tools.recorder", "topics": " ".join(s.name for s in specs),
                                     **({"boats": " ".join(boats)} if boats else {})})
    except (ContractError, BagError, InvalidParameterTypeException, InvalidParameterValueException, OSError) as exc:
        from bb2_sim.outputs import os_error_line

        print(f"bb2-record: error: {os_error_line(exc) if isinstance(exc, OSError) else exc}", file=sys.stderr)
        if node is not None:
            node.destroy_node()
        rclpy.shutdown()
        return 2

    stop = threading.Event()

    previous = stop_signals(stop)
    rec = Recorder(bag, specs, tf_from_odom=not args.no_tf and par["tf_from_odom"], flush_period_s=float(flush),
                   queue_depth=int(depth), use_sim_time=use_sim_time, node=node, boats=boats,
                   status_period_s=status_period)
    print(f"bb2-record: recording {len(specs)} topics" + (f" of each of {len(boats)} boats" if boats else "")
          + f" into {out} (Fast DDS transports {os.environ.get(TRANSPORTS_ENV)})", flush=True)
    heap.settle()  # no 30-45 ms collector pause while recording (the simulator may wait for its acks)
    code = 0
    try:
        while not stop.is_set() and rclpy.ok():
            if rec.spin_once(0.05) and batch > 0:
                stop.wait(float(batch))
    except Exception as exc:  # report, then still finish the bag
        print(f"bb2-record: error while recording: {exc!r}", file=sys.stderr)
        code = 1
    finally:
        try:  # what DDS delivered before the stop goes into the bag too (it waits in the readers, untaken), and the
            # recorder's own last statuses (they come back over DDS: at once, in one process)
            rec.stop_statuses()
            deadline = time.monotonic() + DRAIN_TIMEOUT_S
            while time.monotonic() < deadline:
                if rec.spin_once(0.0):
                    continue
                if not rec.own_statuses_pending():
                    break
                rec.spin_once(0.02)
        except Exception as exc:  # noqa: BLE001 - report, then still finish the bag
            print(f"bb2-record: error while taking the last messages: {exc!r}", file=sys.stderr)
            code = 1
        rec.write_publication_counts()
        path = rec.close()
        counts = {n: t.message_count for n, t in bag.topics.items()}
        print(f"bb2-record: wrote {bag.message_count} messages to {path}: {counts}", flush=True)
        g = rec.gaps
        print(f"bb2-record: gaps: {len(g.gaps)} ({g.missing} message(s) lost before reaching the recorder)"
              + "".join(f"\n  {x.describe()}" for x in g.gaps[:20])
              + (f"\n  ... and {len(g.gaps) - 20} more (bag metadata custom_data {GAPS_KEY})" if len(g.gaps) > 20
                 else ""), flush=True)
        if rclpy.ok():
            rclpy.shutdown()
        restore_signals(previous, stop)
    return code


if __name__ == "__main__":
    sys.exit(main())
