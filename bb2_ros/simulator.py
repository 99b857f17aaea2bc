"""``simulator`` node: the BB2 ROM at a fixed step, in lockstep with the controllers or in real time.

Parameters (``config/bb2_graph.yaml`` lists them all with their defaults):

``mission_file``       the mission YAML (as ``bb2-sim mission``): model, initial state, terrain, duration.
``time_mode``          ``lockstep`` | ``realtime``.
``rate_hz``            real time: steps per wall second (1/Ts = 20 is real time; 100 runs 5x faster), on
                       absolute deadlines in a thread of its own (not an executor timer).
``lockstep_timeout_s`` lockstep: wall time to wait for the answer of a step before holding the last
                       valid commands (or the safe default) and stepping anyway (status + warning).
``lockstep_retry_s``   lockstep: re-send the current ``/bb2/state_native`` (and ``/bb2/odom``) after this wall
                       time without an answer (controllers replay their cached answer, never step twice;
                       covers discovery at start-up and a best-effort odometry sample lost under load).
``startup_timeout_s``  lockstep: the timeout of the very first step (nodes still starting).
``startup_settle_s``   lockstep: hold the first step this long (wall) after its first complete answer,
                       re-sending the state at t = 0 (the controllers replay their cached answers), so a
                       reader matched late (the recorder and a controller that just started) misses none.
``min_state_subscribers`` publish the first state (start stepping) only once this many readers of
                       ``/bb2/state_native`` are discovered (e.g. 3: path_following, l1_autopilot, recorder), at
                       most ``startup_timeout_s``; 0 = start at once.
``realtime_priority``  real time: SCHED_FIFO priority (1-99, default 50) of the stepping thread, so the period
                       holds on a loaded machine (HIL); 0 = normal scheduling.  Refused by the OS (no
                       CAP_SYS_NICE / rtprio limit): one warning, normal scheduling.  A thread that overruns every
                       step for a second gives the priority up (it would starve its core).
``hold_cpu_dma_latency`` real time: hold ``/dev/cpu_dma_latency`` at 0 us while running (the PM QoS request
                       of cyclictest and RT setups: idle cores wake without deep C-state or halt exits;
                       measured here: a DDS round trip 150 -> 102 us).  Refused (not root): one warning.
``wait_for_readers``   publish the first state only once every topic this node publishes has had a reader (a
                       recorder started alongside) for ``startup_settle_s`` (the readers' side matches the
                       writers a moment later: it then misses nothing), at most ``startup_timeout_s``.
``command_timeout_s``  real time: a command older than this (wall time since it arrived), or none at all,
                       engages the failsafe: planes commanded to neutral (0 rad), propeller held at the last
                       valid command (the mission's nominal speed command if none ever arrived).
``max_command_age_s``  a command whose stamp is older than sim time minus this is rejected (stale).
``duration_s``         stop stepping at this sim time (< 0: the mission's duration, none = run on).
``exit_at_end``        exit 0 when the duration is reached (else stay up, status ``finished``); a diverged
                       simulation then exits 1 (status ``diverged``, ``error``).
``trajectory_csv``     if set, every state ``t, x12`` (native, ``%.17g``) is written to this CSV.
``status_period_s``    wall period of ``/bb2/status``.
``warn_throttle_s``    at most one warning of a kind per this many wall seconds.
``strict_remaps``      a ``-r`` rule naming no topic of this node is an error (else a warning).

``/clock`` goes to ``t_n+1`` when the step from ``t_n`` starts (the commands of ``t_n`` are in), before the
integration, so the nodes on sim time handle it while the ROM steps, not when they must answer the state.
Per step ``n`` (time ``t_n``): ``/clock`` (first, at ``t_0``), ``/bb2/state_native``, ``/bb2/odom``, ``/bb2/depth``,
``/bb2/altitude`` (missions with terrain only) carry the state at ``t_n``; once the step from ``t_n`` is
integrated, ``/bb2/imu`` (specific force incl. gravity), ``/bb2/planes/state`` and
``/bb2/propeller/state`` carry the actuator outputs and the acceleration at ``t_n`` (they depend on the
commands applied at ``t_n``).

Lockstep handshake: the simulator waits for ``/bb2/planes/cmd`` AND ``/bb2/propeller/cmd`` stamped exactly
``t_n`` (reliable QoS, like ``/bb2/state_native`` that triggers the controllers), then integrates; so no
message the handshake needs can be dropped and the run is deterministic.

Command validation: non-finite values, wrong joint names/sizes, a frame other than ``base_link``, stale or
future stamps are rejected (never integrated); plane commands beyond the ROM's plane limit and propeller
commands outside its rps limits are clamped; each with a throttled warning and a counter in the status.
"""
from __future__ import annotations

import csv
import math
import os
import sys
import threading
import time
from typing import Sequence

import numpy as np

from bb2_msgs_py import conversions as cv
from bb2_msgs_py.contract import FRAME_BASE_LINK, PLANE_JOINTS, PROPELLER_JOINT
from bb2_sim.integrator import NonFiniteStateError
from bb2_sim.state import VehicleState

from bb2_ros.node_common import (NodeConfigError, Throttle, check_remaps, declare, mission_pieces,
                                   require_choice, require_positive, run_node)

TOPICS_OUT = ("/clock", "/bb2/state_native", "/bb2/odom", "/bb2/imu", "/bb2/depth", "/bb2/altitude",
              "/bb2/planes/state", "/bb2/propeller/state", "/bb2/status")
TOPICS_IN = ("/bb2/planes/cmd", "/bb2/propeller/cmd")
TWO_PI = 2.0 * math.pi


def _piece(components, name: str, default=None):
    if isinstance(components, dict):
        return components.get(name, default)
    return getattr(components, name, default)


class SimulatorShell:
    """The simulator node: parameters, publishers, the lockstep/real-time stepping and the status."""

    def __init__(self, argv: Sequence[str]):
        from rclpy.clock import Clock, ClockType
        from rclpy.node import Node

        from bb2_msgs_py.contract import message_class, qos_profile

        self.node = node = Node("simulator")
        self._lock = threading.RLock()  # real time: the stepping thread vs the executor's callbacks
        self.scheduling = "normal"  # of the real-time stepping thread (status)
        self.cpu_latency = "not held"  # /dev/cpu_dma_latency (status)
        P = lambda *a: declare(node, *a)  # noqa: E731
        self.mission_file = P("mission_file", "", "mission YAML (same file as `bb2-sim mission`)")
        self.time_mode = require_choice("time_mode", P("time_mode", "lockstep",
                                        "lockstep (wait for the controllers each step) | realtime (wall clock)"),
                                        ("lockstep", "realtime"))
        self.rate_hz = require_positive("rate_hz", P("rate_hz", 20.0,
                                        "realtime: steps per wall second (20 = 1/Ts = real time)"))
        self.lockstep_timeout_s = require_positive("lockstep_timeout_s", P(
            "lockstep_timeout_s", 1.0, "lockstep: wall s to wait for a step's answer before holding commands"))
        self.lockstep_retry_s = require_positive("lockstep_retry_s", P(
            "lockstep_retry_s", 0.1, "lockstep: wall s before re-sending an unanswered /bb2/state_native"))
        self.startup_timeout_s = require_positive("startup_timeout_s", P(
            "startup_timeout_s", 30.0, "lockstep: timeout of the first step (graph still starting)"))
        self.startup_settle_s = require_positive("startup_settle_s", P(
            "startup_settle_s", 0.5, "lockstep: hold the first step this long after its first answer"),
            allow_zero=True)
        self._first_answer_wall: float | None = None
        self.realtime_priority = int(P("realtime_priority", 50,
                                       "realtime: SCHED_FIFO priority (1-99) of the stepping thread; 0 = normal "
                                       "scheduling (refused by the OS: a warning, normal scheduling)"))
        self.hold_cpu_dma_latency = bool(P(
            "hold_cpu_dma_latency", True, "realtime: hold /dev/cpu_dma_latency at 0 us while running (idle cores "
            "wake fast, as cyclictest does); refused by the OS: a warning"))
        if not 0 <= self.realtime_priority <= 99:
            raise NodeConfigError(f"realtime_priority must be in 0..99, got {self.realtime_priority}")
        self.command_timeout_s = require_positive("command_timeout_s", P(
            "command_timeout_s", 0.5, "realtime: wall s without a valid command before the failsafe"))
        self.max_command_age_s = require_positive("max_command_age_s", P(
            "max_command_age_s", 1.0, "reject commands stamped more than this (sim s) before the sim time"))
        duration = float(P("duration_s", -1.0, "stop at this sim time (< 0: mission duration; none: run on)"))
        self.exit_at_end = bool(P("exit_at_end", False, "exit 0 when the duration is reached"))
        csv_path = P("trajectory_csv", "", "write t and the native state of every step to this CSV ('' = off)")
        self.min_state_subscribers = int(P("min_state_subscribers", 0,
                                           "wait for this many /bb2/state_native readers before the first step"))
        self._readers_since: float | None = None
        self.wait_for_readers = bool(P("wait_for_readers", False,
                                       "publish the first state only once every topic published here has a "
                                       "reader (a recorder), at most startup_timeout_s"))
        self.status_period_s = require_positive("status_period_s", P(
            "status_period_s", 1.0, "wall period of /bb2/status"))
        throttle_s = require_positive("warn_throttle_s", P(
            "warn_throttle_s", 2.0, "at most one warning of a kind per this many wall seconds"))
        strict = bool(P("strict_remaps", False, "a remap rule naming no topic of this node is an error"))
        check_remaps(node, argv, TOPICS_OUT + TOPICS_IN, strict=strict)

        self.mission, comp = mission_pieces(self.mission_file)
        self.sim = _piece(comp, "simulator")
        self.stack = _piece(comp, "stack")
        self.terrain = getattr(self.mission, "terrain", None)
        if self.sim is None:
            raise NodeConfigError("the mission factory returned no simulator")
        act = self.sim.model.params.act
        self.plane_limit_deg = float(act["plane_limit_deg"])
        self.rps_limits = (float(act["rps_limits"][0]), float(act["rps_limits"][1]))
        self.g = float(self.sim.model.params.g)
        self.h = float(self.sim.h)
        if duration < 0:
            duration = float(getattr(self.mission, "duration", math.inf))
        self.duration_s = duration
        self.default_rps = float(self.stack.speed.step()) if self.stack is not None else 0.0

        # publishers / subscriptions (contract QoS)
        def pub(name):
            from bb2_msgs_py.contract import topic
            return node.create_publisher(message_class(topic(name).type), name, qos_profile(name))

        self.pub = {n: pub(n) for n in TOPICS_OUT if n != "/bb2/altitude" or self.terrain is not None}
        self.sub_planes = node.create_subscription(message_class("sensor_msgs/msg/JointState"), "/bb2/planes/cmd",
                                                   self._locked(self._on_planes), qos_profile("/bb2/planes/cmd"))
        self.sub_prop = node.create_subscription(message_class("sensor_msgs/msg/JointState"), "/bb2/propeller/cmd",
                                                 self._locked(self._on_propeller), qos_profile("/bb2/propeller/cmd"))
        self.warn = Throttle(node.get_logger(), throttle_s)
        self.counters = {k: 0 for k in ("rejected_nonfinite", "rejected_names", "rejected_frame", "rejected_stale",
                                        "rejected_future", "clamped", "late_commands", "lockstep_timeouts",
                                        "lockstep_resends", "failsafe_steps", "overruns")}
        self._csv_fh = open(csv_path, "w", newline="") if csv_path else None
        self._csv = csv.writer(self._csv_fh) if self._csv_fh else None
        if self._csv:
            self._csv.writerow(["t", "x", "y", "z", "phi", "theta", "psi", "u", "v", "w", "p", "q", "r"])

        # command memory: last valid values and when they arrived (wall monotonic) / their stamps (ns)
        self.planes_deg: np.ndarray | None = None
        self.rps: float | None = None
        self.planes_wall = self.rps_wall = -math.inf
        self._ans_planes: np.ndarray | None = None  # answers for the step being awaited (lockstep)
        self._ans_rps: float | None = None
        self.failsafe = False
        self.failsafe_reason = ""
        self.finished = False
        self.diverged = ""
        self.done = False
        self.exit_code = 0
        self._odom_msg = None
        self._t_start_wall = time.monotonic()
        self._steps_at_status, self._wall_at_status = 0, self._t_start_wall
        self._rate_measured = 0.0

        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.status_timer = node.create_timer(self.status_period_s, self._locked(self._publish_status), clock=steady)
        self.started = False
        self._sent_wall = self._first_sent_wall = time.monotonic()
        self.start_timer = node.create_timer(0.02, self._locked(self._start), clock=steady)
        if self.time_mode == "lockstep":
            self.watchdog = node.create_timer(min(0.01, self.lockstep_retry_s / 2), self._watchdog, clock=steady)
        else:  # a thread of its own, on absolute wall deadlines (not an executor timer: no callback queue ahead)
            self._rt_stop = threading.Event()
            self._rt_thread = threading.Thread(target=self._realtime_loop, name="bb2-sim-realtime", daemon=True)
            self._rt_thread.start()
        node.get_logger().info(
            f"simulator up: mission {self.mission_file}, {self.time_mode}"
            + (f" at {self.rate_hz:g} Hz" if self.time_mode == "realtime" else "")
            + f", Ts = {self.h:g} s, duration {self.duration_s:g} s")

    def _locked(self, fn):
        def call(*args):
            with self._lock:
                return fn(*args)
        return call

    # ------------------------------------------------------------------------------------ time
    @property
    def t(self) -> float:
        return self.sim.t

    def _t_ns(self) -> int:
        return cv.seconds_to_ns(self.sim.t)

    # ------------------------------------------------------------------------------------ commands
    def _check_header(self, msg, what: str) -> bool:
        if msg.header.frame_id != FRAME_BASE_LINK:
            self.counters["rejected_frame"] += 1
            self.warn.warn(f"frame_{what}", f"rejected {what} command: frame_id {msg.header.frame_id!r}, "
                                            f"expected {FRAME_BASE_LINK!r}")
            return False
        st, now = cv.stamp_to_ns(msg.header.stamp), self._t_ns()
        if self.time_mode == "lockstep":
            if st < now:
                self.counters["late_commands"] += 1  # an answer to an earlier (resent/timed-out) step
                return False
            if st > now:
                self.counters["rejected_future"] += 1
                self.warn.warn(f"future_{what}", f"rejected {what} command stamped {st * 1e-9:.3f} s: "
                                                 f"ahead of the sim time {now * 1e-9:.3f} s")
                return False
            return True
        if st < now - int(self.max_command_age_s * 1e9):
            self.counters["rejected_stale"] += 1
            self.warn.warn(f"stale_{what}", f"rejected stale {what} command stamped {st * 1e-9:.3f} s "
                                            f"(sim time {now * 1e-9:.3f} s, max age {self.max_command_age_s} s)")
            return False
        if st > now + int(self.h * 1e9):
            self.counters["rejected_future"] += 1
            self.warn.warn(f"future_{what}", f"rejected {what} command stamped {st * 1e-9:.3f} s: "
                                             f"ahead of the sim time {now * 1e-9:.3f} s")
            return False
        return True

    def _on_planes(self, msg) -> None:
        try:
            if len(msg.name) != len(PLANE_JOINTS) or len(set(msg.name)) != len(msg.name):
                raise cv.ConversionError(f"expected the {len(PLANE_JOINTS)} joints {list(PLANE_JOINTS)}, "
                                      f"got {list(msg.name)}")
            rad = cv.planes_from_message(msg)
        except cv.ConversionError as exc:
            self.counters["rejected_names"] += 1
            self.warn.warn("names_planes", f"rejected plane command: {exc}")
            return
        if not np.all(np.isfinite(rad)):
            self.counters["rejected_nonfinite"] += 1
            self.warn.warn("nonfinite_planes", f"rejected non-finite plane command {rad.tolist()} (never integrated)")
            return
        if not self._check_header(msg, "plane"):
            return
        deg = np.degrees(rad)
        if np.any(np.abs(deg) > self.plane_limit_deg):
            self.counters["clamped"] += 1
            self.warn.warn("clamp_planes", f"plane command {np.round(deg, 3).tolist()} deg beyond "
                                           f"+-{self.plane_limit_deg:g} deg: clamped")
            deg = np.clip(deg, -self.plane_limit_deg, self.plane_limit_deg)
        self.planes_deg, self.planes_wall = deg, time.monotonic()
        if self.time_mode == "lockstep":
            self._ans_planes = deg
            self._maybe_advance()

    def _on_propeller(self, msg) -> None:
        try:
            if list(msg.name) != [PROPELLER_JOINT]:
                raise cv.ConversionError(f"expected the joint [{PROPELLER_JOINT!r}], got {list(msg.name)}")
            omega = cv.propeller_from_message(msg)
        except cv.ConversionError as exc:
            self.counters["rejected_names"] += 1
            self.warn.warn("names_prop", f"rejected propeller command: {exc}")
            return
        if not math.isfinite(omega):
            self.counters["rejected_nonfinite"] += 1
            self.warn.warn("nonfinite_prop", f"rejected non-finite propeller command {omega} (never integrated)")
            return
        if not self._check_header(msg, "propeller"):
            return
        rps = omega / TWO_PI
        lo, hi = self.rps_limits
        if not lo <= rps <= hi:
            self.counters["clamped"] += 1
            self.warn.warn("clamp_prop", f"propeller command {rps:.4g} rps outside [{lo:g}, {hi:g}]: clamped")
            rps = min(max(rps, lo), hi)
        self.rps, self.rps_wall = rps, time.monotonic()
        if self.time_mode == "lockstep":
            self._ans_rps = rps
            self._maybe_advance()

    # ------------------------------------------------------------------------------------ stepping
    def _stepping(self) -> bool:
        return not (self.finished or self.diverged)

    def _maybe_advance(self) -> None:
        if self._ans_planes is not None and self._ans_rps is not None and self._stepping():
            if self.sim.n == 0 and self.startup_settle_s > 0:  # let late endpoint matches settle (replays)
                now = time.monotonic()
                if self._first_answer_wall is None:
                    self._first_answer_wall = now
                if now - self._first_answer_wall < self.startup_settle_s:
                    self._ans_planes = self._ans_rps = None  # wait for the answers to the next re-send
                    return
            planes, rps = self._ans_planes, self._ans_rps
            self._set_failsafe(False, "")
            self._advance(planes, rps)

    def _start(self) -> None:
        """Publish the first state once ``min_state_subscribers`` readers of /bb2/state_native are up (or
        after ``startup_timeout_s``), so that a recorder or a test started with the graph misses nothing."""
        n = self.node.count_subscribers("/bb2/state_native")
        unread = [t for t in self.pub if self.node.count_subscribers(t) == 0] if self.wait_for_readers else []
        now = time.monotonic()
        if self.wait_for_readers and not unread:  # every topic read: let the readers' side match too
            self._readers_since = self._readers_since or now
        else:
            self._readers_since = None
        readers_ok = not self.wait_for_readers or (
            self._readers_since is not None and now - self._readers_since >= self.startup_settle_s)
        waited = now - self._t_start_wall
        if (n < self.min_state_subscribers or not readers_ok) and waited < self.startup_timeout_s:
            return
        if n < self.min_state_subscribers:
            self.warn.warn("start", f"starting with {n} of {self.min_state_subscribers} subscribers of "
                                    f"/bb2/state_native after {waited:.1f} s")
        if not readers_ok:
            self.warn.warn("start_readers", f"starting after {waited:.1f} s: "
                           + (f"no reader of {', '.join(unread)}" if unread else "the readers still matching"))
        self.start_timer.cancel()
        self._next_tick = time.monotonic()  # before `started`: the real-time thread reads both unlocked
        self.started = True
        self._publish_state()

    def _watchdog(self) -> None:
        if not self._stepping() or not self.started:
            return
        now = time.monotonic()
        timeout = self.startup_timeout_s if self.sim.n == 0 else self.lockstep_timeout_s
        if now - self._first_sent_wall > timeout:
            self.counters["lockstep_timeouts"] += 1
            planes, rps, why = self._held_commands(now, lockstep=True)
            self.warn.warn("lockstep_timeout", f"no answer to step t = {self.t:.3f} s within {timeout:g} s: "
                                               f"stepping with {why}")
            self._set_failsafe(True, f"lockstep timeout: {why}")
            self._advance(planes, rps)
        elif now - self._sent_wall > self.lockstep_retry_s:
            self.counters["lockstep_resends"] += 1
            self.pub["/bb2/state_native"].publish(self._state_native_msg)
            if self._odom_msg is not None and self._odom_msg.header.stamp == self._state_stamp:
                self.pub["/bb2/odom"].publish(self._odom_msg)  # for controllers on state_source odometry
            self._sent_wall = now

    def _held_commands(self, now: float, *, lockstep: bool) -> tuple[np.ndarray, float, str]:
        """Commands for a step without fresh ones: last valid planes/propeller, else the safe default."""
        fresh_planes = self.planes_deg is not None and (lockstep or now - self.planes_wall <= self.command_timeout_s)
        if self._ans_planes is not None:
            planes, pw = self._ans_planes, "this step's planes"
        elif fresh_planes:
            planes, pw = self.planes_deg, "last valid planes"
        else:
            planes, pw = np.zeros(5), "neutral planes"
        if self._ans_rps is not None:
            rps, rw = self._ans_rps, "this step's propeller"
        elif self.rps is not None:
            rps, rw = self.rps, "propeller held"
        else:
            rps, rw = self.default_rps, "nominal propeller"
        return planes, rps, f"{pw}, {rw}"

    def _realtime_loop(self) -> None:
        """Real time: step at ``rate_hz`` on absolute monotonic deadlines (sleeps to the next deadline; a
        step later than a whole period is an overrun: counted, and the schedule restarts from now)."""
        if self.realtime_priority > 0:
            try:
                os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(self.realtime_priority))  # this thread
                self.scheduling = f"SCHED_FIFO {self.realtime_priority}"
                self.node.get_logger().info(f"stepping thread: SCHED_FIFO priority {self.realtime_priority}")
            except (OSError, AttributeError) as exc:
                self.scheduling = f"normal (SCHED_FIFO {self.realtime_priority} refused: {exc})"
                self.node.get_logger().warning(f"realtime_priority {self.realtime_priority} refused ({exc}): "
                                               "stepping with normal scheduling")
        if self.hold_cpu_dma_latency:
            self._hold_cpu_dma_latency()
        period = 1.0 / self.rate_hz
        late = 0  # consecutive ticks with no time left before the next deadline
        while not self._rt_stop.is_set():
            if not self.started:  # _start sets the first deadline
                self._rt_stop.wait(0.01)
                continue
            delay = self._next_tick - time.monotonic()
            if delay > 0:
                time.sleep(delay)
                late = 0
            else:
                late += 1
                if late == max(1, round(self.rate_hz)) and self.realtime_priority > 0:
                    # a real-time thread that never sleeps would starve its core: give the priority up
                    try:
                        os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
                        self.scheduling = "normal (SCHED_FIFO given up: overruns)"
                    except (OSError, AttributeError):
                        pass
                    self.warn.warn("rt_drop", f"{late} steps in a row (a second's worth at {self.rate_hz:g} Hz) "
                                              "left no time before the next deadline: stepping thread back to "
                                              "normal scheduling")
            with self._lock:
                if self._rt_stop.is_set():
                    break
                try:
                    self._tick(period)
                except Exception as exc:  # never a silent dead stepping thread: the node exits 1, says why
                    self.diverged = self.diverged or f"stepping thread failed: {type(exc).__name__}: {exc}"
                    self.exit_code = 1
                    self.node.get_logger().error(self.diverged)
                    self.done = True
                    return

    def _hold_cpu_dma_latency(self) -> None:
        """PM QoS: 0 us wake-up latency for as long as the file stays open (closed in :meth:`close`)."""
        try:
            self._dma_fd = os.open("/dev/cpu_dma_latency", os.O_WRONLY)
            os.write(self._dma_fd, (0).to_bytes(4, sys.byteorder, signed=True))
            self.cpu_latency = "held at 0 us"
        except OSError as exc:
            self._dma_fd = None
            self.cpu_latency = f"not held ({exc.strerror})"
            self.node.get_logger().warning(f"/dev/cpu_dma_latency: {exc.strerror}: idle cores keep their "
                                           "wake-up latency")

    def _tick(self, period: float) -> None:
        """Real-time step (the stepping thread, at its deadline ``self._next_tick``)."""
        if not self._stepping():
            return
        now = time.monotonic()
        if now - self._next_tick > period:
            self.counters["overruns"] += 1
            self._next_tick = now
        self._next_tick += period
        planes_ok = self.planes_deg is not None and now - self.planes_wall <= self.command_timeout_s
        rps_ok = self.rps is not None and now - self.rps_wall <= self.command_timeout_s
        if planes_ok and rps_ok:
            self._set_failsafe(False, "")
            self._advance(self.planes_deg, self.rps)
            return
        planes = self.planes_deg if planes_ok else np.zeros(5)
        rps = self.rps if self.rps is not None else self.default_rps
        missing = [w for w, ok in (("plane", planes_ok), ("propeller", rps_ok)) if not ok]
        why = (f"no valid {' and '.join(missing)} command for {self.command_timeout_s:g} s: "
               + ("planes neutral" if not planes_ok else "planes held") + ", propeller "
               + ("held" if self.rps is not None else f"nominal {self.default_rps:.4g} rps"))
        self.warn.warn("failsafe", f"failsafe: {why}")
        self._set_failsafe(True, why)
        self._advance(planes, rps)

    def _set_failsafe(self, on: bool, why: str) -> None:
        changed = on != self.failsafe
        self.failsafe, self.failsafe_reason = on, why
        if on:
            self.counters["failsafe_steps"] += 1
        if changed:
            if not on:
                self.node.get_logger().info("failsafe released: valid commands again")
            self._publish_status()

    def _advance(self, planes_deg: np.ndarray, rps: float) -> None:
        self._ans_planes = self._ans_rps = None
        state = VehicleState.from_vector(self.sim.t, self.sim.x)
        # /clock goes to t_n+1 now, before the integration: the nodes on sim time (every controller) take it
        # while the ROM steps, not when the state of t_n+1 comes and they must answer it (recorders log the
        # state of t_n+1 at t_n+1 all the same)
        self.pub["/clock"].publish(cv.clock_message(self.sim.t_next))
        try:
            rec = self.sim.step(planes_deg, rps)
        except (NonFiniteStateError, ValueError) as exc:
            self.diverged = str(exc)
            self.exit_code = 1
            self.node.get_logger().error(f"simulation stopped: {exc}")
            self._publish_status()
            self.done = self.exit_at_end
            return
        finished = self.t >= self.duration_s - 1e-9
        if not finished:
            self._publish_trigger(clock=False)  # first: the controllers work on step n+1 while the sensors go out
        t = rec.t
        f_flu = cv.specific_force_flu(state, rec.ev.xdot[6:9], self.g)
        self.pub["/bb2/imu"].publish(cv.imu_message(state, f_flu))
        self.pub["/bb2/planes/state"].publish(cv.planes_message(t, np.radians(rec.act.planes_deg)))
        self.pub["/bb2/propeller/state"].publish(cv.propeller_message(t, rec.act.rps * TWO_PI))
        if finished:
            self._publish_trigger(clock=False)
            self._publish_sensors()
            self.finished = True
            self.node.get_logger().info(f"mission duration reached at t = {self.t:.3f} s")
            self._publish_status()
            self.done = self.exit_at_end
            return
        self._publish_sensors()

    def _publish_state(self) -> None:
        self._publish_trigger()
        self._publish_sensors()

    def _publish_trigger(self, *, clock: bool = True) -> None:
        """(/clock and) the exact state of the current step (what the controllers answer)."""
        state = VehicleState.from_vector(self.sim.t, self.sim.x)
        if self._csv:
            self._csv.writerow([repr(float(state.t))] + ["%.17g" % v for v in self.sim.x])
        if clock:
            self.pub["/clock"].publish(cv.clock_message(state.t))
        self._state_native_msg = cv.state_native_message(state)
        self._state_stamp = cv.stamp(state.t)
        self.pub["/bb2/state_native"].publish(self._state_native_msg)
        self._sent_wall = self._first_sent_wall = time.monotonic()

    def _publish_sensors(self) -> None:
        """Odometry, depth and altitude of the current step."""
        state = VehicleState.from_vector(self.sim.t, self.sim.x)
        t = state.t
        self._odom_msg = cv.state_to_odometry(state)
        self.pub["/bb2/odom"].publish(self._odom_msg)
        self.pub["/bb2/depth"].publish(cv.depth_message(t, state.depth_m))
        if self.terrain is not None:
            try:
                alt = float(self.terrain.clearance(state.p_native))
            except ValueError:  # off the terrain grid: no bottom known
                alt = math.inf
            self.pub["/bb2/altitude"].publish(cv.altitude_message(t, alt))

    # ------------------------------------------------------------------------------------ status
    def status_values(self) -> dict[str, str]:
        now = time.monotonic()
        dt = now - self._wall_at_status
        if dt > 0.2:
            self._rate_measured = (self.sim.n - self._steps_at_status) / dt
            self._steps_at_status, self._wall_at_status = self.sim.n, now
        state = "diverged" if self.diverged else "finished" if self.finished else "running"
        vals = {"mode": self.time_mode, "state": state, "sim_time_s": f"{self.t:.6f}", "step": str(self.sim.n),
                "failsafe": str(self.failsafe).lower(), "failsafe_reason": self.failsafe_reason,
                "rate_hz": f"{self.rate_hz:g}" if self.time_mode == "realtime" else "as fast as the graph",
                "scheduling": self.scheduling if self.time_mode == "realtime" else "executor (lockstep)",
                "cpu_dma_latency": self.cpu_latency,
                "step_rate_hz": f"{self._rate_measured:.2f}",
                "real_time_factor": f"{self._rate_measured * self.h:.3f}",
                "duration_s": f"{self.duration_s:g}", "mission_file": self.mission_file}
        if self.diverged:
            vals["error"] = self.diverged
        vals.update({k: str(v) for k, v in self.counters.items()})
        return vals

    def _publish_status(self) -> None:
        from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

        from bb2_msgs_py.conversions import stamp

        vals = self.status_values()
        level = (DiagnosticStatus.ERROR if self.diverged else DiagnosticStatus.WARN if self.failsafe
                 else DiagnosticStatus.OK)
        msg_text = (f"diverged: {self.diverged}" if self.diverged else
                    f"FAILSAFE: {self.failsafe_reason}" if self.failsafe else f"{vals['state']}, {self.time_mode}")
        st = DiagnosticStatus(level=level, name="bb2/simulator", message=msg_text, hardware_id="bb2_rom",
                              values=[KeyValue(key=k, value=v) for k, v in vals.items()])
        from std_msgs.msg import Header
        self.pub["/bb2/status"].publish(DiagnosticArray(header=Header(stamp=stamp(self.t)), status=[st]))

    def close(self) -> None:
        if getattr(self, "_rt_thread", None) is not None:
            self._rt_stop.set()
            self._rt_thread.join(timeout=2.0)
        if getattr(self, "_dma_fd", None) is not None:
            os.close(self._dma_fd)  # the kernel drops the request
            self._dma_fd = None
        if self._csv_fh:
            self._csv_fh.close()


def main(args: Sequence[str] | None = None) -> int:
    """Entry point (``ros2 run bb2_sim simulator``)."""
    return run_node("simulator", SimulatorShell, args)


if __name__ == "__main__":
    sys.exit(main())
