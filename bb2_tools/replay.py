"""``bb2-replay BAG``: republish a recorded run, or feed its commands back into the simulator (open loop).

**Replay** (default): every recorded topic is republished *raw* (the CDR bytes of the bag, untouched)
with the QoS its publishers offered when it was recorded (the ``offered_qos_profiles`` of the bag), in
log-time order, paced on the wall clock at ``--rate`` times the recorded speed; ``/clock`` carries the
playback time (the bag's log time, i.e. the simulation time for bags of ``bb2-launch``), so nodes with
``use_sim_time`` run on the recorded time.  A ``/clock`` recorded in the bag is not republished
(the player publishes its own, as ``ros2 bag play --clock`` does; ``--no-clock`` republishes the
recorded one instead, if selected).  ``/tf`` (``tf2_msgs``, not installed here) is skipped with a note.

Pause / resume while playing:

* ``kill -USR1 <pid>`` toggles pause (the pid is printed at start);
* the service ``/bb2_replay/pause`` (``std_srvs/srv/SetBool``): ``data: true`` pauses, ``false``
  resumes, e.g. ``ros2 service call /bb2_replay/pause std_srvs/srv/SetBool "{data: true}"``;
* ``--pause`` starts paused.

While paused the playback time (and ``/clock``) stands still.

**Open loop** (``--open-loop``): no ROS at all.  The recorded plane and propeller commands
(``/bb2/planes/cmd``, ``/bb2/propeller/cmd``) are fed into the library :class:`bb2_sim.integrator.Simulator`
built by the mission factory (the very object the simulator node integrates), with the simulator node's
validation (non-finite / wrong joints / wrong frame rejected, out-of-range clamped).  The command of step
``t_n`` is the one stamped ``t_n`` (lockstep); without one the last valid command is held (as the node does
in real time), else neutral planes and the mission's nominal propeller.  The resulting states are compared
with the recorded ``/bb2/state_native`` (exact; else ``/bb2/odom``) at the same stamps: for a lockstep
recording the deviation is 0 (bit for bit); for a real-time recording it is not, because the node applied
each command when it *arrived* on the wall clock, which the bag does not carry exactly.

The mission is ``--mission FILE.yaml`` or, if not given, the ``mission_file`` the simulator reported in
the recorded ``/bb2/status``.  The sea and current are the bag's own (the latched ``/bb2/sea`` description,
rebuilt exactly by :func:`bb2_sim.environment.environment_from_description`) when it has one, so a run in
waves replays bit for bit even with a sea file or node parameter the mission does not name.

Exit status: 0 done; 1 runtime error; 2 bad input (bag, topics, options); 3 open-loop deviation above
``--max-deviation``.

Usage::

    bb2-replay BAG [--rate R] [--start-offset S] [--topics T ...] [--pause] [--loop] [--domain-id N]
               [--wait-for-readers S] [--delay S] [--no-clock]
    bb2-replay BAG --open-loop [--mission FILE.yaml] [--start-offset S] [--max-deviation M]
"""
from __future__ import annotations

import argparse
import math
import os
import re
import signal
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Sequence

import numpy as np

from bb2_tools.bagfile import BagError, BagReader, TopicInfo

__all__ = ["ReplayError", "PlaybackClock", "replay_qos", "select_bag_topics", "Player", "OpenLoopResult",
           "open_loop", "main"]

CLOCK_TOPIC = "/clock"
PLANES_CMD = "/bb2/planes/cmd"
PROPELLER_CMD = "/bb2/propeller/cmd"
STATE_NATIVE = "/bb2/state_native"
ODOM = "/bb2/odom"
STATUS = "/bb2/status"
SEA = "/bb2/sea"
PAUSE_SERVICE = "/bb2_replay/pause"
NODE_NAME = "bb2_replay"


class ReplayError(ValueError):
    """A bag, topic selection or option that cannot be replayed as asked."""


# ----------------------------------------------------------------------------------------- time
class PlaybackClock:
    """Bag time <-> wall time at a rate factor, with pause/resume (thread-safe).

    ``bag_time_ns(now)`` is the playback time at wall time ``now`` (monotonic seconds): it advances at
    ``rate`` bag seconds per wall second from ``start_ns`` and stands still while paused.
    """

    def __init__(self, start_ns: int, rate: float, *, paused: bool = False, now: float | None = None):
        if not (rate > 0 and math.isfinite(rate)):
            raise ReplayError(f"--rate must be > 0 and finite, got {rate!r}")
        self.rate = float(rate)
        self._lock = threading.Lock()
        now = time.monotonic() if now is None else now
        self._anchor_ns = int(start_ns)  # bag time at the anchor
        self._anchor_wall = now
        self._paused = bool(paused)

    @property
    def paused(self) -> bool:
        return self._paused

    def bag_time_ns(self, now: float | None = None) -> int:
        now = time.monotonic() if now is None else now
        with self._lock:
            if self._paused:
                return self._anchor_ns
            return self._anchor_ns + int(round((now - self._anchor_wall) * self.rate * 1e9))

    def wall_for(self, t_ns: int) -> float:
        """Wall time (monotonic s) at which bag time ``t_ns`` is reached; ``inf`` while paused."""
        with self._lock:
            if self._paused:
                return math.inf
            return self._anchor_wall + (int(t_ns) - self._anchor_ns) * 1e-9 / self.rate

    def set_paused(self, paused: bool, now: float | None = None) -> bool:
        """Pause or resume; returns whether the state changed."""
        now = time.monotonic() if now is None else now
        t = self.bag_time_ns(now)
        with self._lock:
            if paused == self._paused:
                return False
            self._anchor_ns, self._anchor_wall, self._paused = t, now, bool(paused)
            return True

    def toggle(self, now: float | None = None) -> bool:
        """Toggle pause; returns the new paused state."""
        self.set_paused(not self._paused, now)
        return self._paused

    def restart(self, start_ns: int, now: float | None = None) -> None:
        """Jump to ``start_ns`` (loop), keeping the paused state."""
        now = time.monotonic() if now is None else now
        with self._lock:
            self._anchor_ns, self._anchor_wall = int(start_ns), now


# ----------------------------------------------------------------------------------------- QoS / topics
@dataclass(frozen=True)
class ReplayQos:
    """The QoS the player offers for a topic (plain data)."""

    reliability: str  # "reliable" | "best_effort"
    durability: str  # "volatile" | "transient_local"
    depth: int

    def profile(self):
        from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

        return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=self.depth,
                          reliability=(ReliabilityPolicy.RELIABLE if self.reliability == "reliable"
                                       else ReliabilityPolicy.BEST_EFFORT),
                          durability=(DurabilityPolicy.TRANSIENT_LOCAL if self.durability == "transient_local"
                                      else DurabilityPolicy.VOLATILE))


def replay_qos(info: TopicInfo, *, min_depth: int = 10) -> ReplayQos:
    """The QoS to republish a recorded topic with, as rosbag2's player adapts it.

    Reliable only if every recorded publisher offered reliable, transient local only if every one did
    (so every subscriber that matched a recorded publisher matches the player); depth the largest recorded
    depth, at least ``min_depth``.  Without recorded QoS: the contract's QoS if the topic is a contract
    topic, else reliable, volatile.
    """
    offered = [q for q in info.offered_qos if isinstance(q, dict)]
    if not offered:
        try:
            from bb2_msgs_py.contract import topic

            d = topic(info.name).qos_description
            return ReplayQos(d.reliability, d.durability, max(d.depth, min_depth))
        except ValueError:
            return ReplayQos("reliable", "volatile", min_depth)
    rel = "reliable" if all(q.get("reliability") == "reliable" for q in offered) else "best_effort"
    dur = "transient_local" if all(q.get("durability") == "transient_local" for q in offered) else "volatile"
    depth = max([int(q.get("depth", 0) or 0) for q in offered] + [min_depth])
    return ReplayQos(rel, dur, depth)


def select_bag_topics(bag_topics: Iterable[str], patterns: Sequence[str] | None) -> list[str]:
    """Bag topics matching any of ``patterns`` (exact names or full-match regular expressions; all if none).

    A pattern matching no topic of the bag is an error (it is almost always a typo).
    """
    names = sorted(bag_topics)
    if not patterns:
        return names
    out: list[str] = []
    for pat in patterns:
        try:
            rx = re.compile(pat)
        except re.error as exc:
            raise ReplayError(f"bad topic pattern {pat!r}: {exc}") from None
        hits = [n for n in names if n == pat or rx.fullmatch(n)]
        if not hits:
            raise ReplayError(f"topic {pat!r} matches no topic of the bag (it has {', '.join(names)})")
        out.extend(h for h in hits if h not in out)
    return out


def _first_log_time(reader: BagReader) -> int | None:
    for m in reader.raw_messages():
        return m.log_time_ns
    return None


# ----------------------------------------------------------------------------------------- player
@dataclass
class PlayStats:
    published: dict[str, int] = field(default_factory=dict)
    clock_published: int = 0
    loops: int = 0
    skipped_topics: dict[str, str] = field(default_factory=dict)


class Player:
    """Republishes a bag on an rclpy node of its own (``self.node``); :meth:`play` runs in the caller's thread.

    ``topics``: bag topics to republish (see :func:`select_bag_topics`); ``clock``: publish ``/clock``
    with the playback time (and skip a recorded ``/clock``).
    """

    def __init__(self, reader: BagReader, topics: Sequence[str], *, rate: float = 1.0, start_offset_s: float = 0.0,
                 paused: bool = False, loop: bool = False, clock: bool = True, context=None):
        from rclpy.node import Node
        from std_srvs.srv import SetBool

        from bb2_msgs_py.contract import ContractError, message_class, qos_profile

        if not (start_offset_s >= 0 and math.isfinite(start_offset_s)):
            raise ReplayError(f"--start-offset must be >= 0 s, got {start_offset_s!r}")
        self.reader, self.loop, self.clock_on = reader, bool(loop), bool(clock)
        first = _first_log_time(reader)
        if first is None:
            raise ReplayError(f"bag {reader.mcap_path} holds no message")
        self.start_ns = first + int(round(start_offset_s * 1e9))
        end = reader.end_time_ns()
        if self.start_ns > end:
            raise ReplayError(f"--start-offset {start_offset_s:g} s is past the bag's end: it spans "
                              f"{(end - first) * 1e-9:.3f} s from its first message")
        self.clock = PlaybackClock(self.start_ns, rate, paused=paused)
        self.stats = PlayStats()
        self.node = Node(NODE_NAME, context=context)
        infos = {t.name: t for t in reader.topic_infos()}
        self.pubs: dict[str, Any] = {}
        for name in topics:
            if name == CLOCK_TOPIC and self.clock_on:
                continue  # the player's own /clock replaces the recorded one
            info = infos[name]
            try:
                cls = message_class(info.type)
            except ContractError as exc:
                self.stats.skipped_topics[name] = str(exc)
                continue
            self.pubs[name] = self.node.create_publisher(cls, name, replay_qos(info).profile())
        self.topics = list(self.pubs)
        self.clock_pub = (self.node.create_publisher(message_class("rosgraph_msgs/msg/Clock"), CLOCK_TOPIC,
                                                     qos_profile("clock")) if self.clock_on else None)
        self.srv = self.node.create_service(SetBool, PAUSE_SERVICE, self._on_pause)
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._last_clock_ns = -1

    # -- control
    def set_paused(self, paused: bool) -> None:
        if self.clock.set_paused(paused):
            t = self.clock.bag_time_ns() * 1e-9
            self.node.get_logger().info(f"{'paused' if paused else 'resumed'} at bag time {t:.3f} s")
        self._wake.set()

    def toggle(self) -> None:
        self.set_paused(not self.clock.paused)

    def stop(self) -> None:
        self._stop.set()
        self._wake.set()

    def _on_pause(self, request, response):
        self.set_paused(bool(request.data))
        response.success = True
        response.message = (f"{'paused' if self.clock.paused else 'playing'} at bag time "
                            f"{self.clock.bag_time_ns() * 1e-9:.6f} s")
        return response

    # -- playing
    def _wait_until(self, t_ns: int) -> bool:
        """Sleep until bag time ``t_ns`` is due (pauses honoured); False when stopped."""
        while not self._stop.is_set():
            due = self.clock.wall_for(t_ns) - time.monotonic()
            if due <= 0:
                return True
            self._wake.wait(min(due, 0.1))
            self._wake.clear()
        return False

    def _publish_clock(self, t_ns: int) -> None:
        if self.clock_pub is None or t_ns <= self._last_clock_ns:
            return
        from rosgraph_msgs.msg import Clock

        from bb2_ros.node_common import time_msg

        self.clock_pub.publish(Clock(clock=time_msg(t_ns)))
        self._last_clock_ns = t_ns
        self.stats.clock_published += 1

    def play(self) -> PlayStats:
        """Play to the end (or forever with ``loop``) unless :meth:`stop` is called."""
        clock_only = not self.pubs and self.clock_pub is not None  # e.g. --topics /clock: the playback clock
        if not self.pubs and not clock_only:
            return self.stats
        while not self._stop.is_set():
            self._last_clock_ns = -1
            for m in self.reader.raw_messages(None if clock_only else self.topics):
                if m.log_time_ns < self.start_ns or (m.topic not in self.pubs and not clock_only):
                    continue
                if not self._wait_until(m.log_time_ns):
                    return self.stats
                self._publish_clock(m.log_time_ns)
                if m.topic in self.pubs:
                    self.pubs[m.topic].publish(m.data)
                    self.stats.published[m.topic] = self.stats.published.get(m.topic, 0) + 1
            if not self.loop:
                break
            self.stats.loops += 1
            self.clock.restart(self.start_ns)
        return self.stats

    def drain(self, timeout_s: float = 1.0) -> None:
        """Wait (bounded) until reliable subscribers acknowledged what was published."""
        from rclpy.duration import Duration

        for pub in list(self.pubs.values()):
            try:
                pub.wait_for_all_acked(Duration(seconds=timeout_s))
            except Exception:  # best effort publishers, or an rmw without the call
                pass


# ----------------------------------------------------------------------------------------- open loop
@dataclass
class OpenLoopResult:
    """Outcome of :func:`open_loop` (deviations of the re-simulated from the recorded state)."""

    mission_file: str
    reference_topic: str
    steps: int
    compared: int
    t_end_s: float
    exact_commands: int  # steps fed the command stamped with the step's time
    held_commands: int  # steps fed the last valid command (none stamped t_n)
    default_commands: int  # steps without any valid command yet (neutral planes, nominal propeller)
    rejected_commands: int
    clamped_commands: int
    max_position_m: float
    max_attitude_rad: float
    max_velocity_m_s: float
    max_rate_rad_s: float
    worst_time_s: float
    diverged: str = ""
    notes: list[str] = field(default_factory=list)

    def lines(self) -> list[str]:
        out = [f"open loop: mission {self.mission_file}, {self.steps} steps to t = {self.t_end_s:.3f} s, "
               f"compared with {self.reference_topic} at {self.compared} stamps",
               f"  commands: {self.exact_commands} stamped t_n, {self.held_commands} held, "
               f"{self.default_commands} default; {self.rejected_commands} rejected, {self.clamped_commands} clamped",
               f"  max deviation: position {self.max_position_m:.3e} m, attitude {self.max_attitude_rad:.3e} rad, "
               f"velocity {self.max_velocity_m_s:.3e} m/s, rates {self.max_rate_rad_s:.3e} rad/s "
               f"(worst at t = {self.worst_time_s:.3f} s)"]
        if self.diverged:
            out.append(f"  the simulation diverged: {self.diverged}")
        out += [f"  note: {n}" for n in self.notes]
        return out


def _stamp_ns(msg) -> int:
    return int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)


class _CommandFilter:
    """The simulator node's command validation (the lockstep gate's :class:`CommandValidator`) applied to
    recorded commands, with the counts of what it rejected and clamped (no stamp check: a recording's
    stamps are what they were)."""

    def __init__(self, validator):  # a bb2_mission.lockstep_gate.CommandValidator
        self.validator = validator
        self.rejected = self.clamped = 0

    def _count(self, v) -> None:
        if v.clamped:
            self.clamped += 1
        elif not v.accepted:
            self.rejected += 1

    def planes_deg(self, msg) -> np.ndarray | None:
        v = self.validator.planes(msg.name, msg.position, msg.header.frame_id)
        self._count(v)
        return v.value

    def rps(self, msg) -> float | None:
        v = self.validator.propeller(msg.name, msg.velocity, msg.header.frame_id)
        self._count(v)
        return v.value


def _mission_from_status(reader: BagReader) -> str | None:
    if STATUS not in reader.topics:
        return None
    for _, _, msg in reader.messages(STATUS):
        for st in msg.status:
            if st.name == "bb2/simulator":
                for kv in st.values:
                    if kv.key == "mission_file" and kv.value:
                        return kv.value
    return None


def environment_from_bag(reader: BagReader):
    """The sea and current recorded on ``/bb2/sea`` (the last description), or None if the bag has none."""
    from bb2_sim.environment import environment_from_description

    if SEA not in reader.topics:
        return None
    text = None
    for _, _, msg in reader.messages(SEA):
        text = msg.data
    if text is None:
        return None
    try:
        return environment_from_description(text)
    except ValueError as exc:
        raise ReplayError(f"the bag's {SEA} is not a sea description: {exc}") from None


def _wrap(a: np.ndarray) -> np.ndarray:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def open_loop(bag: str | os.PathLike | BagReader, mission_file: str | os.PathLike | None = None, *,
              start_offset_s: float = 0.0) -> OpenLoopResult:
    """Re-simulate a recorded run from its recorded commands (see the module docstring); no ROS needed.

    The simulator starts at the mission's initial state (t = 0: the actuator states are not in the bag) and
    steps while recorded states remain; deviations are taken at stamps ``>= start_offset_s`` after the
    first recorded state.
    """
    from bb2_mission import build_simulator, load_mission, nominal_rps
    from bb2_mission.components import build_model
    from bb2_mission.lockstep_gate import CommandLimits, CommandValidator
    from bb2_msgs_py import conversions as cv
    from bb2_msgs_py.contract import PLANE_JOINTS, PROPELLER_JOINT
    from bb2_sim.integrator import NonFiniteStateError

    reader = bag if isinstance(bag, BagReader) else BagReader(bag)
    notes: list[str] = []
    if reader.truncated:
        notes.append(f"the bag is truncated ({reader.problem}): replayed up to its last complete chunk")
    if mission_file is None:
        mission_file = _mission_from_status(reader)
        if mission_file is None:
            raise ReplayError("no --mission given and the bag has no simulator /bb2/status naming its mission")
        if not Path(mission_file).is_file():
            raise ReplayError(f"the bag's mission file {mission_file!r} does not exist here: give --mission")
    missing = [t for t in (PLANES_CMD, PROPELLER_CMD) if t not in reader.topics]
    if missing:
        raise ReplayError(f"the bag has no {', '.join(missing)}: nothing to feed the simulator")
    ref_topic = STATE_NATIVE if STATE_NATIVE in reader.topics else ODOM if ODOM in reader.topics else None
    if ref_topic is None:
        raise ReplayError(f"the bag has neither {STATE_NATIVE} nor {ODOM} to compare with")
    if ref_topic == ODOM:
        notes.append("compared with /bb2/odom (quaternion round trip): expect ~1e-15 rad attitude noise")

    try:
        mission = load_mission(mission_file)
    except (ValueError, OSError) as exc:
        raise ReplayError(f"mission {mission_file}: {exc}") from None
    env = environment_from_bag(reader)
    if env is not None:
        notes.append(f"sea and current from the bag's {SEA}: {env.summary()}")
    sim = build_simulator(mission, build_model(mission, env))
    base_link = reader.vehicle_base_link()  # boat1/base_link in a fleet boat's bag
    filt = _CommandFilter(CommandValidator(CommandLimits.from_actuators(
        sim.model.params.act, plane_joints=PLANE_JOINTS, propeller_joint=PROPELLER_JOINT, frame_id=base_link)))
    default_rps = nominal_rps(mission)

    planes: dict[int, np.ndarray] = {}
    props: dict[int, float] = {}
    ref: dict[int, np.ndarray] = {}
    for topic_name, _, msg in reader.messages([PLANES_CMD, PROPELLER_CMD, ref_topic]):
        if topic_name == PLANES_CMD:
            deg = filt.planes_deg(msg)
            if deg is not None:
                planes.setdefault(_stamp_ns(msg), deg)  # the first valid command of a stamp (as in lockstep)
        elif topic_name == PROPELLER_CMD:
            rps = filt.rps(msg)
            if rps is not None:
                props.setdefault(_stamp_ns(msg), rps)
        elif topic_name == STATE_NATIVE:
            try:
                s = cv.state_native_from_message(msg)
            except cv.ConversionError:
                continue
            ref.setdefault(cv.seconds_to_ns(s.t), s.as_vector())
        else:
            s = cv.odometry_to_state(msg, child_frame_id=base_link)
            ref.setdefault(_stamp_ns(msg), s.as_vector())
    if not ref:
        raise ReplayError(f"no readable {ref_topic} message in the bag")
    first_ref, last_ref = min(ref), max(ref)
    if first_ref != 0 and abs(first_ref - cv.seconds_to_ns(sim.t)) > 0:
        notes.append(f"the first recorded state is at t = {first_ref * 1e-9:.3f} s, not at the mission start")
    if 0 in ref and not np.array_equal(ref[0], sim.x):
        notes.append("the recorded initial state differs from the mission's initial state: wrong mission?")
    compare_from = first_ref + int(round(start_offset_s * 1e9))
    if compare_from > last_ref:  # nothing would be compared: no "deviation 0" for a run never looked at
        raise ReplayError(f"--start-offset {start_offset_s:g} s is past the last recorded state: the states span "
                          f"{(last_ref - first_ref) * 1e-9:.3f} s")
    plane_stamps, prop_stamps = sorted(planes), sorted(props)

    def held(stamps: list[int], table: dict, t_ns: int):
        import bisect

        i = bisect.bisect_right(stamps, t_ns) - 1
        return table[stamps[i]] if i >= 0 else None

    exact = hold = dflt = 0
    dev = np.zeros(4)
    worst_t, worst_p = 0.0, -1.0
    compared = 0
    diverged = ""

    def compare(t_ns: int, x: np.ndarray) -> None:
        nonlocal compared, worst_t, worst_p
        if t_ns < compare_from or t_ns not in ref:
            return
        d = x - ref[t_ns]
        e = np.array([np.linalg.norm(d[0:3]), np.max(np.abs(_wrap(d[3:6]))), np.linalg.norm(d[6:9]),
                      np.linalg.norm(d[9:12])])
        np.maximum(dev, e, out=dev)
        if e[0] > worst_p:
            worst_p, worst_t = e[0], t_ns * 1e-9
        compared += 1

    compare(cv.seconds_to_ns(sim.t), sim.x)
    while True:
        t_ns = cv.seconds_to_ns(sim.t)
        if t_ns >= last_ref:
            break
        p_cmd, r_cmd = planes.get(t_ns), props.get(t_ns)
        if p_cmd is not None and r_cmd is not None:
            exact += 1
        else:
            p_cmd = p_cmd if p_cmd is not None else held(plane_stamps, planes, t_ns)
            r_cmd = r_cmd if r_cmd is not None else held(prop_stamps, props, t_ns)
            if p_cmd is None and r_cmd is None:
                dflt += 1
            else:
                hold += 1
            p_cmd = p_cmd if p_cmd is not None else np.zeros(5)
            r_cmd = r_cmd if r_cmd is not None else default_rps
        try:
            sim.step(p_cmd, r_cmd)
        except (NonFiniteStateError, ValueError) as exc:
            diverged = str(exc)
            break
        compare(cv.seconds_to_ns(sim.t), sim.x)
    return OpenLoopResult(str(mission_file), ref_topic, sim.n, compared, sim.t, exact, hold, dflt, filt.rejected,
                          filt.clamped, float(dev[0]), float(dev[1]), float(dev[2]), float(dev[3]), worst_t,
                          diverged, notes)


# ----------------------------------------------------------------------------------------- CLI
REPLAY_ONLY = frozenset({"--rate", "--topics", "--pause", "--loop", "--domain-id", "--wait-for-readers", "--delay",
                         "--no-clock"})
"""Options of the replay that ``--open-loop`` (no ROS) does not read: refused with it."""
OPEN_LOOP_ONLY = frozenset({"--mission", "--max-deviation"})
"""Options of ``--open-loop`` that the replay does not read: refused without it."""


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="bb2-replay", description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter,
                                epilog="Pause/resume: SIGUSR1 toggles; service /bb2_replay/pause (std_srvs/SetBool).")
    p.add_argument("bag", type=Path, help="bag directory (metadata.yaml + .mcap) or .mcap file")
    p.add_argument("--rate", type=float, default=1.0, help="playback speed factor (default 1 = recorded speed)")
    p.add_argument("--start-offset", type=float, default=0.0, metavar="S",
                   help="start S seconds (bag time) after the first message (default 0)")
    p.add_argument("--topics", nargs="+", default=None, metavar="T",
                   help="bag topics to republish (exact names or regular expressions); default all")
    p.add_argument("--pause", action="store_true", help="start paused (resume with SIGUSR1 or the service)")
    p.add_argument("--loop", action="store_true", help="play again from the start offset at the end, until Ctrl-C")
    p.add_argument("--domain-id", type=int, default=None, metavar="N",
                   help="ROS domain id (default: ROS_DOMAIN_ID of the environment)")
    p.add_argument("--wait-for-readers", type=float, default=0.0, metavar="S",
                   help="before playing, wait up to S wall seconds until every republished topic has a matched "
                        "subscriber (default 0: do not wait)")
    p.add_argument("--delay", type=float, default=0.5, metavar="S",
                   help="wall seconds to wait after start-up for discovery before playing (default 0.5)")
    p.add_argument("--no-clock", action="store_true",
                   help="do not publish the playback /clock (republish a recorded /clock if selected)")
    p.add_argument("--open-loop", action="store_true",
                   help="feed the recorded plane/propeller commands into the simulator and compare the states")
    p.add_argument("--mission", type=Path, default=None,
                   help="open loop: mission YAML (default: the mission_file in the recorded /bb2/status)")
    p.add_argument("--max-deviation", type=float, default=None, metavar="M",
                   help="open loop: exit 3 if the position deviation exceeds M metres")
    return p


def _error(msg: str) -> int:
    print(f"bb2-replay: error: {msg}", file=sys.stderr, flush=True)
    return 2


def _run_open_loop(args: argparse.Namespace) -> int:
    try:
        res = open_loop(args.bag, args.mission, start_offset_s=args.start_offset)
    except (ReplayError, BagError) as exc:
        return _error(str(exc))
    for line in res.lines():
        print(line, flush=True)
    if res.diverged:
        return 1
    if args.max_deviation is not None and not res.max_position_m <= args.max_deviation:
        print(f"bb2-replay: position deviation {res.max_position_m:.3e} m exceeds --max-deviation "
              f"{args.max_deviation:g} m", file=sys.stderr)
        return 3
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``bb2-replay``; returns the exit status (0 done, 1 the open-loop run diverged, 2 bad input or
    an OS error: one line naming the file, 130 interrupted)."""
    from bb2_sim.outputs import run_cli

    return run_cli("bb2-replay", lambda: _main(argv))


def _main(argv: Sequence[str] | None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = _parser()
    args = parser.parse_args(argv)
    from bb2_msgs_py.ros_env import ros_environment_or_error

    if (bad := ros_environment_or_error("bb2-replay")) is not None:
        return bad
    if not (args.start_offset >= 0 and math.isfinite(args.start_offset)):
        return _error(f"--start-offset must be >= 0 s, got {args.start_offset}")
    other = sorted(o for o in (REPLAY_ONLY if args.open_loop else OPEN_LOOP_ONLY)   # set to other than the default
                   if getattr(args, dest := o[2:].replace("-", "_")) != parser.get_default(dest))
    if other:  # it would be ignored without a word
        return _error(f"{', '.join(other)} {'do' if len(other) > 1 else 'does'} not apply "
                      + ("to --open-loop (no ROS: nothing is republished)" if args.open_loop else
                         "without --open-loop (the replay republishes the bag: no simulator runs)"))
    if args.max_deviation is not None and not (args.max_deviation >= 0 and math.isfinite(args.max_deviation)):
        return _error(f"--max-deviation must be >= 0 m and finite, got {args.max_deviation}")
    if args.open_loop:
        return _run_open_loop(args)
    if not (args.wait_for_readers >= 0 and math.isfinite(args.wait_for_readers)):
        return _error(f"--wait-for-readers must be >= 0 s and finite, got {args.wait_for_readers}")
    if not (args.rate > 0 and math.isfinite(args.rate)):
        return _error(f"--rate must be > 0 and finite, got {args.rate}")
    if args.delay < 0 or not math.isfinite(args.delay):
        return _error(f"--delay must be >= 0 s, got {args.delay}")
    if args.domain_id is not None and not 0 <= args.domain_id <= 232:
        return _error(f"--domain-id must be in 0..232, got {args.domain_id}")
    try:
        reader = BagReader(args.bag)
        topics = select_bag_topics(reader.topics, args.topics)
    except (ReplayError, BagError) as exc:
        return _error(str(exc))
    if reader.truncated:
        print(f"bb2-replay: note: the bag is truncated ({reader.problem}); playing up to its last complete chunk",
              file=sys.stderr)

    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    init_kw: dict[str, Any] = {"signal_handler_options": SignalHandlerOptions.NO}
    if args.domain_id is not None:
        init_kw["domain_id"] = args.domain_id
    rclpy.init(args=["bb2_replay"], **init_kw)
    player = None
    previous: dict[int, Any] = {}
    spin_stop = threading.Event()
    spinner: threading.Thread | None = None
    code = 0
    try:
        try:
            player = Player(reader, topics, rate=args.rate, start_offset_s=args.start_offset, paused=args.pause,
                            loop=args.loop, clock=not args.no_clock)
        except (ReplayError, BagError) as exc:
            return _error(str(exc))
        previous = {s: signal.signal(s, lambda *_: player.stop()) for s in (signal.SIGINT, signal.SIGTERM)}
        previous[signal.SIGUSR1] = signal.signal(signal.SIGUSR1, lambda *_: player.toggle())
        executor = SingleThreadedExecutor()
        executor.add_node(player.node)

        def spin() -> None:
            while not spin_stop.is_set():
                executor.spin_once(timeout_sec=0.05)

        spinner = threading.Thread(target=spin, name="bb2_replay_spin", daemon=True)
        spinner.start()
        for name, why in player.stats.skipped_topics.items():
            print(f"bb2-replay: note: {name} not republished: {why}", file=sys.stderr)
        print(f"bb2-replay: pid {os.getpid()}: playing {len(player.topics)} topics of {args.bag} at {args.rate:g}x "
              f"from bag time {player.start_ns * 1e-9:.3f} s{' (paused)' if args.pause else ''}; "
              f"pause/resume: kill -USR1 {os.getpid()} or service {PAUSE_SERVICE}", flush=True)
        # the playback clock stands still until playing starts: waiting for readers and the discovery delay
        # must not eat into the bag (else the first messages would go out in a catch-up burst)
        paused = player.clock.paused
        player.clock.set_paused(True)
        player.clock.restart(player.start_ns)
        if args.wait_for_readers > 0:
            deadline = time.monotonic() + args.wait_for_readers
            while time.monotonic() < deadline and not all(
                    pub.get_subscription_count() > 0 for pub in player.pubs.values()):
                time.sleep(0.05)
        if args.delay > 0:
            time.sleep(args.delay)
        player.clock.set_paused(paused)
        stats = player.play()
        player.drain()
        print(f"bb2-replay: published {sum(stats.published.values())} messages "
              f"({', '.join(f'{k}: {v}' for k, v in sorted(stats.published.items()))}), "
              f"{stats.clock_published} /clock, {stats.loops} loops", flush=True)
    except Exception as exc:
        print(f"bb2-replay: error: {type(exc).__name__}: {exc}", file=sys.stderr, flush=True)
        code = 1
    finally:
        spin_stop.set()
        if spinner is not None:
            spinner.join(2.0)
        for s, h in previous.items():
            signal.signal(s, h)
        if player is not None:
            player.node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
    return code


if __name__ == "__main__":
    sys.exit(main())
