"""The BB2 topic contract: topic names, standard message types, QoS, frame ids and units.

Everything in this module is plain data usable without ROS; only :func:`qos_profile` imports
rclpy (inside the function).  The Jazzy wheels here cannot build custom interfaces, so every topic
uses a standard message type.

Frames (REP-103 / REP-105): the world frame is ENU (``map``; ``odom`` coincides with it because the
simulator publishes ground truth), the body frame is ``base_link`` FLU (x forward, y port, z up) at
the centre of gravity.  The marine variants ``map_ned`` (NED) and ``base_link_frd`` (FRD) exist
as an option for consumers that want them (see :mod:`bb2_sim.frames` for the math).

Time stamps: every stamped message carries the simulation time (``/clock`` with use_sim_time).

Lockstep handshake (simulator ``time_mode: lockstep``): for step n the simulator publishes
``/bb2/state_native`` (reliable) at t_n (``/clock`` went to t_n when the step to t_n started); path_following
answers ``/bb2/guidance/rate_cmd`` stamped t_n;
l1_autopilot pairs state and rate command by stamp and answers ``/bb2/autopilot/vh_cmd`` and
``/bb2/propeller/cmd`` stamped t_n; the mixer answers ``/bb2/planes/cmd`` stamped t_n; the simulator
integrates once it holds both commands stamped t_n.  Every topic of the handshake is reliable, so no
sample can be lost to a slow reader (best-effort ``/bb2/odom`` is not part of it); an unanswered state is
re-sent and each stage replays its cached answer for a stamp it has already answered (never stepping its
controller twice); after ``lockstep_timeout_s`` the simulator steps on held commands and says so in
``/bb2/status``.  ``/bb2/state_native`` carries the ROM state in float64 as it is, so the controllers see
exactly the numbers the library runner's stack sees (no quaternion -> Euler rounding).

Names: the nodes name every topic relative to their namespace (:func:`node_topic_name`: ``bb2/odom``), so the
contract's ``/bb2/...`` names are those of the root namespace and a boat started in ``/boat1`` uses
``/boat1/bb2/...``; ``/clock``, ``/diagnostics`` and the tf topics stay absolute (:data:`ABSOLUTE_TOPICS`).
Remapping is the standard ROS 2 one (``--ros-args -r /bb2/odom:=/other``); a rule that names no topic of a
node is reported by the node (an error with its parameter ``strict_remaps: true``).
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any


class ContractError(ValueError):
    """A topic or QoS name that is not part of the contract."""


# ----------------------------------------------------------------------------------------- frames
SCENE_TOPIC = "/bb2/scene/markers"
SEA_SURFACE_TOPIC = "/bb2/scene/sea_surface"
FRAME_MAP = "map"
"""World frame, ENU, origin at the native earth origin (calm surface, z = 0)."""
FRAME_ODOM = "odom"
"""Odometry frame, ENU; identical to ``map`` (ground truth, no drift)."""
FRAME_BASE_LINK = "base_link"
"""Body frame FLU at the CG."""
FRAME_MAP_NED = "map_ned"
"""Optional marine world frame, NED (x north = ENU y, y east = ENU x, z down)."""
FRAME_BASE_LINK_FRD = "base_link_frd"
"""Optional marine body frame FRD at the CG."""
FRAME_NATIVE = "native"
"""The ROM's own frames (earth z up, bow along -x at psi = 0; body x aft / y stbd / z up): see bb2_sim.state."""
FRAME_PATH = "path_frenet"
"""Path frame at the closest path point: x along the path tangent, y left, z up (errors)."""

FRAMES: dict[str, str] = {
    FRAME_MAP: "world, ENU (REP-103), z = 0 on the calm surface",
    FRAME_ODOM: "odometry world frame, ENU, equal to map (simulator ground truth)",
    FRAME_BASE_LINK: "body at the CG, FLU: x forward, y port, z up",
    FRAME_MAP_NED: "optional marine world frame, NED",
    FRAME_BASE_LINK_FRD: "optional marine body frame at the CG, FRD",
    FRAME_PATH: "path (Serret-Frenet-like) frame: x along track, y left, z up",
    FRAME_NATIVE: "ROM native frames: earth z up (bow along -x at psi = 0), body x aft / y stbd / z up",
}

WORLD_FRAMES = frozenset({FRAME_MAP, FRAME_MAP_NED, FRAME_NATIVE})
"""The frames every vehicle of a graph shares (never prefixed); the others (odom, base_link, base_link_frd,
path_frenet, the sensors' frames) are the vehicle's own."""


GLOBAL_TOPICS = ("/diagnostics",)
"""Contract topics every vehicle of a graph shares (never under a boat's namespace): the standard diagnostics topic
carries the statuses of every node of every boat (each also on its boat's ``bb2/status``)."""


def recorded_in_namespace(topic: str, namespace: str) -> bool:
    """Whether a recorder records ``topic`` for the boat in ``namespace`` (``''`` or ``'/'``: the root): every
    contract topic, but a boat of a fleet's recording leaves the global ones out (:data:`GLOBAL_TOPICS`: every
    boat's statuses; the boat's own are on its ``bb2/status``).  The recorder's default topics, and the topics
    whose readers a boat's simulator waits for before its first step."""
    return not (namespace.strip("/") and topic in GLOBAL_TOPICS)


RECORDER_ACK_WINDOW = 10
"""Steps a lockstep simulator with a recorder may run ahead of the recorder's acknowledgement (its parameter
``recorder_ack_window``, as ``bb2-launch`` and the launch files set it): a stalled recorder stops the graph within
half a second of sim time, far inside every writer's history (:data:`QOS`: keep last 100)."""

ABSOLUTE_TOPICS = ("/clock", *GLOBAL_TOPICS, "/tf", "/tf_static")
"""Topics a node names absolutely, whatever its namespace: ``/clock`` (rclpy's time source reads ``/clock``; a boat
with a clock of its own remaps it: ``-r /clock:=/boat1/clock``), the global topics, and the tf topics (one tree for
every vehicle, their frames prefixed: :func:`frame_prefix`)."""


def node_topic_name(name: str) -> str:
    """The name a node creates contract topic ``name`` under: relative to the node's namespace (``bb2/odom``), so
    that in the root namespace it is the contract's ``/bb2/odom`` and a node started in ``/boat1``
    (``--ros-args -r __ns:=/boat1``) reads and writes ``/boat1/bb2/odom``; :data:`ABSOLUTE_TOPICS` stay absolute.
    A remap rule names the resolved topic (``-r /bb2/odom:=/other`` in the root namespace)."""
    return name if name in ABSOLUTE_TOPICS or not name.startswith("/") else name[1:]


def boat_topic(name: str, namespace: str) -> str:
    """The resolved name of contract topic ``name`` for a boat whose nodes run in ``namespace`` with a clock of its
    own (``bb2-launch --namespace``, the launch files' ``namespace``): ``/boat1/bb2/odom``, ``/boat1/clock``; the
    global and tf topics (:data:`ABSOLUTE_TOPICS` but ``/clock``) and every name in the root namespace unchanged."""
    ns = namespace.strip("/")
    if not ns or (name in ABSOLUTE_TOPICS and name != "/clock"):
        return name
    return f"/{ns}{name}"


def frame_prefix(namespace: str) -> str:
    """The prefix of the frame ids of a vehicle whose nodes run in ``namespace``: ``""`` in the root namespace (the
    single-vehicle frames unchanged), ``"boat1/"`` in ``/boat1`` (``boat1/base_link``, ``boat1/odom`` under ``map``:
    REP-105's multi-robot convention; tf2 frame ids carry no leading slash)."""
    ns = namespace.strip("/")
    return f"{ns}/" if ns else ""


NAMESPACE_SEGMENT = re.compile(r"[A-Za-z][A-Za-z0-9_]*")


def check_namespace(namespace: str, what: str = "namespace") -> str:
    """``namespace`` without its slashes (``''`` for the root namespace); a :class:`ContractError` naming the rule
    (and ``what`` was given) when it is not a ROS 2 namespace: segments of letters, digits and underscores, each
    starting with a letter."""
    ns = namespace.strip().strip("/")
    if ns and not all(NAMESPACE_SEGMENT.fullmatch(p) for p in ns.split("/")):
        raise ContractError(f"{what} must be a ROS 2 namespace (segments of letters, digits and '_', each "
                            f"starting with a letter, separated by '/'), got {namespace!r}")
    return ns


def vehicle_frame(frame: str, prefix: str = "") -> str:
    """``frame`` of the vehicle whose frame ids carry ``prefix`` (:func:`frame_prefix`); a world frame
    (:data:`WORLD_FRAMES`) is returned as it is."""
    return frame if not prefix or frame in WORLD_FRAMES else prefix + frame


STATE_NATIVE_LABEL = "t_x_y_z_phi_theta_psi_u_v_w_p_q_r"
"""``layout.dim[0].label`` of ``/bb2/state_native``: data = [t (s), x12 native (m, rad, m/s, rad/s)]."""
BERNSTEIN_POINTS_LABEL = "control_points"
"""``layout.dim[0].label`` of ``/bb2/path/bernstein``; ``dim[1].label`` is the path frame
(``native``, ``controller``, ``enu``, ``ned``); ``data_offset`` = 2 and data = [t0, tf, c00, c01, c02, c10, ...]."""

PLANE_JOINTS: tuple[str, ...] = ("delta1", "delta2", "delta3", "delta4", "delta5")
"""Joint names of the five control planes in JointState messages (rad, ROM sign convention)."""
PROPELLER_JOINT = "propeller"
"""Joint name of the propeller in JointState messages (velocity, rad/s)."""
VH_JOINTS: tuple[str, ...] = ("delta_V", "delta_H")
"""Joint names of the virtual vertical/horizontal plane commands of the autopilot (rad)."""


# ----------------------------------------------------------------------------------------- QoS
@dataclass(frozen=True)
class QosDescription:
    """A QoS profile as plain data (the names rosbag2 writes in metadata version 9)."""

    reliability: str  # "reliable" | "best_effort"
    durability: str  # "volatile" | "transient_local"
    history: str  # "keep_last" | "keep_all"
    depth: int
    #: the readers' reliability when it differs from the writer's ("" = the same): a reliable writer with
    #: best-effort readers serves both kinds of subscriber (a reliable reader needs a reliable writer)
    reader_reliability: str = ""
    #: the readers' durability when it differs from the writer's ("" = the same): a transient-local writer
    #: serves volatile readers (our nodes: only what comes after they match) and transient-local ones (the
    #: recorder: also the history it missed before it matched)
    reader_durability: str = ""

    def as_dict(self) -> dict[str, Any]:
        return {"reliability": self.reliability, "durability": self.durability,
                "history": self.history, "depth": self.depth}


QOS: dict[str, QosDescription] = {
    # vehicle state and sensors: written reliable (keep last 100) so that a subscriber with the default reliable
    # QoS (RViz, `ros2 topic echo --qos-reliability reliable`) and a best-effort one (qos_profile_sensor_data)
    # both receive them; our controllers read best effort, as sensor data is read, and so also match a
    # best-effort publisher (an external simulator, a HIL bench); the recorder reads reliable (what the writers
    # offer, as rosbag2 does), so that a recorder stalled for up to its lockstep window (10 steps, the
    # simulator's recorder_ack_window) loses nothing: the writer keeps 100 (a sample dropped in transport on a
    # loaded machine is repaired from it; 20 was measured too few); measured cost in lockstep: README "QoS choices"
    "sensor": QosDescription("reliable", "volatile", "keep_last", 100, reader_reliability="best_effort"),
    # commands, guidance outputs and the lockstep state: every sample matters; the writer keeps 100
    # samples so a reader that is not part of the lockstep handshake (recorder, test, tool) may lag 100
    # steps without losing one (reliable keep-last drops unacknowledged samples beyond the depth); written
    # transient local, so the recorder (which asks for it) also gets the answers a controller sent before
    # the two matched (the first steps of a loaded start), while our nodes read volatile (never an old sample)
    "command": QosDescription("reliable", "transient_local", "keep_last", 100, reader_durability="volatile"),
    # paths are latched so a late subscriber (RViz, recorder) gets the current path
    "latched": QosDescription("reliable", "transient_local", "keep_last", 1),
    # /clock: read as rclcpp::ClockQoS (best effort, what every node's time source asks for) and written
    # reliable keep last 100 (as the sensors), which serves those readers and lets the recorder read it reliable
    "clock": QosDescription("reliable", "volatile", "keep_last", 100, reader_reliability="best_effort"),
    # /tf as tf2_ros::DynamicBroadcasterQoS writes it (bags only: the recorder's, from /bb2/odom)
    "tf": QosDescription("reliable", "volatile", "keep_last", 100),
    # /tf_static as tf2_ros::StaticBroadcasterQoS writes it (bags only: the recorder's, from the sensor mountings)
    "tf_static": QosDescription("reliable", "transient_local", "keep_last", 1),
    # status / diagnostics
    # (written transient local as the commands: the recorder gets a node's first statuses even when it matched
    # that node after they went out; readers ask for volatile)
    "status": QosDescription("reliable", "transient_local", "keep_last", 10, reader_durability="volatile"),
    # the sensor models' measurements (/bb2/sensors/*): several samples of a sensor may go out in one ROM step
    # (an IMU at 200 Hz: 10 per 0.05 s), so the writer is reliable and keeps 100; a best-effort reader
    # (qos_profile_sensor_data) matches it as well as a reliable one
    "measurement": QosDescription("reliable", "volatile", "keep_last", 100),
}


# ----------------------------------------------------------------------------------------- topics
@dataclass(frozen=True)
class TopicSpec:
    """One row of the contract."""

    name: str
    type: str  # ROS 2 type name, "pkg/msg/Type"
    qos: str  # key of QOS
    frame: str
    units: str
    publisher: str
    subscribers: tuple[str, ...]
    description: str
    bag_only: bool = False  # written into bags only (e.g. /tf: tf2_msgs is not in the wheels)

    @property
    def qos_description(self) -> QosDescription:
        return QOS[self.qos]


SIM = "simulator"
PLANNER = "planner"
PATHF = "path_following"
AUTOPILOT = "l1_autopilot"
MIXER = "mixer"
RECORDER = "recorder"
EXTERNAL = "(external tools)"
EVERY_NODE = "(every node)"   # a publisher: each node of the graph publishes its own status there

CONTRACT: tuple[TopicSpec, ...] = (
    TopicSpec("/clock", "rosgraph_msgs/msg/Clock", "clock", "-", "s (sim time)", SIM,
              (PLANNER, PATHF, AUTOPILOT, MIXER, RECORDER), "simulation time (use_sim_time)"),
    TopicSpec("/bb2/odom", "nav_msgs/msg/Odometry", "sensor", "odom -> base_link",
              "m, quaternion; m/s, rad/s (twist in base_link)", SIM, (PATHF, AUTOPILOT, RECORDER),
              "ground-truth pose (ENU) and body twist (FLU) of the CG"),
    TopicSpec("/bb2/imu", "sensor_msgs/msg/Imu", "sensor", "base_link",
              "quaternion; rad/s; m/s^2 (specific force, includes gravity reaction)", SIM,
              (AUTOPILOT, RECORDER), "IMU at the CG: orientation, angular velocity, specific force"),
    TopicSpec("/bb2/depth", "sensor_msgs/msg/FluidPressure", "sensor", "base_link",
              "Pa (absolute: p_atm + rho g depth)", SIM, (AUTOPILOT, RECORDER),
              "pressure depth sensor at the CG"),
    TopicSpec("/bb2/altitude", "sensor_msgs/msg/Range", "sensor", "base_link",
              "m (float32), range to the bottom straight down", SIM, (PATHF, RECORDER),
              "altimeter; +inf when no bottom within max_range"),
    TopicSpec("/bb2/planes/state", "sensor_msgs/msg/JointState", "sensor", "base_link",
              "rad (position), rad/s (velocity)", SIM, (RECORDER,),
              "actual deflections delta1..delta5 after the actuator model"),
    TopicSpec("/bb2/propeller/state", "sensor_msgs/msg/JointState", "sensor", "base_link",
              "rad/s (velocity)", SIM, (RECORDER,), "actual propeller shaft speed"),
    TopicSpec("/bb2/planes/cmd", "sensor_msgs/msg/JointState", "command", "base_link",
              "rad (position)", MIXER, (SIM, RECORDER),
              "commanded deflections delta1..delta5 (stamp checked for staleness)"),
    TopicSpec("/bb2/propeller/cmd", "sensor_msgs/msg/JointState", "command", "base_link",
              "rad/s (velocity)", AUTOPILOT, (SIM, RECORDER), "commanded propeller shaft speed"),
    TopicSpec("/bb2/state_native", "std_msgs/msg/Float64MultiArray", "command", FRAME_NATIVE,
              "[t s, x y z m, phi theta psi rad, u v w m/s, p q r rad/s] (float64, exact)", SIM,
              (PATHF, AUTOPILOT, RECORDER),
              "exact ROM state of every step, reliable: what the controllers run on and the lockstep trigger"),
    TopicSpec("/bb2/nav/state_native", "std_msgs/msg/Float64MultiArray", "command", FRAME_NATIVE,
              "[t s, x12 as /bb2/state_native] (float64): the navigation estimate", SIM,
              (PATHF, AUTOPILOT, RECORDER),
              "with navigation: sensors, the navigation filter's estimate at every step (bb2_control.navigation, "
              "from the sensor suite's samples), published with /bb2/state_native: what the controllers fly on"),
    TopicSpec("/bb2/path", "nav_msgs/msg/Path", "latched", "map", "m (ENU), quaternion (path tangent)",
              PLANNER, (PATHF, RECORDER), "Bernstein path samples"),
    TopicSpec("/bb2/path/bernstein", "std_msgs/msg/Float64MultiArray", "latched", "dim[1].label (path frame)",
              "[t0 s, tf s, control points m row-major] (data_offset 2, float64, exact)", PLANNER,
              (PATHF, RECORDER), "the exact Bernstein path: control points and time span"),
    TopicSpec("/bb2/guidance/rate_cmd", "geometry_msgs/msg/Vector3Stamped", "command", "base_link",
              "rad/s: x = 0, y = -q_c, z = r_c (FLU body rates)", PATHF, (AUTOPILOT, RECORDER),
              "path-following pitch/yaw rate commands"),
    TopicSpec("/bb2/guidance/path_error", "geometry_msgs/msg/Vector3Stamped", "command", FRAME_PATH,
              "m: x along track, y cross track (left), z vertical (up)", PATHF, (RECORDER,),
              "vehicle position minus closest path point, in the path frame"),
    TopicSpec("/bb2/mission/progress", "std_msgs/msg/Float64", "command", "-", "1 (0..1)", PATHF,
              (SIM, RECORDER), "fraction of the path length travelled (the simulator reads it with end_at_progress)"),
    TopicSpec("/bb2/autopilot/vh_cmd", "sensor_msgs/msg/JointState", "command", "base_link",
              "rad (position of delta_V, delta_H)", AUTOPILOT, (MIXER, RECORDER),
              "virtual vertical/horizontal plane commands"),
    TopicSpec("/bb2/sea", "std_msgs/msg/String", "latched", FRAME_NATIVE,
              "JSON (format bb2_sea/1): the sea: and current: blocks as given (m, s, deg) and the realised wave "
              "components (amplitude_m, omega_rad_s, direction_rad, phase_rad)", SIM, (RECORDER,),
              "the sea and current of the run, latched: a run's sea can be rebuilt from its bag alone "
              "(bb2_sim.environment.environment_from_description)"),
    TopicSpec("/bb2/status", "diagnostic_msgs/msg/DiagnosticArray", "status", "-",
              "key/values (mode, failsafe, rates, overruns)", EVERY_NODE, (RECORDER,),
              "what the simulator (and each node) is doing"),
    TopicSpec("/diagnostics", "diagnostic_msgs/msg/DiagnosticArray", "status", "-",
              "key/values, as /bb2/status", EVERY_NODE, (RECORDER, EXTERNAL),
              "the same statuses on the standard ROS diagnostics topic (rqt_robot_monitor, diagnostic_aggregator)"),
    # the sensor models (bb2_sim.sensors; the mission's sensors: block): measurements with honest covariances,
    # each at its own rate, stamped with its time of validity, in its mounting frame (SENSOR_FRAMES)
    TopicSpec("/bb2/sensors/imu", "sensor_msgs/msg/Imu", "measurement", "imu_link",
              "quaternion (imu_link in map, ENU: REP-145); rad/s; m/s^2 (specific force); covariances", SIM,
              (RECORDER, EXTERNAL), "IMU: gyros, accelerometers (noise, biases, scale, misalignment), AHRS attitude"),
    TopicSpec("/bb2/sensors/pressure", "sensor_msgs/msg/FluidPressure", "measurement", "pressure_link",
              "Pa (absolute: the day's atmosphere + water column incl. the wave pressure); variance Pa^2", SIM,
              (RECORDER, EXTERNAL), "pressure (depth) sensor: noise, resolution, zero offset"),
    TopicSpec("/bb2/sensors/dvl", "geometry_msgs/msg/TwistWithCovarianceStamped", "measurement", "dvl_link",
              "m/s, velocity of the DVL over the bottom in dvl_link; covariance (angular block -1: not measured)",
              SIM, (RECORDER, EXTERNAL), "DVL bottom track: only while the DVL has bottom lock"),
    TopicSpec("/bb2/sensors/dvl/water_track", "geometry_msgs/msg/TwistWithCovarianceStamped", "measurement",
              "dvl_link", "m/s, velocity of the DVL through the water in dvl_link; covariance", SIM,
              (RECORDER, EXTERNAL), "DVL water track: the pings without bottom lock (beyond range, large attitude)"),
    TopicSpec("/bb2/sensors/dvl/ranges", "sensor_msgs/msg/Range", "measurement", "dvl_beam_0 .. dvl_beam_3",
              "m (float32) slant range along each beam (x of its frame); +inf no echo (REP-117)", SIM,
              (RECORDER, EXTERNAL), "DVL per-beam ranges: one message per beam per ping"),
    TopicSpec("/bb2/sensors/altimeter", "sensor_msgs/msg/Range", "measurement", "altimeter_link",
              "m (float32) along the boresight (x of altimeter_link, down); +inf beyond max range (REP-117)", SIM,
              (RECORDER, EXTERNAL), "altimeter: noise, max range, dropped pings (no message)"),
    TopicSpec("/bb2/sensors/gps", "sensor_msgs/msg/NavSatFix", "measurement", "gps_link",
              "deg, deg, m (ellipsoidal); ENU covariance m^2; status NO_FIX (-1) under water / before the first fix",
              SIM, (RECORDER, EXTERNAL), "GPS at the sail top: a fix only while the antenna is above the surface"),
    TopicSpec("/bb2/sensors/mountings", "std_msgs/msg/String", "latched", "base_link",
              "JSON (format bb2_sensor_mountings/1): frame, parent base_link, translation m, quaternion (x, y, z, w), "
              "rate_hz per sensor; the suite and its seed", SIM, (RECORDER, EXTERNAL),
              "the sensors' mountings (the /tf_static of the suite: tf2_msgs is not in the wheels) and rates"),
    TopicSpec(SCENE_TOPIC, "visualization_msgs/msg/MarkerArray", "latched", "base_link (hull); map (terrain, sea)",
              "m: TRIANGLE_LIST markers, ns bb2/hull, bb2/terrain, bb2/sea_surface (calm: the plane z = 0)", SIM,
              (RECORDER, EXTERNAL), "the scene for RViz / Foxglove, once at start: the ROM's own hull surfaces, the "
              "mission's terrain (bb2_msgs_py.scene_markers)"),
    TopicSpec(SEA_SURFACE_TOPIC, "visualization_msgs/msg/MarkerArray", "measurement", "map",
              "m: a TRIANGLE_LIST (ns bb2/sea_surface), the free-surface elevation on a 160 m square around the CG",
              SIM, (RECORDER, EXTERNAL), "the wavy sea around the boat every scene_sea_period_s of sim time "
              "(simulator parameter; waves only)"),
    TopicSpec("/bb2/recorder/ack", "std_msgs/msg/Header", "command", "-",
              "stamp: sim time up to which the recorder holds every per-step topic of the simulator", RECORDER,
              (SIM, RECORDER),
              "the recorder's acknowledgement, after each batch it wrote: in lockstep with recorder_ack_window > 0 "
              "the simulator steps at most that many steps ahead of it (a stalled recorder slows the graph, "
              "loses nothing)"),
    TopicSpec("/tf", "tf2_msgs/msg/TFMessage", "tf", "odom -> base_link", "m, quaternion",
              RECORDER, (EXTERNAL,), "derived from /bb2/odom by the recorder (bags only)",
              bag_only=True),
    TopicSpec("/tf_static", "tf2_msgs/msg/TFMessage", "tf_static", "base_link -> <sensor>_link", "m, quaternion",
              RECORDER, (EXTERNAL,), "the sensor mountings (and DVL beams) from /bb2/sensors/mountings, written by "
              "the recorder (bags only)", bag_only=True),
)

_BY_NAME = {t.name: t for t in CONTRACT}


def topic(name: str) -> TopicSpec:
    """The contract row of a topic, or :class:`ContractError`."""
    try:
        return _BY_NAME[name]
    except KeyError:
        raise ContractError(f"unknown topic {name!r}; the contract has: {', '.join(_BY_NAME)}") from None


def node_interface(node: str) -> tuple[list[TopicSpec], list[TopicSpec]]:
    """What graph node ``node`` publishes and what it may read, by the contract: what a node of a user's own in its
    place (``bb2-launch --without``) publishes and reads.  The statuses every node publishes are left out;
    some inputs are read only in some settings (``/bb2/odom`` with ``state_source: odometry``, ``/bb2/nav/...`` with
    ``navigation: sensors``)."""
    return ([t for t in CONTRACT if t.publisher == node and not t.bag_only],
            [t for t in CONTRACT if node in t.subscribers and not t.bag_only])


def select_topics(patterns: list[str] | None = None, *, include_bag_only: bool = False) -> list[TopicSpec]:
    """Contract topics matching any of ``patterns`` (exact names or regular expressions, full match).

    ``None`` or an empty list selects every topic.  A pattern that matches nothing is an error
    (it is almost always a typo).
    """
    rows = [t for t in CONTRACT if include_bag_only or not t.bag_only]
    if not patterns:
        return rows
    out: list[TopicSpec] = []
    for pat in patterns:
        try:
            rx = re.compile(pat)
        except re.error as exc:
            raise ContractError(f"bad topic pattern {pat!r}: {exc}") from None
        hits = [t for t in rows if t.name == pat or rx.fullmatch(t.name)]
        if not hits:
            raise ContractError(f"topic pattern {pat!r} matches no contract topic")
        out.extend(t for t in hits if t not in out)
    return out


def qos_profile(name: str, *, reader: bool = False):
    """The rclpy ``QoSProfile`` of a topic (by topic name) or of a QoS key of :data:`QOS`: the writer's, or with
    ``reader`` the subscription's (they differ in reliability for the state topics, see :data:`QOS`)."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    if name in QOS:
        desc = QOS[name]
    else:
        desc = topic(name).qos_description
    reliability = (desc.reader_reliability or desc.reliability) if reader else desc.reliability
    durability = (desc.reader_durability or desc.durability) if reader else desc.durability
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST if desc.history == "keep_last" else HistoryPolicy.KEEP_ALL,
        depth=desc.depth,
        reliability=(ReliabilityPolicy.RELIABLE if reliability == "reliable"
                     else ReliabilityPolicy.BEST_EFFORT),
        durability=(DurabilityPolicy.TRANSIENT_LOCAL if durability == "transient_local"
                    else DurabilityPolicy.VOLATILE),
    )


def message_class(type_name: str):
    """The Python message class of a ``pkg/msg/Type`` name (imports the ROS message package)."""
    import importlib

    parts = type_name.split("/")
    if len(parts) != 3 or parts[1] != "msg":
        raise ContractError(f"not a message type name 'pkg/msg/Type': {type_name!r}")
    try:
        return getattr(importlib.import_module(f"{parts[0]}.msg"), parts[2])
    except (ImportError, AttributeError):
        raise ContractError(f"message type {type_name!r} is not installed") from None


def contract_markdown(*, include_bag_only: bool = True) -> str:
    """The contract as a Markdown table (for the README)."""
    head = ("| topic | type | QoS | frame | units | publisher | subscribers |\n"
            "|---|---|---|---|---|---|---|\n")
    rows = []
    for t in CONTRACT:
        if t.bag_only and not include_bag_only:
            continue
        q = t.qos_description
        readers = ", ".join(x for x in (q.reader_reliability, q.reader_durability) if x)
        qos = f"{q.reliability}, {q.durability}, {q.history} {q.depth}" + (f" (readers: {readers})" if readers else "")
        rows.append(f"| `{t.name}` | `{t.type}` | {qos} | {t.frame} | {t.units} | {t.publisher} | "
                    f"{', '.join(t.subscribers)} |")
    return head + "\n".join(rows) + "\n"
