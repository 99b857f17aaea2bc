"""The graph monitor of bb2-launch: a small rclpy node on the graph's ``ROS_DOMAIN_ID`` reading sim time
(``/clock``), mission progress (``/bb2/mission/progress``) and the simulator's ``/bb2/status`` -- of the boat in
``namespace``: ``/boat1/clock``, ``/boat1/bb2/...`` (:func:`bb2_msgs_py.contract.boat_topic`) -- and answering
graph questions (which nodes are up, who subscribes to what).

``/clock`` and the progress come once per step (hundreds per wall second in lockstep): they are polled, the
latest sample only, and deserialized with rclpy's standard CDR deserializer; the status is spun.  From the
samples the monitor derives the real-time factor and when the mission is over (``end_at``).
:func:`free_domain_id` finds a domain id nobody else uses — claimed with a lock file, so two launches on one machine
never share a domain however close together they start (listening for nodes alone misses a graph still starting,
whose participants are not discovered yet) — and :func:`format_status` is the one progress line.
"""
from __future__ import annotations

import collections
import fcntl
import os
import random
import tempfile
import threading
import time
from pathlib import Path
from typing import Iterable

from bb2_ros.discovery_port import discovery_blocked
from bb2_ros.node_common import take_all
from bb2_tools.supervisor import LaunchError

SAFE_DOMAIN_IDS = range(1, 102)  # ROS 2 docs: 0..101 never collide with Linux ephemeral ports

END_WORDS = {"complete", "completed", "finished", "done", "end", "ended"}
END_AT = ("either", "simulator", "progress")
"""When the mission is over: the simulator reports the end of the mission duration (status
``state: finished``), the mission progress reaches 1 (the path is flown), or whichever comes first."""


def _unused(_msg) -> None:  # pragma: no cover - polled subscriptions have no executor
    pass


class GraphMonitor:
    """A small rclpy node (own context, own thread) watching ``/clock``, the mission progress and
    ``/bb2/status`` on ``domain_id``; also answers graph questions (nodes, subscriptions)."""

    def __init__(self, domain_id: int, *, node_name: str = "bb2_launch_monitor", rtf_window_s: float = 3.0,
                 end_at: str = "either", namespace: str = ""):
        if end_at not in END_AT:
            raise LaunchError(f"end_at must be one of {END_AT}, got {end_at!r}")
        self.domain_lock_fd: int | None = None  # the claim of the domain (claim_domain), released by close()
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.qos import DurabilityPolicy, HistoryPolicy
        from rclpy.serialization import deserialize_message
        from rclpy.signals import SignalHandlerOptions

        from bb2_msgs_py.contract import boat_topic, message_class, qos_profile

        self.domain_id = domain_id
        self.node_name = node_name
        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain_id, signal_handler_options=SignalHandlerOptions.NO)
        self.namespace = namespace.strip("/")  # the watched boat's: its nodes in /NAMESPACE, its own clock
        # the monitor's nodes sit in the boat's namespace too: two launches' monitors on one domain never share a name
        self.node = rclpy.create_node(node_name, context=self.context, namespace="/" + self.namespace,
                                      start_parameter_services=False, enable_rosout=False)
        self._lock = threading.Lock()
        self.sim_time_s: float | None = None
        self._status_time_wall: float | None = None  # wall s when a status's sim time was last taken over /clock's
        self.progress: float | None = None
        self.status_end = False  # the simulator's status says the mission duration is over
        self.sim_error: str | None = None  # the simulator's status says it stopped on an error
        self.sim_error_state: str | None = None  # which: diverged, or stalled (on its failsafe: stall_timeout_s)
        self.failsafe: str | None = None  # the simulator's last status: stepping on the failsafe, and why
        self.end_at = end_at
        self._samples: collections.deque[tuple[float, float]] = collections.deque()
        self._first: tuple[float, float] | None = None  # the first /clock (start-up handshake at t0)
        self._first_step: tuple[float, float] | None = None  # the first /clock after t0 (stepping started)
        self.rtf_window_s = rtf_window_s
        n = self.node
        n.create_subscription(message_class("diagnostic_msgs/msg/DiagnosticArray"),
                              boat_topic("/bb2/status", self.namespace),
                              self._on_status, qos_profile("/bb2/status", reader=True))
        # /clock and the progress come once per step (hundreds per wall second in lockstep): they are not
        # spun (a Python callback each would take CPU from the graph) but polled, the latest sample only,
        # from a second node that no executor waits on.
        self.poll_node_name = node_name + "_poll"
        self._poll_node = rclpy.create_node(self.poll_node_name, context=self.context, namespace="/" + self.namespace,
                                            start_parameter_services=False, enable_rosout=False)

        def latest_only(name):
            q = qos_profile(name, reader=True)
            q.history, q.depth = HistoryPolicy.KEEP_LAST, 1
            return q

        self._deserialize = deserialize_message
        self._clock_type = message_class("rosgraph_msgs/msg/Clock")
        self._progress_type = message_class("std_msgs/msg/Float64")
        self._clock_sub = self._poll_node.create_subscription(
            self._clock_type, boat_topic("/clock", self.namespace), _unused, latest_only("/clock"), raw=True)
        self._progress_sub = self._poll_node.create_subscription(
            self._progress_type, boat_topic("/bb2/mission/progress", self.namespace), _unused,
            latest_only("/bb2/mission/progress"), raw=True)
        self.recorder_ack_s: float | None = None  # the newest /bb2/recorder/ack: the recorder holds every step to it
        self._ack_type = message_class("std_msgs/msg/Header")
        ack_qos = latest_only("/bb2/recorder/ack")
        # the recorder's writer keeps its latest acknowledgements (transient local): a monitor that matches it after
        # the last one went out (a short lockstep run on a fast machine ends within a second) still learns where
        # it stands, instead of waiting for news that will not come
        ack_qos.durability = DurabilityPolicy.TRANSIENT_LOCAL
        self._ack_sub = self._poll_node.create_subscription(
            self._ack_type, boat_topic("/bb2/recorder/ack", self.namespace), _unused, ack_qos, raw=True)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(n)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._spin, name="bb2-launch-monitor", daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        while not self._stop.is_set() and self.context.ok():
            try:
                self.executor.spin_once(timeout_sec=self.POLL_S)
                self._poll()
            except Exception:  # context shut down under us
                if self._stop.is_set():
                    break
                raise

    POLL_S = 0.05

    def _poll(self) -> None:
        """Take the latest /clock, progress and recorder acknowledgement (if new ones came)."""
        for sub, handler in ((self._clock_sub, self._on_clock), (self._progress_sub, self._on_progress),
                             (self._ack_sub, self._on_ack)):
            got = take_all(sub)
            if got:
                data, info = got[-1]
                handler(data, int(info.get("source_timestamp", 0)) * 1e-9 or time.time())

    def _on_clock(self, data: bytes, wall: float) -> None:
        """``wall``: the DDS source timestamp (the simulator's wall clock when it published this /clock)."""
        stamp = self._deserialize(data, self._clock_type).clock
        t = stamp.sec + stamp.nanosec * 1e-9
        with self._lock:
            # a /clock sent before a status whose newer sim time was taken is old news (a restarted simulator's
            # lower times come after it and are taken)
            if not (self._status_time_wall is not None and wall < self._status_time_wall
                    and self.sim_time_s is not None and t < self.sim_time_s):
                self.sim_time_s = t
            if self._first is None:
                self._first = (wall, t)
            elif self._first_step is None and t != self._first[1]:
                self._first_step = (wall, t)
            self._samples.append((wall, t))
            while len(self._samples) > 2 and wall - self._samples[0][0] > self.rtf_window_s:
                self._samples.popleft()

    def _on_progress(self, data: bytes, _wall: float = 0.0) -> None:
        p = self._deserialize(data, self._progress_type).data
        with self._lock:
            self.progress = p

    def _on_ack(self, data: bytes, _wall: float = 0.0) -> None:
        stamp = self._deserialize(data, self._ack_type).stamp
        with self._lock:
            self.recorder_ack_s = stamp.sec + stamp.nanosec * 1e-9

    def _on_status(self, msg) -> None:
        for st in msg.status:
            if "simulator" not in st.name:
                continue
            vals = {kv.key: kv.value for kv in st.values}
            try:  # the sim time the status was sent at: the newest known if /clock has not come (yet) or is older
                t = float(vals["sim_time_s"])
                with self._lock:
                    if self.sim_time_s is None or t > self.sim_time_s:
                        self.sim_time_s, self._status_time_wall = t, time.time()
            except (KeyError, ValueError):
                pass
            state = vals.get("state", "").lower()
            self.failsafe = ((vals.get("failsafe_reason") or "no valid command")
                             if vals.get("failsafe") == "true" and state == "running" else None)
            if state in END_WORDS:
                self.status_end = True
            elif state in ("diverged", "stalled"):
                self.sim_error = vals.get("error") or st.message or state
                self.sim_error_state = state

    def rtf(self, *, overall: bool = False) -> float | None:
        """Sim seconds per wall second over the last window, or (``overall``) while stepping: from the
        first /clock after the start time (the first step done; the graph's start-up handshake at t0,
        which waits for every node to answer, is not stepping) to the last one."""
        if overall:
            sim_s, wall_s = self.stepping_span()
            return sim_s / wall_s if wall_s else None
        with self._lock:
            if len(self._samples) < 2:
                return None
            (w0, t0), (w1, t1) = self._samples[0], self._samples[-1]
        return (t1 - t0) / (w1 - w0) if w1 > w0 else None

    @property
    def stepping_started(self) -> bool:
        """Whether the graph has stepped: the sim time moved past the first one seen here, or that one was already
        past 0 (this monitor came late).  Before, the graph is at its start-up handshake at t = 0, waiting for every
        node to answer."""
        with self._lock:
            return self._first_step is not None or (self._first is not None and self._first[1] > 0.0)

    def stepping_span(self) -> tuple[float | None, float | None]:
        """(sim s, wall s) from the first /clock after the start time to the last one."""
        with self._lock:
            if self._first_step is None or not self._samples:
                return None, None
            (w0, t0), (w1, t1) = self._first_step, self._samples[-1]
        return t1 - t0, w1 - w0

    @property
    def mission_complete(self) -> bool:
        by_sim = self.status_end
        by_progress = self.progress is not None and self.progress >= 1.0
        return {"either": by_sim or by_progress, "simulator": by_sim, "progress": by_progress}[self.end_at]

    def node_names(self) -> list[str]:
        own = (self.node_name, self.poll_node_name)
        return sorted(n for n, _ns in self.node.get_node_names_and_namespaces() if n not in own)

    def subscribed(self, node_name: str, topics: Iterable[str]) -> bool:
        """Whether ``node_name`` (of the watched boat's namespace) has a subscription on each of ``topics``
        (resolved names, as discovered here)."""
        ns = "/" + self.namespace
        for t in topics:
            if not any(i.node_name == node_name and i.node_namespace == ns
                       for i in self.node.get_subscriptions_info_by_topic(t)):
                return False
        return True

    def close(self) -> None:
        import rclpy

        if self.domain_lock_fd is not None:  # the domain claim goes with the monitor
            os.close(self.domain_lock_fd)
            self.domain_lock_fd = None
        self._stop.set()
        self._thread.join(timeout=2.0)
        try:
            self.executor.shutdown(timeout_sec=1.0)
            self._poll_node.destroy_node()
            self.node.destroy_node()
        finally:
            if self.context.ok():
                rclpy.shutdown(context=self.context)


DOMAIN_LOCK_DIR = Path(tempfile.gettempdir()) / "bb2_ros_domains"
"""Where the domain claims of this machine's launches are (``<id>.lock``, held with ``flock`` while a launch runs;
the kernel releases a claim when its process ends, however it ends)."""


def claim_domain(domain_id: int, lock_dir: Path | None = None) -> int | None:
    """Claim ``domain_id`` for this process (an open, ``flock``-ed lock file: its descriptor, to keep open for the
    run and close to release); None when another process holds it."""
    d = Path(lock_dir or DOMAIN_LOCK_DIR)
    d.mkdir(parents=True, exist_ok=True)
    fd = os.open(d / f"{int(domain_id)}.lock", os.O_RDWR | os.O_CREAT, 0o666)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        os.close(fd)
        return None
    os.ftruncate(fd, 0)
    os.write(fd, f"{os.getpid()}\n".encode())
    return fd


def domain_monitor(domain_id: int | None, **monitor_kw) -> GraphMonitor:
    """A :class:`GraphMonitor` on ``domain_id``, claimed for this process when no other holds it
    (``domain_lock_fd`` None: another launch holds it), or with ``domain_id`` None on a free one
    (:func:`free_domain_id`).  A domain whose discovery port another socket holds unshared is refused (LaunchError,
    :func:`bb2_ros.discovery_port.discovery_blocked`): its nodes would never find each other."""
    if domain_id is None:
        return free_domain_id(**monitor_kw)
    if (blocked := discovery_blocked(os.environ, domain_id)) is not None:
        raise LaunchError(blocked)
    monitor = GraphMonitor(domain_id, **monitor_kw)
    monitor.domain_lock_fd = claim_domain(domain_id)
    return monitor


def free_domain_id(*, rng: random.Random | None = None, tries: int = 8, listen_s: float = 0.5,
                   lock_dir: Path | None = None, **monitor_kw) -> GraphMonitor:
    """A :class:`GraphMonitor` on a random domain id (1..101) that no other launch of this machine has claimed
    (:func:`claim_domain`), whose discovery port is free to share (:func:`bb2_ros.discovery_port.discovery_blocked`)
    and where no other node is seen; the claim is held until the monitor is closed."""
    rng = rng or random.Random()
    candidates = rng.sample(list(SAFE_DOMAIN_IDS), len(SAFE_DOMAIN_IDS))  # every id, in random order
    listened = []
    for d in candidates:
        fd = claim_domain(d, lock_dir)
        if fd is None:  # another launch runs there
            continue
        if discovery_blocked(os.environ, d) is not None:  # no node there would discover another
            os.close(fd)
            continue
        mon = GraphMonitor(d, **monitor_kw)
        mon.domain_lock_fd = fd
        time.sleep(listen_s)
        if not mon.node_names():
            return mon
        mon.close()
        listened.append(d)
        if len(listened) >= tries:
            break
    raise LaunchError(f"no free ROS_DOMAIN_ID in {SAFE_DOMAIN_IDS.start}..{SAFE_DOMAIN_IDS.stop - 1} (the others "
                      f"claimed by launches of this machine; nodes seen on {listened}); give one with --domain-id")


def format_status(sim_time_s: float | None, progress: float | None, rtf: float | None,
                  up: int, total: int, wall_s: float, failsafe: str | None = None) -> str:
    """The one progress line; ``failsafe`` (why the simulator steps on its failsafe: a controller silent, or with
    ``--without`` no node of the user's answering yet) is appended."""
    t = "--" if sim_time_s is None else f"{sim_time_s:8.2f} s"
    p = "--" if progress is None else f"{100.0 * progress:5.1f} %"
    r = "--" if rtf is None else f"{rtf:6.1f}x"
    return (f"[bb2-launch] sim {t} | progress {p} | RTF {r} | nodes {up}/{total} | wall {wall_s:6.1f} s"
            + (f" | FAILSAFE: {failsafe}" if failsafe else ""))
