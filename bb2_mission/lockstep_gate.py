"""The lockstep gate: what may reach the ROM from outside, and when it steps (no ROS).

The simulator node (and the replayer, for recorded commands) calls this plain code; the node only turns
messages into names, numbers and stamps, and the gate's answers into steps, warnings and status.

Command validation (:class:`CommandValidator`): a plane command must name the five plane joints (each once, any
order), a propeller command the one propeller joint; non-finite values, a frame other than the vehicle's, stale
or future stamps are rejected (never integrated); planes beyond the ROM's limit and propeller speeds outside its
rps limits are clamped.  Each verdict names its counter and carries the warning text.

Stepping (:class:`LockstepGate`), per step ``n`` at sim time ``t_n``:

* **lockstep**: step once a valid plane AND a valid propeller command stamped exactly ``t_n`` are in
  (:meth:`LockstepGate.answer`); an answer to an earlier step is *late* (counted, ignored), one stamped ahead is
  rejected.  At start-up the first complete answer is held ``startup_settle_s`` (wall) so late-matched readers
  miss nothing.  The :meth:`LockstepGate.watchdog` re-sends the state after ``lockstep_retry_s`` without an answer
  and, after ``lockstep_timeout_s`` (``startup_timeout_s`` for the first step), steps with the held commands and
  engages the failsafe;
* **real time**: every tick (:meth:`LockstepGate.realtime_commands`) steps with the last valid commands if both
  arrived within ``command_timeout_s`` (wall); otherwise the failsafe engages: planes neutral (0 deg) unless the
  plane command is still fresh, the propeller held at its last valid command (the stack's nominal command if
  none ever came).  The failsafe releases at the first step with valid commands again.

* **recorder back-pressure** (lockstep, :class:`RecorderAck`): with a window of ``w`` steps, the step from
  ``t_n`` waits until a reliable reader that must miss nothing (the recorder) has acknowledged the state of
  ``t_(n-w)``, so a stalled recorder slows the graph instead of losing messages; the controllers' answer is held
  meanwhile (no re-send, no lockstep timeout).  A reader silent for ``timeout_s`` is given up on (said once;
  the graph steps on, the recording will have a gap) until it acknowledges again.

All times are passed in (``wall`` = monotonic seconds, stamps in integer nanoseconds), so every rule is
unit-tested without a clock or DDS.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Sequence

import numpy as np

__all__ = ["TimeMode", "Counter", "CommandLimits", "clamp_planes_deg", "clamp_rps", "Verdict", "CommandValidator",
           "StepDecision", "WatchdogAction", "GateTimings", "LockstepGate", "RecorderAck"]


class TimeMode(StrEnum):
    """How the simulator steps."""

    LOCKSTEP = "lockstep"   #: wait for the controllers' answer to each state
    REALTIME = "realtime"   #: on the wall clock, with a stale-command failsafe


class Counter(StrEnum):
    """The gate's counters (their values are the status keys of ``/bb2/status``)."""

    REJECTED_NONFINITE = "rejected_nonfinite"
    REJECTED_NAMES = "rejected_names"
    REJECTED_FRAME = "rejected_frame"
    REJECTED_STALE = "rejected_stale"
    REJECTED_FUTURE = "rejected_future"
    CLAMPED = "clamped"
    LATE_COMMANDS = "late_commands"
    LOCKSTEP_TIMEOUTS = "lockstep_timeouts"
    LOCKSTEP_RESENDS = "lockstep_resends"
    FAILSAFE_STEPS = "failsafe_steps"
    FAILSAFE_STEPS_AFTER_TAKEOVER = "failsafe_steps_after_takeover"  #: ... once a step had gone on valid commands


def clamp_planes_deg(planes_deg: np.ndarray, limit_deg: float) -> np.ndarray:
    """Plane commands clamped to the ROM's plane limit (what reaches the actuators; the gate's and the
    library runner's one rule, so the graph and the runner integrate the same commands)."""
    return np.minimum(np.maximum(planes_deg, -limit_deg), limit_deg)   # np.clip's values, a third of its cost


def clamp_rps(rps: float, limits: tuple[float, float]) -> float:
    """A propeller command clamped to the ROM's rps limits."""
    lo, hi = limits
    return min(max(rps, lo), hi)


@dataclass(frozen=True)
class CommandLimits:
    """What a valid command looks like: joint names, frame, and the ROM's actuator limits."""

    plane_joints: tuple[str, ...]          #: the five plane joints, in ROM order delta_1..delta_5
    propeller_joint: str
    frame_id: str                          #: the vehicle's body frame (commands in any other frame are refused)
    plane_limit_deg: float                 #: |delta_i| beyond this is clamped, deg
    rps_limits: tuple[float, float]        #: propeller rev/s outside [lo, hi] is clamped

    @classmethod
    def from_actuators(cls, act: dict, *, plane_joints: Sequence[str], propeller_joint: str,
                       frame_id: str) -> "CommandLimits":
        """From the ROM's actuator parameters (``model.params.act``)."""
        lo, hi = act["rps_limits"]
        return cls(tuple(plane_joints), str(propeller_joint), str(frame_id), float(act["plane_limit_deg"]),
                   (float(lo), float(hi)))


@dataclass(frozen=True)
class Verdict:
    """The gate's answer to one command.

    ``value`` is what may be integrated (planes in deg in ROM order, or rev/s), None when rejected;
    ``counter`` the counter it adds to (None for a clean accept); ``key`` the warning's throttle key and
    ``message`` its text ('' for a clean accept).
    """

    value: np.ndarray | float | None
    counter: Counter | None = None
    key: str = ""
    message: str = ""
    clamped: bool = False

    @property
    def accepted(self) -> bool:
        return self.value is not None


class CommandValidator:
    """Stateless checks of plane and propeller commands (the simulator node's and the replayer's)."""

    def __init__(self, limits: CommandLimits, *, mode: TimeMode = TimeMode.LOCKSTEP, max_command_age_s: float = 1.0,
                 step_s: float = 0.05) -> None:
        self.limits, self.mode = limits, TimeMode(mode)
        self.max_age_ns = int(max_command_age_s * 1e9)
        self.step_ns = int(step_s * 1e9)

    # -- stamps and frames
    def _header(self, what: str, frame_id: str, stamp_ns: int | None, now_ns: int | None) -> Verdict | None:
        """A rejection for a wrong frame or stamp, else None (``stamp_ns`` None: no stamp check)."""
        if frame_id != self.limits.frame_id:
            return Verdict(None, Counter.REJECTED_FRAME, f"frame_{what}", f"rejected {what} command: frame_id "
                           f"{frame_id!r}, expected {self.limits.frame_id!r}")
        if stamp_ns is None or now_ns is None:
            return None
        st, now = int(stamp_ns), int(now_ns)
        ahead = Verdict(None, Counter.REJECTED_FUTURE, f"future_{what}", f"rejected {what} command stamped "
                        f"{st * 1e-9:.3f} s: ahead of the sim time {now * 1e-9:.3f} s")
        if self.mode is TimeMode.LOCKSTEP:
            if st < now:  # an answer to an earlier (re-sent / timed-out) step
                return Verdict(None, Counter.LATE_COMMANDS, "", "")
            return ahead if st > now else None
        if st < now - self.max_age_ns:
            return Verdict(None, Counter.REJECTED_STALE, f"stale_{what}", f"rejected stale {what} command stamped "
                           f"{st * 1e-9:.3f} s (sim time {now * 1e-9:.3f} s, max age {self.max_age_ns * 1e-9:g} s)")
        return ahead if st > now + self.step_ns else None

    # -- commands
    def planes(self, names: Sequence[str], positions_rad: Sequence[float], frame_id: str,
               stamp_ns: int | None = None, now_ns: int | None = None) -> Verdict:
        """A plane command: joint ``names`` with their ``positions_rad`` -> planes in deg, ROM order."""
        want = self.limits.plane_joints
        names = list(names)
        if len(names) != len(want) or len(set(names)) != len(names) or set(names) != set(want) \
                or len(positions_rad) != len(names):
            return Verdict(None, Counter.REJECTED_NAMES, "names_planes",
                           f"rejected plane command: expected the {len(want)} joints {list(want)}, got {names}")
        order = [names.index(j) for j in want]
        rad = np.asarray(positions_rad, dtype=float)[order]
        if not np.all(np.isfinite(rad)):
            return Verdict(None, Counter.REJECTED_NONFINITE, "nonfinite_planes",
                           f"rejected non-finite plane command {rad.tolist()} (never integrated)")
        bad = self._header("plane", frame_id, stamp_ns, now_ns)
        if bad is not None:
            return bad
        deg = np.degrees(rad)
        lim = self.limits.plane_limit_deg
        if np.any(np.abs(deg) > lim):
            return Verdict(clamp_planes_deg(deg, lim), Counter.CLAMPED, "clamp_planes",
                           f"plane command {np.round(deg, 3).tolist()} deg beyond +-{lim:g} deg: clamped", True)
        return Verdict(deg)

    def propeller(self, names: Sequence[str], velocities_rad_s: Sequence[float], frame_id: str,
                  stamp_ns: int | None = None, now_ns: int | None = None) -> Verdict:
        """A propeller command: the shaft speed (rad/s) of the propeller joint -> rev/s."""
        want = self.limits.propeller_joint
        if list(names) != [want] or len(velocities_rad_s) != 1:
            return Verdict(None, Counter.REJECTED_NAMES, "names_prop",
                           f"rejected propeller command: expected the joint [{want!r}], got {list(names)}")
        omega = float(velocities_rad_s[0])
        if not math.isfinite(omega):
            return Verdict(None, Counter.REJECTED_NONFINITE, "nonfinite_prop",
                           f"rejected non-finite propeller command {omega} (never integrated)")
        bad = self._header("propeller", frame_id, stamp_ns, now_ns)
        if bad is not None:
            return bad
        rps = omega / (2.0 * math.pi)
        lo, hi = self.limits.rps_limits
        if not lo <= rps <= hi:
            return Verdict(clamp_rps(rps, (lo, hi)), Counter.CLAMPED, "clamp_prop",
                           f"propeller command {rps:.4g} rps outside [{lo:g}, {hi:g}]: clamped", True)
        return Verdict(rps)


@dataclass(frozen=True)
class GateTimings:
    """Wall-clock rules of the gate, seconds."""

    lockstep_timeout_s: float = 1.0
    lockstep_retry_s: float = 0.1
    startup_timeout_s: float = 30.0
    startup_settle_s: float = 0.5
    command_timeout_s: float = 0.5


@dataclass(frozen=True)
class StepDecision:
    """Step now with these commands; ``failsafe`` engaged or released, and why."""

    planes_deg: np.ndarray
    rps: float
    failsafe: bool
    reason: str = ""


class WatchdogAction(StrEnum):
    NONE = "none"
    RESEND = "resend"   #: re-send the current state (controllers answer again from their caches)
    STEP = "step"       #: no answer in time: step with the held commands (failsafe)


@dataclass
class LockstepGate:
    """The stepping rules around one simulator (see the module docstring).  The caller holds any lock."""

    validator: CommandValidator
    timings: GateTimings = GateTimings()
    nominal_rps: float = 0.0                 #: propeller before any valid command, rev/s
    counters: dict[str, int] = field(default_factory=lambda: {c.value: 0 for c in Counter})
    planes_deg: np.ndarray | None = None     #: last valid planes (deg) and their arrival (wall s)
    rps: float | None = None
    planes_wall: float = -math.inf
    rps_wall: float = -math.inf
    failsafe: bool = False
    failsafe_reason: str = ""
    took_over: bool = False                  #: a step went on valid commands (the controllers took over)
    command_gap_max_s: float = 0.0           #: since the takeover: the longest wall gap between two valid plane
    #: (or two valid propeller) commands -- how close a real-time autopilot came to ``command_timeout_s``
    _planes_stall_credited: bool = False     # real time: the last valid planes / propeller command was given a stall
    _rps_stall_credited: bool = False        # back (simulator_stalled)
    _ans_planes: np.ndarray | None = None    # lockstep: answers to the step being awaited
    _ans_rps: float | None = None
    _first_answer_wall: float | None = None
    _sent_wall: float = 0.0                  # the current state was last (re-)sent
    _first_sent_wall: float = 0.0            # ... and first sent

    @property
    def mode(self) -> TimeMode:
        return self.validator.mode

    def count(self, counter: Counter | None) -> None:
        if counter is not None:
            self.counters[counter.value] += 1

    # -- commands in
    def on_planes(self, names: Sequence[str], positions_rad: Sequence[float], frame_id: str, stamp_ns: int,
                  now_ns: int, wall: float) -> Verdict:
        """A plane command arrived at ``wall``; the current step is at ``now_ns``."""
        v = self.validator.planes(names, positions_rad, frame_id, stamp_ns, now_ns)
        self.count(v.counter)
        if v.accepted:
            self._gap(wall - self.planes_wall)
            self.planes_deg, self.planes_wall, self._planes_stall_credited = v.value, wall, False
            if self.mode is TimeMode.LOCKSTEP:
                self._ans_planes = v.value
        return v

    def on_propeller(self, names: Sequence[str], velocities_rad_s: Sequence[float], frame_id: str, stamp_ns: int,
                     now_ns: int, wall: float) -> Verdict:
        v = self.validator.propeller(names, velocities_rad_s, frame_id, stamp_ns, now_ns)
        self.count(v.counter)
        if v.accepted:
            self._gap(wall - self.rps_wall)
            self.rps, self.rps_wall, self._rps_stall_credited = v.value, wall, False
            if self.mode is TimeMode.LOCKSTEP:
                self._ans_rps = v.value
        return v

    def _gap(self, gap_s: float) -> None:
        if self.took_over and gap_s > self.command_gap_max_s:  # (-inf before the first: the takeover comes after)
            self.command_gap_max_s = gap_s

    # -- lockstep
    def state_sent(self, wall: float) -> None:
        """The state of a new step went out at ``wall``."""
        self._sent_wall = self._first_sent_wall = wall

    def state_resent(self, wall: float) -> None:
        self._sent_wall = wall

    def answer(self, step: int, wall: float) -> StepDecision | None:
        """Lockstep: the decision to step once both answers of step ``step`` are in, else None."""
        if self._ans_planes is None or self._ans_rps is None:
            return None
        if step == 0 and self.timings.startup_settle_s > 0:  # let late endpoint matches settle (replays)
            if self._first_answer_wall is None:
                self._first_answer_wall = wall
            if wall - self._first_answer_wall < self.timings.startup_settle_s:
                self._ans_planes = self._ans_rps = None  # wait for the answers to the next re-send
                return None
        return self._decide(self._ans_planes, self._ans_rps, False, "")

    def watchdog(self, step: int, wall: float) -> tuple[WatchdogAction, StepDecision | None]:
        """Lockstep, between answers: re-send, or step on held commands after the timeout."""
        timeout = self.timeout_s(step)
        if wall - self._first_sent_wall > timeout:
            self.count(Counter.LOCKSTEP_TIMEOUTS)
            planes, rps, why = self.held_commands(wall, lockstep=True)
            return WatchdogAction.STEP, self._decide(planes, rps, True, f"lockstep timeout: {why}")
        if wall - self._sent_wall > self.timings.lockstep_retry_s:
            self.count(Counter.LOCKSTEP_RESENDS)
            self._sent_wall = wall
            return WatchdogAction.RESEND, None
        return WatchdogAction.NONE, None

    def timeout_s(self, step: int) -> float:
        """The wall time to wait for the answer of step ``step`` before stepping on held commands."""
        return self.timings.startup_timeout_s if step == 0 else self.timings.lockstep_timeout_s

    def held_commands(self, wall: float, *, lockstep: bool) -> tuple[np.ndarray, float, str]:
        """Commands for a step without fresh ones: this step's, last valid, else the safe default."""
        fresh_planes = self.planes_deg is not None and (
            lockstep or wall - self.planes_wall <= self.timings.command_timeout_s)
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
            rps, rw = self.nominal_rps, "nominal propeller"
        return planes, rps, f"{pw}, {rw}"

    # -- real time
    @property
    def has_commands(self) -> bool:
        """Valid plane and propeller commands have come (the controllers are up)."""
        return self.planes_deg is not None and self.rps is not None

    def state_age_s(self, wall: float) -> float:
        """Wall seconds since the current state first went out."""
        return wall - self._first_sent_wall

    def first_commands(self, wall: float) -> WatchdogAction:
        """Real time with ``wait_for_commands``, the first state out and the clock not started: STEP (start the
        clock) once valid commands have come or ``startup_timeout_s`` after the first state (then on the failsafe);
        RESEND it every ``lockstep_retry_s`` meanwhile, for controllers that match it late."""
        if self.has_commands or self.state_age_s(wall) >= self.timings.startup_timeout_s:
            return WatchdogAction.STEP
        if wall - self._sent_wall >= self.timings.lockstep_retry_s:
            self.state_resent(wall)
            return WatchdogAction.RESEND
        return WatchdogAction.NONE

    def realtime_commands(self, wall: float) -> StepDecision:
        """Real time, at a tick: the commands to step with, failsafe engaged when they are stale."""
        limit = self.timings.command_timeout_s
        planes_ok = self.planes_deg is not None and wall - self.planes_wall <= limit
        rps_ok = self.rps is not None and wall - self.rps_wall <= limit
        if planes_ok and rps_ok:
            return self._decide(self.planes_deg, self.rps, False, "")
        planes = self.planes_deg if planes_ok else np.zeros(5)
        rps = self.rps if self.rps is not None else self.nominal_rps
        missing = [w for w, ok in (("plane", planes_ok), ("propeller", rps_ok)) if not ok]
        why = (f"no valid {' and '.join(missing)} command for {limit:g} s: "
               + ("planes neutral" if not planes_ok else "planes held") + ", propeller "
               + ("held" if self.rps is not None else f"nominal {self.nominal_rps:.4g} rps"))
        return self._decide(planes, rps, True, why)

    def simulator_stalled(self, since: float, until: float) -> None:
        """Real time: the stepping thread itself missed its deadlines from ``since`` to ``until`` (wall s; the process
        stopped or starved): no state went out, so the controllers had nothing to answer.  A command still fresh at
        ``since`` gets the stall's time back, so the failsafe counts the controllers' silence, not the simulator's
        (once per command: a controller that fell silent for good is still caught one stall later)."""
        d = until - since
        if not d > 0:
            return
        limit = self.timings.command_timeout_s
        if self.planes_deg is not None and not self._planes_stall_credited and since - self.planes_wall <= limit:
            self.planes_wall += d
            self._planes_stall_credited = True
        if self.rps is not None and not self._rps_stall_credited and since - self.rps_wall <= limit:
            self.rps_wall += d
            self._rps_stall_credited = True

    # -- both
    def _decide(self, planes: np.ndarray, rps: float, failsafe: bool, why: str) -> StepDecision:
        self.failsafe, self.failsafe_reason = failsafe, why
        if failsafe:
            self.count(Counter.FAILSAFE_STEPS)
            if self.took_over:  # not the start-up wait for the controllers: they had answered, then fell silent
                self.count(Counter.FAILSAFE_STEPS_AFTER_TAKEOVER)
        else:
            self.took_over = True
        return StepDecision(planes, rps, failsafe, why)

    def stepped(self) -> None:
        """The step went ahead: the next step's answers start empty."""
        self._ans_planes = self._ans_rps = None


@dataclass
class RecorderAck:
    """Lockstep back-pressure from one reader that must miss nothing (the recorder's ``/bb2/recorder/ack``).

    The step from ``t_n`` may go when the reader has acknowledged a state stamped at or after
    ``t_n - window_steps * step_ns``; before its first acknowledgement it counts as having acknowledged the
    step before ``t0_ns`` (the first ``window_steps`` steps go at once).  ``window_steps`` 0: off."""

    window_steps: int
    step_ns: int
    t0_ns: int = 0
    timeout_s: float = 30.0        #: wall s without an acknowledgement that lets a step go, before giving up
    acked_ns: int | None = None    #: newest acknowledged stamp
    waiting_since: float | None = None  #: wall s the step now held started waiting
    given_up: bool = False         #: the reader was silent for timeout_s: steps go without it until it acks
    waits: int = 0                 #: steps that had to wait for the reader
    timeouts: int = 0              #: times it was given up on

    def __post_init__(self) -> None:
        if self.window_steps < 0 or self.step_ns <= 0 or not self.timeout_s > 0:
            raise ValueError(f"RecorderAck: window_steps >= 0, step_ns > 0 and timeout_s > 0 needed, got "
                             f"{self.window_steps}, {self.step_ns}, {self.timeout_s}")

    @property
    def enabled(self) -> bool:
        return self.window_steps > 0

    def on_ack(self, stamp_ns: int) -> None:
        """An acknowledgement of the state stamped ``stamp_ns`` (older ones than the newest are ignored)."""
        if self.acked_ns is None or stamp_ns > self.acked_ns:
            self.acked_ns = int(stamp_ns)
        self.given_up = False

    def lag_steps(self, now_ns: int) -> int:
        """Steps from the newest acknowledged state to the state at ``now_ns``."""
        acked = self.t0_ns - self.step_ns if self.acked_ns is None else self.acked_ns
        return (int(now_ns) - acked) // self.step_ns

    def may_step(self, now_ns: int, wall: float) -> bool:
        """May the step from the state at ``now_ns`` go now?  (A step that may not is counted once, and its
        wait starts at ``wall``.)"""
        if not self.enabled or self.given_up or self.lag_steps(now_ns) <= self.window_steps:
            self.waiting_since = None
            return True
        if self.waiting_since is None:
            self.waiting_since = wall
            self.waits += 1
        return False

    def expired(self, wall: float) -> bool:
        """The held step has waited ``timeout_s``: give the reader up (once; steps go without it)."""
        if self.waiting_since is None or wall - self.waiting_since < self.timeout_s:
            return False
        self.given_up = True
        self.timeouts += 1
        self.waiting_since = None
        return True
