"""``simulator`` node: the BB2 ROM at a fixed step, in lockstep with the controllers or in real time.

Parameters (``config/bb2_graph.yaml`` lists them all with their defaults).  Live (``ros2 param set`` takes
effect at once, checked first): ``rate_hz`` (from the next deadline), the gate's timings ``lockstep_timeout_s``,
``lockstep_retry_s``, ``startup_timeout_s``, ``startup_settle_s``, ``command_timeout_s`` (the gate's frozen
``GateTimings`` replaced), ``max_command_age_s``, ``duration_s``, ``exit_at_end``, ``stall_timeout_s``,
``warn_throttle_s``; every
other one is read-only (fixed at start-up; the set is refused):

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
``wait_for_commands``  real time: the first deadline only once valid plane and propeller commands have answered
                       the first state (re-sent every ``lockstep_retry_s``; the controllers are up), at most
                       ``startup_timeout_s`` (then a warning and the failsafe until they come, as without it);
                       ``bb2-launch`` and the launch files set it, so a run does not start on the failsafe.
``realtime_priority``  real time: SCHED_FIFO priority (1-99, default 50) of the stepping thread, so the period
                       holds on a loaded machine (HIL); 0 = normal scheduling.  Refused by the OS (no
                       CAP_SYS_NICE / rtprio limit): one warning, normal scheduling.  A thread that overruns every
                       step for a second of wall time gives the priority up (it would starve its core).
``callback_priority``  real time: SCHED_FIFO priority (1-99) of the process's executor and middleware threads,
                       which receive the commands, so a command is not queued behind other processes (a HIL
                       bench's autopilot answers in time, but a normally scheduled reception beside a busy
                       real-time thread was starved past the command timeout); 0 = normal scheduling (default;
                       ``bb2-launch``, the launch files and ``examples/hil`` set 40).  Lockstep:
                       ``lockstep_priority`` decides.
``hold_cpu_dma_latency`` real time: hold ``/dev/cpu_dma_latency`` at 0 us while running (the PM QoS request
                       of cyclictest and RT setups: idle cores wake without deep C-state or halt exits;
                       measured here: a DDS round trip 150 -> 102 us).  Refused (not root): one warning.
``wait_for_readers``   publish the first state only once every topic this node publishes has had a reader of the
                       node ``reader_node`` (``recorder``; '' = any node) for ``startup_settle_s`` (the readers'
                       side matches the writers a moment later: it then misses nothing), at most
                       ``startup_timeout_s``.  In real time a finished run (``exit_at_end``) then ends only once
                       the recorder acknowledges its final step (``/bb2/recorder/ack``, at most
                       ``recorder_ack_timeout_s``): nothing holds a real-time run back for a recorder starved of
                       CPU, and the steps it has not taken yet would go with this node's writers (``ros2 launch``;
                       ``bb2-launch`` waits for it itself).  Its statuses too: a finished run waits (at most
                       5 s) until every reader of ``bb2/status`` has them, the last one included.
``recorder_ack_window`` lockstep: step at most this many steps ahead of the newest ``/bb2/recorder/ack`` (the
                       recorder's acknowledgement of the states it holds), so a stalled recorder slows the graph
                       instead of losing messages (the controllers' answer is held meanwhile: no re-send, no
                       lockstep timeout); 0 = do not wait (``bb2-launch`` sets 10 when it records in lockstep).
                       A finished run then ends (``exit_at_end``) only once the recorder acknowledges its final
                       step, so the last steps still on their way to it are not lost with this node's writers.
``recorder_ack_timeout_s`` lockstep: a recorder that acknowledges nothing for this many wall s is given up on
                       (a warning; the graph steps on and the bag will have a gap) until it acknowledges again.
``command_timeout_s``  real time: a command older than this (wall time since it arrived), or none at all,
                       engages the failsafe: planes commanded to neutral (0 rad), propeller held at the last
                       valid command (the mission's nominal speed command if none ever arrived).  Time the
                       stepping thread itself lost (an overrun: the process stopped or starved, no state went out)
                       is given back to a command that was fresh when the stall began, once per command: the
                       failsafe counts the controllers' silence, not the simulator's.
``max_command_age_s``  a command whose stamp is older than sim time minus this is rejected (stale).
``duration_s``         stop stepping at this sim time (< 0: the mission's duration, none = run on).
``exit_at_end``        exit 0 when the duration is reached (else stay up, status ``finished``); a diverged
                       simulation then exits 1 (status ``diverged``, ``error``), and so does a stalled one.
``stall_timeout_s``    wall s of stepping on the failsafe without a break (every controller silent: in lockstep
                       one step per ``lockstep_timeout_s``) after which the run stops as stalled (status
                       ``stalled``, ``error`` saying what was silent; exit 1 with ``exit_at_end``) rather than
                       crawl on neutral planes; 0 = never (the default; ``bb2-launch`` sets it from ``--stall-timeout``,
                       the launch files from their ``stall_timeout`` argument).
``trajectory_csv``     if set, every state ``t, x12`` (native, ``%.17g``) is written to this CSV.
``sea_file``           "" = the mission's sea and current; else a YAML/JSON file whose ``sea:`` and/or
                       ``current:`` blocks (the mission file's keys, :mod:`bb2_sim.environment`) replace the
                       mission's, or a sea description of format ``bb2_sea/1`` (the ``/bb2/sea`` JSON of a bag),
                       which rebuilds that run's sea exactly.
``sensor_suite``       "" = the mission's ``sensors:`` block; ``none``; or ``tactical`` | ``mems`` | a suite FILE (with
                       the mission's sensor seed and faults): the sensor models (:mod:`bb2_sim.sensors`) whose
                       measurements go out on ``/bb2/sensors/*``, each at its own rate (below).
``status_period_s``    wall period of ``/bb2/status``.
``warn_throttle_s``    at most one warning of a kind per this many wall seconds.
``strict_remaps``      a ``-r`` rule naming no topic of this node is an error (else a warning).

``/bb2/sea`` (latched, once at start) carries the sea and current as JSON, so a bag holds its sea.

Frames: ``odom`` and ``base_link`` (and the sensors' frames) in the root namespace; in a namespace they carry its
name (``/boat1``: ``boat1/odom``, ``boat1/base_link``, ``boat1/imu_link``: :func:`bb2_msgs_py.contract.frame_prefix`),
so the boats of a fleet share ``map`` and keep their own trees.

Sensors (a suite from the mission or ``sensor_suite``): once the step from ``t_n`` is integrated, every sensor
sample whose time falls in ``[t_n, t_n+1)`` (each sensor at its own rate, from the truth interpolated between the
two states: :class:`bb2_sim.sensors.SensorSuite`) and is out of the sensor (latency) goes out on
``/bb2/sensors/imu``, ``pressure``, ``dvl`` (bottom track) or ``dvl/water_track``, ``dvl/ranges``, ``altimeter``,
``gps``, stamped with its time of validity; ``/bb2/sensors/mountings`` (latched) gives the mounting frames and
rates (the suite's /tf_static).  In lockstep the measurements are a function of the seed alone.

Navigation (the mission's ``navigation: sensors``): the vehicle's navigation filter
(:class:`bb2_control.navigation.NavigationFilter`, as the library runner's) takes those samples once the step is
integrated, before the state of ``t_n+1`` goes out; with every state its estimate goes out first on
``/bb2/nav/state_native`` (re-sent with it), and the controllers fly on that.

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

Command validation, the handshake, the watchdog and the failsafe are the ROS-free lockstep gate
(:mod:`bb2_mission.lockstep_gate`): non-finite values, wrong joint names/sizes, a frame other than
the vehicle's ``base_link``, stale or future stamps are rejected (never integrated); plane commands beyond the
ROM's plane limit and propeller commands outside its rps limits are clamped; each with a throttled warning and a
counter in the status.  This node turns messages into the gate's inputs and its decisions into steps and messages.

Its status (``/bb2/status``, ``bb2/simulator``) says ``state``: ``starting`` until the first step is integrated
(waiting for the controllers' first commands or the recorder; ``failsafe`` is then ``false``, nothing decided yet),
``running``, ``finished`` at the end of the duration, ``diverged`` or ``stalled`` (with ``error``).  It goes out at
once on each change of state or failsafe (the first as the node comes up) and every ``status_period_s`` between.
"""
from __future__ import annotations

import collections
import csv
import dataclasses
import math
import os
import sys
import threading
import time
from typing import Callable, Sequence

import numpy as np

from rclpy.clock import Clock, ClockType
from rclpy.node import Node

from bb2_mission.components import (build_model, build_navigation_filter, build_sensor_suite, build_simulator,
                                    expected_speed, mission_warnings, nominal_rps, sensor_spec,
                                    step_truths)
from bb2_mission.lockstep_gate import (CommandLimits, CommandValidator, GateTimings, LockstepGate, RecorderAck,
                                       StepDecision, TimeMode, Verdict, WatchdogAction)
from bb2_msgs_py import conversions as cv
from bb2_msgs_py import scene_markers
from bb2_msgs_py.contract import SCENE_TOPIC, SEA_SURFACE_TOPIC
from bb2_msgs_py.sensor_conversions import SENSOR_TOPICS, mountings_json, sample_messages
from bb2_msgs_py.contract import (FRAME_BASE_LINK, FRAME_ODOM, PLANE_JOINTS, PROPELLER_JOINT, frame_prefix,
                                  message_class, node_topic_name, qos_profile, recorded_in_namespace,
                                  vehicle_frame)
from bb2_sim.integrator import NonFiniteStateError
from bb2_sim.step_stability import substeps_hint
from bb2_sim.state import VehicleState

from bb2_ros import heap
from bb2_ros.node_common import (NAV_STATE_TOPIC, NodeConfigError, Throttle, build_piece, check_remaps,
                                 contract_publisher, declare, declare_callback_priority, declare_lockstep_priority,
                                 cpu_times, format_cpus, mission_only, node_options, parse_cpus, pin_this_thread,
                                 process_cpus, require_choice, require_positive, run_node)

TOPICS_OUT = ("/clock", "/bb2/state_native", "/bb2/odom", "/bb2/imu", "/bb2/depth", "/bb2/altitude",
              "/bb2/planes/state", "/bb2/propeller/state", "/bb2/sea", "/bb2/status", "/diagnostics",
              SCENE_TOPIC, SEA_SURFACE_TOPIC)
# a late reader still gets these: no reason to wait for one before the first step
LATCHED_OUT = ("/bb2/sea", "/bb2/sensors/mountings", SCENE_TOPIC)
STATUS_DELIVERY_TIMEOUT_S = 5.0  # a finished run waits at most this long (wall) for its statuses to reach the readers
TOPICS_IN = ("/bb2/planes/cmd", "/bb2/propeller/cmd", "/bb2/mission/progress",  # progress: end_at_progress
             "/bb2/recorder/ack")  # recorder_ack_window
TWO_PI = 2.0 * math.pi
RT_GIVE_UP_S = 1.0  # real time: a SCHED_FIFO stepping thread late on every tick for this long (wall s) drops it
RECORDER_WAIT_WARN_S = 1.0  # a hold for the recorder longer than this (wall s) is said, once per hold


def status_state(*, diverged: bool, finished: bool, steps: int, stalled: bool = False) -> str:
    """The status's ``state``: ``diverged``, ``stalled`` (stopped on the failsafe: ``stall_timeout_s``),
    ``finished``, ``starting`` (no step integrated yet) or ``running``."""
    return ("diverged" if diverged else "stalled" if stalled else "finished" if finished
            else "starting" if steps == 0 else "running")


class Simulator(Node):
    """The simulator node: parameters, publishers, the lockstep/real-time stepping and the status."""

    def __init__(self, argv: Sequence[str]):
        super().__init__("simulator", **node_options())
        # the vehicle's frame ids: base_link, odom in the root namespace; boat1/base_link, boat1/odom in /boat1
        self.frame_prefix = frame_prefix(self.get_namespace())
        self.base_link = vehicle_frame(FRAME_BASE_LINK, self.frame_prefix)
        self.odom_frame = vehicle_frame(FRAME_ODOM, self.frame_prefix)
        node = self
        self._lock = threading.RLock()  # real time: the stepping thread vs the executor's callbacks
        self.scheduling = "normal"  # of the real-time stepping thread (status)
        self.cpu_latency = "not held"  # /dev/cpu_dma_latency (status)
        P = lambda *a: declare(node, *a)  # noqa: E731  (read-only: fixed at start-up)

        def L(name, default, desc, apply, check):  # live: `ros2 param set` takes effect at once (issue 13)
            return declare(node, name, default, desc, on_set=self._locked(apply), check=check)

        def positive(name, zero=False):
            return lambda v: require_positive(name, v, allow_zero=zero)
        self.mission_file = P("mission_file", "", "mission YAML (same file as `bb2-sim mission`)")
        self.time_mode = TimeMode(require_choice("time_mode", P(
            "time_mode", "lockstep", "lockstep (wait for the controllers each step) | realtime (wall clock)"),
            [m.value for m in TimeMode]))
        self.rate_hz = L("rate_hz", 20.0, "realtime: steps per wall second (20 = 1/Ts = real time); from the "
                         "next step when set", lambda v: setattr(self, "rate_hz", v), positive("rate_hz"))
        self.lockstep_timeout_s = L(
            "lockstep_timeout_s", 1.0, "lockstep: wall s to wait for a step's answer before holding commands",
            lambda v: self._set_timing("lockstep_timeout_s", v), positive("lockstep_timeout_s"))
        self.lockstep_retry_s = L(
            "lockstep_retry_s", 0.1, "lockstep: wall s before re-sending an unanswered /bb2/state_native",
            lambda v: self._set_timing("lockstep_retry_s", v), positive("lockstep_retry_s"))
        self.startup_timeout_s = L(
            "startup_timeout_s", 30.0, "lockstep: timeout of the first step (graph still starting)",
            lambda v: self._set_timing("startup_timeout_s", v), positive("startup_timeout_s"))
        self.startup_settle_s = L(
            "startup_settle_s", 0.5, "lockstep: hold the first step this long after its first answer",
            lambda v: self._set_timing("startup_settle_s", v), positive("startup_settle_s", zero=True))
        self.realtime_priority = int(P("realtime_priority", 50,
                                       "realtime: SCHED_FIFO priority (1-99) of the stepping thread; 0 = normal "
                                       "scheduling (refused by the OS: a warning, normal scheduling)"))
        self.hold_cpu_dma_latency = bool(P(
            "hold_cpu_dma_latency", True, "realtime: hold /dev/cpu_dma_latency at 0 us while running (idle cores "
            "wake fast, as cyclictest does); refused by the OS: a warning"))
        if not 0 <= self.realtime_priority <= 99:
            raise NodeConfigError(f"realtime_priority must be in 0..99, got {self.realtime_priority}")
        self.stepping_cpus = parse_cpus(P(
            "stepping_cpus", "", "realtime: CPUs of the stepping thread, as taskset -c takes them ('0', '0,2'); '' = "
            "the process's (its cpus). Apart from the CPUs of the controllers and of this node's other threads, "
            "a woken controller does not wait behind the stepping thread"), "stepping_cpus")
        self.stepping_cpu_affinity = "the process's"
        self.realtime_loop = require_choice("realtime_loop", P(
            "realtime_loop", "executor", "realtime: executor (the thread that spins the process's executor steps at "
            "the deadlines and runs every callback between them: a controller composed with the simulator answers "
            "a state on the thread that published it, and a command wakes no second thread; ros2 run, the container "
            "and bb2-launch drive it -- a process of your own spinning this node calls Simulator.drive) | thread (a "
            "stepping thread of its own beside the executor's)"), ("executor", "thread"))
        self.answer_first_s = L(
            "answer_first_s", 0.005, "realtime: once a step's state (and odometry) went out, publish the step's "
            "other samples (IMU, plane and propeller states, depth, altitude, sensors) only when the controllers' "
            "plane command to it has come, or after this many wall s (at most half a period): until then they take "
            "neither the interpreter lock (composed) nor a CPU (one process per node) from the controllers; "
            "0 = at once", lambda v: setattr(self, "answer_first_s", v), positive("answer_first_s", zero=True))
        self._on_scheduling: Callable[[str], None] | None = None  # drive(): the executor's thread's scheduling
        self._answered = threading.Event()  # real time: the plane command to the state of the current step came
        self._started = threading.Event()  # real time: set with `started` (wakes the stepping loop at once)
        self._deferred: Callable[[], None] | None = None  # real time: the step's samples held for the answer
        self.samples_after_answer = 0  # real time: steps whose samples waited for the answer ...
        self.samples_after_wait = 0  # ... and steps whose answer did not come within answer_first_s
        self.command_timeout_s = L(
            "command_timeout_s", 0.5, "realtime: wall s without a valid command before the failsafe",
            lambda v: self._set_timing("command_timeout_s", v), positive("command_timeout_s"))
        self.max_command_age_s = L(
            "max_command_age_s", 1.0, "reject commands stamped more than this (sim s) before the sim time",
            self._set_max_command_age, positive("max_command_age_s"))
        duration = L("duration_s", -1.0, "stop at this sim time (< 0: mission duration; none: run on); when set, "
                     "for the steps to come (a finished run stays finished)", self._set_duration, None)
        self.stall_timeout_s = L(
            "stall_timeout_s", 0.0, "wall s of stepping on the failsafe without a break after which the run stops "
            "as stalled (status stalled; exit 1 with exit_at_end); 0 = never (bb2-launch: --stall-timeout)",
            lambda v: setattr(self, "stall_timeout_s", v), positive("stall_timeout_s", zero=True))
        self.exit_at_end = L("exit_at_end", False, "exit 0 when the duration is reached (set true on a finished "
                             "run: it exits now)", self._set_exit_at_end, None)
        self._path_flown = False  # /bb2/mission/progress reached 1 (end_at_progress)
        self.end_at_progress = bool(P("end_at_progress", False, "also end the run (as at the duration) once "
                                      "/bb2/mission/progress reaches 1: the path flown, where bb2-launch and the "
                                      "library runner end it (the launch files set it)"))
        self.scene = bool(P("scene_markers", True, f"publish the hull, the terrain and the calm sea plane on "
                                                  f"{SCENE_TOPIC} (latched, once at start) for RViz / Foxglove"))
        sea_period = float(P("scene_sea_period_s", -1.0,
                             f"sim s between two free-surface markers around the boat on {SEA_SURFACE_TOPIC} "
                             f"(waves only); 0 = none; < 0 = auto: 1 s in real time, none in lockstep (about "
                             f"11 ms each, which a lockstep run would wait for)"))
        csv_path = P("trajectory_csv", "", "write t and the native state of every step to this CSV ('' = off)")
        sea_file = P("sea_file", "", "'' = the mission's sea and current; else a YAML/JSON file with sea: and/or "
                                     "current: blocks, or a bb2_sea/1 description (a bag's /bb2/sea), replacing them")
        sensor_suite = str(P("sensor_suite", "", "'' = the mission's sensors: block; none; or tactical | mems | "
                                                 "a suite FILE (with the mission's sensor seed and faults)"))
        self.min_state_subscribers = int(P("min_state_subscribers", 0,
                                           "wait for this many /bb2/state_native readers before the first step"))
        self._readers_since: float | None = None
        wait_for_commands = bool(P(  # (declared in lockstep too: one parameter list whatever the mode)
            "wait_for_commands", False, "real time: start the clock (the first deadline) only once valid plane and "
            "propeller commands answer the first state (re-sent every lockstep_retry_s), at most startup_timeout_s; "
            "false = step on the failsafe from the first tick until they come (bb2-launch sets it)"))
        self._awaiting_commands = self.time_mode is TimeMode.REALTIME and wait_for_commands
        self.wait_for_readers = bool(P("wait_for_readers", False,
                                       "publish the first state only once every topic published here has a "
                                       "reader (a recorder), at most startup_timeout_s"))
        self.reader_node = str(P("reader_node", "recorder", "with wait_for_readers: the node whose readers are "
                                 "waited for (another reader, e.g. a Foxglove bridge, does not count); '' = any"))
        ack_window = int(P("recorder_ack_window", 0, "lockstep: step at most this many steps ahead of the newest "
                             "/bb2/recorder/ack (a stalled recorder slows the graph, loses nothing); 0 = do not wait"))
        if ack_window < 0:
            raise NodeConfigError(f"recorder_ack_window must be >= 0, got {ack_window}")
        ack_timeout = L("recorder_ack_timeout_s", 30.0, "lockstep: wall s without a recorder acknowledgement before "
                        "stepping on without it (the bag will have a gap)",
                        lambda v: setattr(self.ack, "timeout_s", v), positive("recorder_ack_timeout_s"))
        self.status_period_s = require_positive("status_period_s", P(
            "status_period_s", 1.0, "wall period of /bb2/status"))
        throttle_s = L("warn_throttle_s", 2.0, "at most one warning of a kind per this many wall seconds",
                       lambda v: setattr(self.warn, "period_s", v), positive("warn_throttle_s"))
        strict = bool(P("strict_remaps", False, "a remap rule naming no topic of this node is an error"))
        check_remaps(node, argv, TOPICS_OUT + TOPICS_IN + SENSOR_TOPICS + (NAV_STATE_TOPIC,), strict=strict)
        lockstep = self.time_mode is TimeMode.LOCKSTEP
        declare_lockstep_priority(self, lockstep=lockstep)
        # real time: the command reception's priority (lockstep: lockstep_priority decides)
        declare_callback_priority(self, applies=not lockstep)

        # this node's pieces only: the ROM at the mission's initial state and the stack's nominal propeller
        self.mission = mission_only(self.mission_file)
        self.environment = self.mission.environment if not sea_file else load_sea_file(sea_file,
                                                                                       self.mission.environment)
        self.sim = build_piece(self.mission, lambda m: build_simulator(m, build_model(m, self.environment)))
        self.terrain = self.mission.terrain
        self.sensor_spec = build_piece(self.mission, lambda m: sensor_spec(m, sensor_suite))
        self.suite = None if self.sensor_spec is None else build_piece(  # None: 'none', or no sensors: block
            self.mission, lambda m: build_sensor_suite(m, self.sim.model, self.sensor_spec))
        self.g = float(self.sim.model.params.g)
        self.nav = None  # navigation: sensors -- the vehicle's navigation filter on its own sensor samples
        if self.mission.navigation == "sensors":
            if self.suite is None:
                raise NodeConfigError(f"mission {self.mission.name!r}: navigation: sensors needs a sensor suite "
                                      f"(sensor_suite is {sensor_suite!r})")
            self.nav = build_piece(self.mission, lambda m: build_navigation_filter(self.suite, self.sim))
        self._nav_msg = None
        self.h = float(self.sim.h)
        if duration < 0:
            duration = float(self.mission.duration)
        self.duration_s = duration
        limits = CommandLimits.from_actuators(self.sim.model.params.act, plane_joints=PLANE_JOINTS,
                                              propeller_joint=PROPELLER_JOINT, frame_id=self.base_link)
        rps = build_piece(self.mission, nominal_rps)  # the stack's feed-forward propeller command, rev/s
        self._expected_speed_mps = build_piece(self.mission, lambda m: expected_speed(m, rps))  # (a divergence's hint)
        self.gate = LockstepGate(
            CommandValidator(limits, mode=self.time_mode, max_command_age_s=self.max_command_age_s, step_s=self.h),
            GateTimings(lockstep_timeout_s=self.lockstep_timeout_s, lockstep_retry_s=self.lockstep_retry_s,
                        startup_timeout_s=self.startup_timeout_s, startup_settle_s=self.startup_settle_s,
                        command_timeout_s=self.command_timeout_s),
            nominal_rps=rps)
        # faster than its sub-steps fly, a sea steeper than any wave
        for warning in build_piece(self.mission, lambda m: mission_warnings(m, rps)):
            self.get_logger().warning(warning)
        self._failsafe_shown = False  # the failsafe state last logged / published
        self._takeover_t: float | None = None  # sim time of the first step on valid commands
        if ack_window and self.time_mode is not TimeMode.LOCKSTEP:
            node.get_logger().warning("recorder_ack_window applies in lockstep only: ignored in real time")
            ack_window = 0
        self.ack = RecorderAck(ack_window, step_ns=cv.seconds_to_ns(self.h), t0_ns=self._t_ns(),
                               timeout_s=ack_timeout)
        # real time with a recorder: the end waits for its acknowledgement of the final step (no window: the steps
        # never wait for it)
        self._final_ack = self.time_mode is not TimeMode.LOCKSTEP and self.wait_for_readers
        self._held: StepDecision | None = None  # the controllers' answer, held while the recorder lags
        self._wait_said = False  # the current hold was said (past RECORDER_WAIT_WARN_S)

        # publishers / subscriptions (contract QoS)
        def pub(name):
            return contract_publisher(node, name)

        self.pub = {n: pub(n) for n in TOPICS_OUT if (n != "/bb2/altitude" or self.terrain is not None)
                    and n not in (SCENE_TOPIC, SEA_SURFACE_TOPIC)}  # the scene's: below, when they are published
        if self.suite is not None:
            self.pub.update({n: pub(n) for n in SENSOR_TOPICS})
        if self.nav is not None:
            self.pub[NAV_STATE_TOPIC] = pub(NAV_STATE_TOPIC)
        def sub(type_name, name, callback):  # the readers' QoS of the contract
            return node.create_subscription(message_class(type_name), node_topic_name(name), self._locked(callback),
                                            qos_profile(name, reader=True))

        self.sub_planes = sub("sensor_msgs/msg/JointState", "/bb2/planes/cmd", self._on_planes)
        self.sub_prop = sub("sensor_msgs/msg/JointState", "/bb2/propeller/cmd", self._on_propeller)
        if self.ack.enabled or self._final_ack:
            self.sub_ack = sub("std_msgs/msg/Header", "/bb2/recorder/ack", self._on_ack)
        if self.end_at_progress:
            self.sub_progress = node.create_subscription(
                message_class("std_msgs/msg/Float64"), node_topic_name("/bb2/mission/progress"),
                self._locked(lambda m: setattr(self, "_path_flown", self._path_flown or m.data >= 1.0)),
                qos_profile("/bb2/mission/progress", reader=True))
        self.warn = Throttle(node.get_logger(), throttle_s)
        self.overruns = 0  # real time: steps later than a whole period (the stepping thread's own count)
        self._csv_fh = open(csv_path, "w", newline="") if csv_path else None
        self._csv = csv.writer(self._csv_fh) if self._csv_fh else None
        if self._csv:
            self._csv.writerow(["t", "x", "y", "z", "phi", "theta", "psi", "u", "v", "w", "p", "q", "r"])

        from std_msgs.msg import String
        self.pub["/bb2/sea"].publish(String(data=self.environment.description_json(self.g)))
        from bb2_sim.maneuvers import model_sea
        self.sea = model_sea(self.sim.model)
        if sea_period < 0:
            sea_period = 1.0 if self.time_mode is TimeMode.REALTIME else 0.0
        self.sea_period_s = sea_period if self.sea is not None and self.scene else 0.0
        self._sea_next_t = self.sim.t
        if self.sea_period_s > 0:
            self.pub[SEA_SURFACE_TOPIC] = pub(SEA_SURFACE_TOPIC)
        if self.scene:
            self.pub[SCENE_TOPIC] = pub(SCENE_TOPIC)
            self._publish_scene()
        if self.suite is not None:
            self.pub["/bb2/sensors/mountings"].publish(String(data=mountings_json(
                self.suite.config, self.sensor_spec.seed, frame_prefix=self.frame_prefix)))

        self.finished = False
        self.diverged = ""
        self.stalled = ""  # why the run stopped on the failsafe (stall_timeout_s)
        self._failsafe_since: float | None = None  # wall s of the first step of the failsafe now engaged
        # (t, speed) of the states stepped from over the last 2 s and a little more: a divergence at a speed where
        # the ROM's step is numerically unstable is said with the mission's ``substeps`` that would fly it
        self._recent_speeds: collections.deque[tuple[float, float]] = collections.deque(
            maxlen=int(math.ceil(2.0 / self.h)) + 2)
        self.done = False
        self._final_wait_since: float | None = None  # wall s the finished run began waiting for the recorder
        self._status_wait_since: float | None = None  # wall s it began waiting for its statuses to be delivered
        self._final_wait_said = False  # real time: the wait for the recorder's final acknowledgement was said
        self.exit_code = 0
        self._odom_msg = None  # the last odometry published (re-sent with its state; the template below, refilled)
        # each step's odometry and IMU sample are written into one message each (publishing copies it; rclpy
        # builds every nested default of a new message first: 4-5 times the cost)
        from nav_msgs.msg import Odometry
        from sensor_msgs.msg import Imu

        self._odom_template, self._imu_template = Odometry(), Imu()
        self._t_start_wall = time.monotonic()
        self._steps_at_status, self._wall_at_status = 0, self._t_start_wall
        self._rate_measured = 0.0

        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.status_timer = node.create_timer(self.status_period_s, self._locked(self._publish_status), clock=steady)
        self.started = False
        self.start_timer = node.create_timer(0.02, self._locked(self._start), clock=steady)
        # a status at once (``starting``; transient local, so a reader that matches later has it): a run killed
        # or stopped within its first status period still says what the simulator was doing
        self._publish_status()
        if self.time_mode is TimeMode.LOCKSTEP:
            self.watchdog = node.create_timer(min(0.01, self.lockstep_retry_s / 2), self._watchdog, clock=steady)
        else:  # on absolute wall deadlines (not an executor timer: no callback queue ahead)
            self._rt_stop = threading.Event()
            if not self.drives_executor:  # a thread of its own (else: run_nodes's spinning thread calls drive)
                self._rt_thread = threading.Thread(target=self._realtime_loop, name="bb2-sim-realtime", daemon=True)
                self._rt_thread.start()
        node.get_logger().info(
            f"simulator up: mission {self.mission_file}, {self.time_mode.value}"
            + (f" at {self.rate_hz:g} Hz" if self.time_mode is TimeMode.REALTIME else "")
            + f", Ts = {self.h:g} s, duration {self.duration_s:g} s")

    # ------------------------------------------------------------------------------------ live parameters
    def _set_timing(self, name: str, value: float) -> None:
        """A gate timing set at run time: the gate's own (frozen) settings are replaced."""
        setattr(self, name, value)
        self.gate.timings = dataclasses.replace(self.gate.timings, **{name: value})

    def _set_max_command_age(self, value: float) -> None:
        self.max_command_age_s = value
        self.gate.validator.max_age_ns = int(value * 1e9)

    def _set_duration(self, value: float) -> None:
        self.duration_s = value if value >= 0 else float(self.mission.duration)

    def _set_exit_at_end(self, value: bool) -> None:
        self.exit_at_end = value
        if value and (self.diverged or self.stalled):
            self._end_after_error()
        elif value and self.finished:
            self._end_when_recorded()

    def _end_when_recorded(self) -> None:
        """A finished run ends (``done``, with ``exit_at_end``) once the recorder holds its final step: in lockstep
        with ``recorder_ack_window`` the last steps may still be on their way to it when the mission ends, and they
        would be lost with this node's writers.  Waits for the acknowledgement of the final state at most
        ``recorder_ack_timeout_s`` (wall), then ends all the same with a warning (the bag's gaps say the loss)."""
        if not self.exit_at_end or self.done:
            return
        # (real time: only a recorder that acknowledged during the run -- ours -- is waited for, not another reader)
        final_ack = self._final_ack and self.ack.acked_ns is not None
        if (self.ack.enabled and self.time_mode is TimeMode.LOCKSTEP or final_ack) and not self.ack.given_up:
            final_ns = self._t_ns()
            if self.ack.acked_ns is None or self.ack.acked_ns < final_ns:
                now = time.monotonic()
                if self._final_wait_since is None:
                    self._final_wait_since = now
                if final_ack and not self._final_wait_said and now - self._final_wait_since > 0.5:
                    self._final_wait_said = True
                    self.get_logger().info(f"waiting for the recorder to acknowledge the final step t = "
                                           f"{self.t:.3f} s (its last: t = {self.ack.acked_ns * 1e-9:.3f} s; at most "
                                           f"{self.ack.timeout_s:g} s)")
                if now - self._final_wait_since < self.ack.timeout_s:
                    return
                self.get_logger().warning(
                    f"the recorder did not acknowledge the final step t = {self.t:.3f} s within recorder_ack_timeout_s "
                    f"{self.ack.timeout_s:g} s: ending all the same (the bag may lack the last steps)")
                self._final_wait_said = False
        if self._final_wait_said:
            self.get_logger().info(f"the recorder acknowledged the final step after "
                                   f"{time.monotonic() - self._final_wait_since:.1f} s")
            self._final_wait_said = False
        if self._statuses_waited_for():
            self.done = True

    def _end_after_error(self) -> None:
        """A run stopped on an error (``diverged``, ``stalled``) ends (``done``, with ``exit_at_end``) once every
        reader of ``bb2/status`` has the status that says why (at most ``STATUS_DELIVERY_TIMEOUT_S``): the node's
        writers go with it, and the recorder's bag would end without it (a stalled run analysed as stopped)."""
        if self.exit_at_end and not self.done and self._statuses_waited_for():
            self.done = True

    def _statuses_waited_for(self) -> bool:
        """Whether the statuses have reached every reader of ``bb2/status`` (with ``wait_for_readers``; else at
        once), or the wait for them is over (``STATUS_DELIVERY_TIMEOUT_S``, said)."""
        if self.wait_for_readers and not self._statuses_delivered():
            now = time.monotonic()
            self._status_wait_since = self._status_wait_since or now
            if now - self._status_wait_since < STATUS_DELIVERY_TIMEOUT_S:
                return False
            self.get_logger().warning(f"the statuses were not delivered to every reader of bb2/status within "
                                      f"{STATUS_DELIVERY_TIMEOUT_S:g} s: ending all the same")
        return True

    def _statuses_delivered(self) -> bool:
        """Whether every reader of ``bb2/status`` the graph shows is matched with this node's status writer and has
        acknowledged every status (the final one, ``finished``, included).  On a short run under load the recorder's
        reader may match the status writer only after the last step: the writer's history (transient local) then
        reaches it, if the writer is still there -- so the finished run waits for that before ending."""
        from rclpy.duration import Duration

        pub = self.pub["/bb2/status"]
        try:
            readers = self.count_subscribers(self.resolve_topic_name(node_topic_name("/bb2/status")))
            return pub.get_subscription_count() >= readers and pub.wait_for_all_acked(Duration(seconds=0))
        except Exception:  # noqa: BLE001 - a middleware that cannot tell: do not hold the end
            return True

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
    def _say(self, verdict: Verdict) -> None:
        if verdict.message:
            self.warn.warn(verdict.key, verdict.message)

    def _on_planes(self, msg) -> None:
        stamp_ns = cv.stamp_to_ns(msg.header.stamp)
        now_ns = self._t_ns()
        v = self.gate.on_planes(msg.name, msg.position, msg.header.frame_id, stamp_ns, now_ns, time.monotonic())
        self._say(v)
        if v.accepted and self.time_mode is TimeMode.LOCKSTEP:
            self._maybe_advance()
        elif v.accepted and stamp_ns == now_ns:
            self._answered.set()  # the answer to the state just sent: its step's other samples may go

    def _on_propeller(self, msg) -> None:
        v = self.gate.on_propeller(msg.name, msg.velocity, msg.header.frame_id, cv.stamp_to_ns(msg.header.stamp),
                                   self._t_ns(), time.monotonic())
        self._say(v)
        if v.accepted and self.time_mode is TimeMode.LOCKSTEP:
            self._maybe_advance()

    # ------------------------------------------------------------------------------------ stepping
    def _stepping(self) -> bool:
        return not (self.finished or self.diverged or self.stalled)

    def _maybe_advance(self) -> None:
        if self._stepping():
            decision = self.gate.answer(self.sim.n, time.monotonic())
            if decision is not None:
                self._step(decision)

    def _on_ack(self, msg) -> None:
        """The recorder holds every per-step topic up to ``msg.stamp``: a step held for it may go (or, the run
        finished, the node may end)."""
        self.ack.on_ack(cv.stamp_to_ns(msg.stamp))
        if self.finished:
            self._end_when_recorded()
        if self._held is not None and self._stepping():
            held, self._held = self._held, None
            self._step(held)

    def _step(self, d: StepDecision) -> None:
        """Step with the gate's decision (held instead while the recorder lags more than its window); a failsafe
        engaged or released is logged and published once."""
        if self.time_mode is TimeMode.LOCKSTEP and not self.ack.may_step(self._t_ns(), time.monotonic()):
            self._held = d  # (short waits are the normal pace of a loaded machine: said only past 1 s)
            return
        if self._wait_said:
            self.get_logger().info(f"the recorder caught up: stepping on from t = {self.t:.3f} s")
        self._held, self._wait_said = None, False
        if not d.failsafe and self._takeover_t is None:
            self._takeover_t = self.t
        if d.failsafe != self._failsafe_shown:
            self._failsafe_shown = d.failsafe
            if not d.failsafe:
                self.get_logger().info("failsafe released: valid commands again")
            self._publish_status()
        if self._stalls(d):
            return
        self._advance(d.planes_deg, d.rps)

    def _stalls(self, d: StepDecision) -> bool:
        """Whether this step on the failsafe is past ``stall_timeout_s`` of them without a break: the run then stops
        as stalled (said once, status ``stalled``; exit 1 with ``exit_at_end``) instead of stepping."""
        now = time.monotonic()
        if not d.failsafe:
            self._failsafe_since = None
            return False
        self._failsafe_since = self._failsafe_since or now
        if not self.stall_timeout_s or now - self._failsafe_since < self.stall_timeout_s:
            return False
        self.stalled = (f"stalled: stepped on the failsafe for {now - self._failsafe_since:.0f} s of wall time "
                        f"at t = {self.t:.3f} s ({d.reason}; stall_timeout_s {self.stall_timeout_s:g}): is every "
                        f"controller running, on this ROS_DOMAIN_ID and namespace?")
        self.exit_code = 1
        self.get_logger().error(self.stalled)
        self._publish_status()
        self._end_after_error()
        return True

    def _start(self) -> None:
        """Publish the first state once ``min_state_subscribers`` readers of /bb2/state_native are up (or
        after ``startup_timeout_s``), so that a recorder or a test started with the graph misses nothing."""
        n = self.count_subscribers(self.resolve_topic_name(node_topic_name("/bb2/state_native")))  # rclpy counts
        # unremapped names
        def readers(t: str) -> int:  # after -r remaps; the reader node's own readers
            name = self.resolve_topic_name(node_topic_name(t))
            if not self.reader_node:
                return self.count_subscribers(name)
            return sum(i.node_name == self.reader_node for i in self.get_subscriptions_info_by_topic(name))
        # (a boat of a fleet: its recorder leaves the global topics out, so their readers are not waited for)
        unread = [t for t in self.pub if t not in LATCHED_OUT and recorded_in_namespace(t, self.get_namespace())
                  and readers(t) == 0] if self.wait_for_readers else []
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
        self._next_tick = time.monotonic()  # real time: the first deadline once the first state is out (its first
        self._started.set()  # publication's cost, ms on a slow machine, would make the first step late)

    def _poll_end(self) -> None:
        """A run over and not yet ``done``: its bounded wait, for the recorder's acknowledgement of the final step
        and the statuses (finished), or for the status that says why to reach the recorder (diverged, stalled)."""
        if self.finished and not self.done:
            self._end_when_recorded()
        elif (self.diverged or self.stalled) and not self.done:
            self._end_after_error()

    def _watchdog(self) -> None:
        self._poll_end()
        if not self._stepping() or not self.started:
            return
        if self._held is not None:  # answered; waiting for the recorder, not the controllers
            waited = time.monotonic() - (self.ack.waiting_since or time.monotonic())
            if waited >= RECORDER_WAIT_WARN_S and not self._wait_said:
                self._wait_said = True
                held = "none yet" if self.ack.acked_ns is None else f"up to t = {self.ack.acked_ns * 1e-9:.3f} s"
                self.get_logger().warning(
                    f"step from t = {self.t:.3f} s waits for the recorder for {waited:.1f} s now (it holds every "
                    f"per-step topic {held}, {self.ack.lag_steps(self._t_ns())} steps behind; recorder_ack_window "
                    f"{self.ack.window_steps}; given up on after recorder_ack_timeout_s {self.ack.timeout_s:g} s)")
            if self.ack.expired(time.monotonic()):
                self.get_logger().warning(
                    f"the recorder acknowledged nothing for {self.ack.timeout_s:g} s: stepping on without it from "
                    f"t = {self.t:.3f} s (the bag will have a gap)")
                held, self._held = self._held, None
                self._step(held)
            return
        action, decision = self.gate.watchdog(self.sim.n, time.monotonic())
        if action is WatchdogAction.STEP:
            why = decision.reason.removeprefix("lockstep timeout: ")
            self.warn.warn("lockstep_timeout", f"no answer to step t = {self.t:.3f} s within "
                                               f"{self.gate.timeout_s(self.sim.n):g} s: stepping with {why}")
            self._step(decision)
        elif action is WatchdogAction.RESEND:
            self._resend_state()

    def _resend_state(self) -> None:
        """The current state again (the controllers replay their cached answer to a state they answered)."""
        if self._nav_msg is not None:
            self.pub[NAV_STATE_TOPIC].publish(self._nav_msg)
        self.pub["/bb2/state_native"].publish(self._state_native_msg)
        if self._odom_msg is not None and self._odom_msg.header.stamp == self._state_stamp:
            self.pub["/bb2/odom"].publish(self._odom_msg)  # for controllers on state_source odometry

    def _first_commands_in(self) -> bool:
        """Real time with ``wait_for_commands``, before the first deadline: whether the clock may start (the gate's
        :meth:`first_commands`: valid commands have come, or ``startup_timeout_s`` passed: then a warning, and the
        run starts on the failsafe as without the wait); meanwhile the state at t = 0 is re-sent."""
        now = time.monotonic()
        action = self.gate.first_commands(now)
        if action is WatchdogAction.RESEND:
            self._resend_state()
        if action is not WatchdogAction.STEP:
            return False
        waited = self.gate.state_age_s(now)
        if self.gate.has_commands:
            self.get_logger().info(f"real time: the controllers answered the first state after {waited:.1f} s: "
                                   "the clock starts")
        else:
            self.warn.warn("start_commands", f"real time: no valid commands {waited:.1f} s after the first state "
                                             "(startup_timeout_s): the clock starts on the failsafe")
        return True

    @property
    def drives_executor(self) -> bool:
        """Real time with ``realtime_loop`` executor: the process's spinning thread is to call :meth:`drive`
        (:func:`bb2_ros.node_common.run_nodes` does; a node spun otherwise does not step until someone does)."""
        return self.time_mode is TimeMode.REALTIME and self.realtime_loop == "executor"

    def drive(self, executor, keep_going: Callable[[], bool],
              on_scheduling: Callable[[str], None] | None = None) -> None:
        """The real-time loop on the caller's thread, the one that spins ``executor`` (``realtime_loop``
        executor): every wait between deadlines spins it, so the callbacks of every node of the process run here,
        on the stepping thread's priority and CPUs.  A state published here is taken by a composed controller
        in the same turn (the middleware delivers within the process at once) and its answer is back without
        waking another thread.  ``on_scheduling(scheduling)``: the stepping thread's scheduling, when it is set
        or given up (what every node of the process runs its callbacks with).  Returns when ``keep_going()`` is
        false or the node closes."""
        def spin_for(seconds: float, event: threading.Event | None = None) -> bool:
            deadline = time.monotonic() + seconds
            while keep_going() and not self._rt_stop.is_set():
                if event is not None and event.is_set():
                    return True
                left = deadline - time.monotonic()
                if left <= 0:
                    break
                executor.spin_once(timeout_sec=left)
            return event is not None and event.is_set()

        self._on_scheduling = on_scheduling
        self._realtime_loop(pause=spin_for, keep_going=keep_going)

    def _realtime_loop(self, pause: Callable[..., bool] | None = None,
                       keep_going: Callable[[], bool] = lambda: True) -> None:
        """Real time: step at ``rate_hz`` on absolute monotonic deadlines (waits to the next deadline; a
        step later than a whole period is an overrun: counted, and the schedule restarts from now).  ``pause(s,
        event=None)`` waits ``s`` seconds or until ``event`` (a :class:`threading.Event`) is set, and returns whether
        it is: a thread of its own sleeps on the event, :meth:`drive` spins the executor meanwhile."""
        if pause is None:
            def pause(seconds: float, event: threading.Event | None = None) -> bool:
                if event is None:
                    time.sleep(seconds)
                    return False
                return event.wait(seconds)
        if self.realtime_priority > 0:
            try:
                os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(self.realtime_priority))  # this thread
                self.scheduling = f"SCHED_FIFO {self.realtime_priority}"
                self.get_logger().info(f"stepping thread: SCHED_FIFO priority {self.realtime_priority}")
            except (OSError, AttributeError) as exc:
                self.scheduling = f"normal (SCHED_FIFO {self.realtime_priority} refused: {exc})"
                self.get_logger().warning(f"realtime_priority {self.realtime_priority} refused ({exc}): "
                                               "stepping with normal scheduling")
        self._scheduling_said()
        if self.hold_cpu_dma_latency:
            self._hold_cpu_dma_latency()
        pinned = not self.stepping_cpus
        late = 0  # consecutive ticks with no time left before the next deadline ...
        late_since = 0.0  # ... since this wall time (the first of them)
        while not self._rt_stop.is_set() and keep_going():
            period = 1.0 / self.rate_hz  # live parameter: a new rate from the next deadline on
            if not self.started:  # _start sets the first deadline and wakes this loop at once (a plain 10-ms poll
                pause(0.1, self._started)  # made the first step up to a period late, the second an overrun)
                continue
            if not pinned:  # now: the process's threads were pinned (its cpus) before it began to spin
                pinned = True
                try:  # (on the executor's thread the process's CPUs are still said as they were: process_cpus)
                    self.stepping_cpu_affinity = pin_this_thread(self.stepping_cpus)
                    self.get_logger().info(f"stepping thread on CPU(s) {self.stepping_cpu_affinity}")
                except OSError as exc:
                    self.stepping_cpu_affinity = f"the process's (stepping_cpus refused: {exc})"
                    self.get_logger().warning(f"stepping_cpus {format_cpus(self.stepping_cpus)} refused ({exc})")
            if self._awaiting_commands:  # the loop closes before the clock starts (wait_for_commands)
                with self._lock:
                    if self._first_commands_in():
                        self._awaiting_commands = False
                        self._next_tick = time.monotonic()
                if self._awaiting_commands:
                    pause(0.005)
                    continue
            now = time.monotonic()
            delay = self._next_tick - now
            if delay > 0:
                while (left := self._next_tick - time.monotonic()) > 0 and not self._rt_stop.is_set() \
                        and keep_going():
                    pause(left)  # (a spin may end early: a callback ran)
                late = 0
            else:
                late += 1
                if late == 1:
                    late_since = now
                elif (now - late_since >= RT_GIVE_UP_S and self.realtime_priority > 0
                      and not self.scheduling.startswith("normal")):
                    # a real-time thread that never sleeps would starve its core: give the priority up after a
                    # second of wall time (not of steps: at a rate far beyond the step's cost that was seconds)
                    try:
                        os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
                        self.scheduling = (f"normal (SCHED_FIFO given up: late on every tick for "
                                           f"{now - late_since:.2f} s)")
                        self._scheduling_said()
                    except (OSError, AttributeError):
                        pass
                    self.warn.warn("rt_drop", f"{late} steps in a row over {now - late_since:.2f} s left no time "
                                              f"before the next deadline (at {self.rate_hz:g} Hz): stepping thread "
                                              "back to normal scheduling")
            with self._lock:
                if self._rt_stop.is_set():
                    break
                try:
                    self._tick(period)
                except Exception as exc:  # never a silent dead stepping thread: the node exits 1, says why
                    self._stepping_failed(exc)
                    return
            if self._deferred is not None:
                self._publish_after_answer(period, pause)

    def _scheduling_said(self) -> None:
        if self._on_scheduling is not None:
            self._on_scheduling(self.scheduling)

    def _publish_after_answer(self, period: float, pause: Callable[..., bool]) -> None:
        """The held samples of the step just taken: out once the controllers answered its state (the lock free
        meanwhile: the answer's callback takes it), or after ``answer_first_s`` (at most half a period)."""
        if pause(min(self.answer_first_s, 0.5 * period), self._answered):
            self.samples_after_answer += 1
        else:
            self.samples_after_wait += 1
        with self._lock:
            publish, self._deferred = self._deferred, None
            try:
                if publish is not None:
                    publish()
            except Exception as exc:  # noqa: BLE001 - as a failed tick
                self._stepping_failed(exc)

    def _stepping_failed(self, exc: Exception) -> None:
        """Never a silent dead stepping thread: the node exits 1 and says why."""
        self.diverged = self.diverged or f"stepping thread failed: {type(exc).__name__}: {exc}"
        self.exit_code = 1
        self.get_logger().error(self.diverged)
        self.done = True

    def _hold_cpu_dma_latency(self) -> None:
        """PM QoS: 0 us wake-up latency for as long as the file stays open (closed in :meth:`close`)."""
        try:
            self._dma_fd = os.open("/dev/cpu_dma_latency", os.O_WRONLY)
            os.write(self._dma_fd, (0).to_bytes(4, sys.byteorder, signed=True))
            self.cpu_latency = "held at 0 us"
        except OSError as exc:
            self._dma_fd = None
            self.cpu_latency = f"not held ({exc.strerror})"
            self.get_logger().warning(f"/dev/cpu_dma_latency: {exc.strerror}: idle cores keep their "
                                           "wake-up latency")

    def _tick(self, period: float) -> None:
        """Real-time step (the stepping thread, at its deadline ``self._next_tick``)."""
        self._poll_end()
        now = time.monotonic()
        if not self._stepping():  # finished or diverged: poll the end at the step rate, never spin
            self._next_tick = now + period
            return
        if now - self._next_tick > period:
            self.overruns += 1
            self.gate.simulator_stalled(self._next_tick, now)  # its own stall: not the controllers' silence
            self._next_tick = now
        self._next_tick += period
        decision = self.gate.realtime_commands(now)
        if decision.failsafe:
            self.warn.warn("failsafe", f"failsafe: {decision.reason}")
        self._step(decision)

    def _advance(self, planes_deg: np.ndarray, rps: float) -> None:
        self.gate.stepped()
        state = VehicleState.from_vector(self.sim.t, self.sim.x)
        u, v, w = state.v_body_native
        self._recent_speeds.append((state.t, math.sqrt(u * u + v * v + w * w)))
        # /clock goes to t_n+1 now, before the integration: the nodes on sim time (every controller) take it
        # while the ROM steps, not when the state of t_n+1 comes and they must answer it (recorders log the
        # state of t_n+1 at t_n+1 all the same)
        self.pub["/clock"].publish(cv.clock_message(self.sim.t_next))
        try:
            rec = self.sim.step(planes_deg, rps)
        except (NonFiniteStateError, ValueError) as exc:
            hint = substeps_hint(*zip(*self._recent_speeds), self.sim.substeps, "the mission's substeps:",
                                 self._expected_speed_mps)
            self.diverged = f"{exc}; {hint}" if hint else str(exc)
            self.exit_code = 1
            self.get_logger().error(f"simulation stopped: {self.diverged}")
            self._publish_status()
            self._end_after_error()
            return
        finished = self.t >= self.duration_s - 1e-9 or self._path_flown
        if self.nav is not None:  # the filter takes the samples of this step before its estimate of t_n+1 goes out
            self._publish_measurements(state, rec)
        if finished:
            self._publish_samples(state, rec)
            self._publish_sensors(self._publish_trigger(clock=False))
            self.finished = True
            self.get_logger().info(f"mission duration reached at t = {self.t:.3f} s")
            self._publish_status()
            self._end_when_recorded()
            return
        if self.sim.n == 1:  # starting -> running: said at once, not at the next status period
            self._publish_status()
        self._answered.clear()
        now = self._publish_trigger(clock=False)  # first: the controllers work on step n+1 while the samples go out
        if self.time_mode is TimeMode.REALTIME and self.answer_first_s > 0:
            self._publish_odometry(now)  # (a controller on state_source odometry answers it)
            self._deferred = lambda: (self._publish_samples(state, rec), self._publish_sensors(now, odometry=False))
            return
        self._publish_samples(state, rec)
        self._publish_sensors(now)

    def _publish_samples(self, state: VehicleState, rec) -> None:
        """The samples of the step just integrated from ``state`` (``[t_n, t_n+1)``): IMU, plane and propeller
        states, and the sensor suite's measurements (those the navigation filter takes went out before)."""
        t = rec.t
        f_flu = cv.specific_force_flu(state, rec.ev.xdot[6:9], self.g)
        self.pub["/bb2/imu"].publish(cv.fill_imu(self._imu_template, state, f_flu, frame_id=self.base_link))
        self.pub["/bb2/planes/state"].publish(cv.planes_message(t, np.radians(rec.act.planes_deg),
                                                                frame_id=self.base_link))
        self.pub["/bb2/propeller/state"].publish(cv.propeller_message(t, rec.act.rps * TWO_PI,
                                                                      frame_id=self.base_link))
        if self.suite is not None and self.nav is None:
            self._publish_measurements(state, rec)

    def _publish_measurements(self, state: VehicleState, rec) -> None:
        """The sensor samples of ``[t_n, t_n+1)`` (the step just integrated from ``state``)."""
        a, b = step_truths(state.t, state.as_vector(), rec.ev.xdot, self.sim.t, self.sim.x, self.terrain, self.g)
        samples = self.suite.step(a, b)
        if self.nav is not None:
            self.nav.update(samples)
        for s in samples:
            for name, msg in sample_messages(s, self.suite.config, frame_prefix=self.frame_prefix):
                self.pub[name].publish(msg)

    def _publish_state(self) -> None:
        self._publish_sensors(self._publish_trigger())

    def _publish_trigger(self, *, clock: bool = True) -> VehicleState:
        """(/clock and) the exact state of the current step (what the controllers answer); returns it."""
        state = VehicleState.from_vector(self.sim.t, self.sim.x)
        if self._csv:
            self._csv.writerow([repr(float(state.t))] + ["%.17g" % v for v in self.sim.x])
        if clock:
            self.pub["/clock"].publish(cv.clock_message(state.t))
        self._state_native_msg = cv.state_native_message(state)
        self._state_stamp = cv.stamp(state.t)
        if self.nav is not None:  # the estimate the controllers fly on, first: the truth is what the gate counts
            self._nav_msg = cv.state_native_message(self.nav.state(state.t))
            self.pub[NAV_STATE_TOPIC].publish(self._nav_msg)
        self.pub["/bb2/state_native"].publish(self._state_native_msg)
        self.gate.state_sent(time.monotonic())
        return state

    def _publish_scene(self) -> None:
        """The latched scene: the hull (base_link), the terrain and, in a calm sea, the plane z = 0 (map)."""
        sm = scene_markers
        markers = [sm.hull_marker(self.sim.model.surfaces, self.sim.t, frame_id=self.base_link)]
        if self.terrain is not None:
            markers.append(sm.terrain_marker(self.terrain, self.sim.t))
        if self.sea is None:
            markers.append(sm.sea_surface_marker(None, self.sim.x[0:2], self.sim.t, half_size_m=1000.0, cells=2))
        self.pub[SCENE_TOPIC].publish(sm.marker_array(markers))

    def _publish_sea_surface(self) -> None:
        """The free surface around the boat, every ``scene_sea_period_s`` of sim time (waves only)."""
        if self.sea_period_s <= 0 or self.sim.t < self._sea_next_t - 1e-9:
            return
        self._sea_next_t = (math.floor(self.sim.t / self.sea_period_s + 1e-9) + 1.0) * self.sea_period_s
        self.pub[SEA_SURFACE_TOPIC].publish(scene_markers.marker_array(
            [scene_markers.sea_surface_marker(self.sea.elevation, self.sim.x[0:2], self.sim.t)]))

    def _publish_odometry(self, state: VehicleState | None = None) -> None:
        """The odometry of the current step (``state``: its VehicleState, if made already)."""
        state = state or VehicleState.from_vector(self.sim.t, self.sim.x)
        self._odom_msg = cv.fill_odometry(self._odom_template, state, frame_id=self.odom_frame,
                                          child_frame_id=self.base_link)
        self.pub["/bb2/odom"].publish(self._odom_msg)

    def _publish_sensors(self, state: VehicleState | None = None, *, odometry: bool = True) -> None:
        """(Odometry,) depth and altitude of the current step (``state``: its VehicleState, if made already), and
        the free surface when due."""
        self._publish_sea_surface()
        state = state or VehicleState.from_vector(self.sim.t, self.sim.x)
        if odometry:
            self._publish_odometry(state)
        t = state.t
        self.pub["/bb2/depth"].publish(cv.depth_message(t, state.depth_m, frame_id=self.base_link))
        if self.terrain is not None:
            try:
                alt = float(self.terrain.clearance(state.p_native))
            except ValueError:  # off the terrain grid: no bottom known
                alt = math.inf
            self.pub["/bb2/altitude"].publish(cv.altitude_message(t, alt, frame_id=self.base_link))

    # ------------------------------------------------------------------------------------ status
    def status_values(self) -> dict[str, str]:
        now = time.monotonic()
        dt = now - self._wall_at_status
        if dt > 0.2:
            self._rate_measured = (self.sim.n - self._steps_at_status) / dt
            self._steps_at_status, self._wall_at_status = self.sim.n, now
        state = status_state(diverged=bool(self.diverged), finished=self.finished, steps=self.sim.n,
                             stalled=bool(self.stalled))
        realtime = self.time_mode is TimeMode.REALTIME
        vals = {"mode": self.time_mode.value, "state": state, "sim_time_s": f"{self.t:.6f}", "step": str(self.sim.n),
                "failsafe": str(self.gate.failsafe).lower(), "failsafe_reason": self.gate.failsafe_reason,
                "takeover_sim_time_s": "" if self._takeover_t is None else f"{self._takeover_t:.6f}",
                "rate_hz": f"{self.rate_hz:g}" if realtime else "as fast as the graph",
                "scheduling": self.scheduling if realtime else "executor (lockstep)",
                "callback_scheduling": self.callback_scheduling,
                "cpu_dma_latency": self.cpu_latency,
                "cpus": process_cpus(),
                "stepping_cpus": self.stepping_cpu_affinity if realtime else "",
                "step_rate_hz": f"{self._rate_measured:.2f}",
                "real_time_factor": f"{self._rate_measured * self.h:.3f}",
                "duration_s": f"{self.duration_s:g}", "mission_file": self.mission_file,
                "rom_substeps": str(self.sim.substeps)}
        if self.diverged or self.stalled:
            vals["error"] = self.diverged or self.stalled
        vals.update({k: str(v) for k, v in self.gate.counters.items()})
        vals["command_gap_max_s"] = f"{self.gate.command_gap_max_s:.3f}"
        vals["overruns"] = str(self.overruns)
        if realtime:  # the steps whose other samples went out on the controllers' answer / after answer_first_s
            vals["samples_after_answer"] = str(self.samples_after_answer)
            vals["samples_after_wait"] = str(self.samples_after_wait)
        vals.update(heap.PAUSES.status_values())
        vals.update(cpu_times())
        if self.ack.enabled:
            vals["recorder_ack"] = ("given up" if self.ack.given_up else "waiting" if self._held is not None
                                    else "ok")
            vals["recorder_lag_steps"] = str(self.ack.lag_steps(self._t_ns()))
            vals["recorder_waits"] = str(self.ack.waits)
            vals["recorder_ack_timeouts"] = str(self.ack.timeouts)
        return vals

    def _publish_status(self) -> None:
        from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

        from bb2_msgs_py.conversions import stamp

        vals = self.status_values()
        failsafe = self.gate.failsafe
        level = (DiagnosticStatus.ERROR if self.diverged or self.stalled else DiagnosticStatus.WARN if failsafe
                 else DiagnosticStatus.OK)
        msg_text = (f"diverged: {self.diverged}" if self.diverged else self.stalled if self.stalled
                    else f"FAILSAFE: {self.gate.failsafe_reason}" if failsafe
                    else f"{vals['state']}, {self.time_mode.value}")
        st = DiagnosticStatus(level=level, name="bb2/simulator", message=msg_text,
                              hardware_id=self.get_fully_qualified_name(),  # /boat1/simulator in a fleet
                              values=[KeyValue(key=k, value=v) for k, v in vals.items()])
        from std_msgs.msg import Header
        msg = DiagnosticArray(header=Header(stamp=stamp(self.t)), status=[st])
        self.pub["/bb2/status"].publish(msg)
        self.pub["/diagnostics"].publish(msg)  # the standard diagnostics topic too

    def close(self) -> None:
        if getattr(self, "_rt_thread", None) is not None:
            self._rt_stop.set()
            self._rt_thread.join(timeout=2.0)
        if getattr(self, "_dma_fd", None) is not None:
            os.close(self._dma_fd)  # the kernel drops the request
            self._dma_fd = None
        if self._csv_fh:
            self._csv_fh.close()


def load_sea_file(path: str, mission_env):
    """The environment of parameter ``sea_file``: a ``bb2_sea/1`` description, or ``sea:``/``current:`` blocks
    over the mission's (:class:`NodeConfigError` with one line for any fault)."""
    import json
    from pathlib import Path

    import yaml

    from bb2_sim.environment import (DESCRIPTION_FORMAT, Environment, current_from_mapping,
                                     environment_from_description, sea_from_mapping)
    from bb2_sim.yaml_files import load as load_yaml

    f = Path(path)
    try:
        text = f.read_text(encoding="utf-8")
        doc = json.loads(text) if f.suffix.lower() == ".json" else load_yaml(text)
    except (OSError, UnicodeDecodeError, ValueError, yaml.YAMLError) as exc:
        raise NodeConfigError(f"parameter 'sea_file': cannot read {path}: {exc}") from None
    try:
        if isinstance(doc, dict) and doc.get("format") == DESCRIPTION_FORMAT:
            return environment_from_description(doc)
        if not isinstance(doc, dict) or not ({"sea", "current"} & set(doc)) or set(doc) - {"sea", "current"}:
            raise ValueError("expected a mapping with sea: and/or current: blocks (only), or a "
                             f"{DESCRIPTION_FORMAT} description")
        sea = sea_from_mapping(doc["sea"], base_dir=f.parent) if "sea" in doc else mission_env.sea
        cur = current_from_mapping(doc["current"]) if "current" in doc else mission_env.current
        return Environment(sea, cur)
    except ValueError as exc:
        raise NodeConfigError(f"parameter 'sea_file' ({path}): {exc}") from None


def main(args: Sequence[str] | None = None) -> int:
    """Entry point (``ros2 run bb2_ros simulator``)."""
    return run_node("simulator", Simulator, args)


if __name__ == "__main__":
    sys.exit(main())
