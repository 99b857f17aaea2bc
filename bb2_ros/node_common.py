"""Shared rclpy plumbing of the BB2 nodes (simulator, planner, path_following, l1_autopilot, mixer).

A node here is a thin shell (an ``rclpy.node.Node`` subclass): declared parameters in, a library call,
messages out.  This module holds
what every shell needs and nothing numerical:

* :func:`run_node` -- ``rclpy.init(args=args)``, build the node, spin until SIGINT/SIGTERM, exit 0;
  a malformed params file, parameter or mission gives one clear line on stderr and exit status 2;
  :func:`run_nodes` the same for several nodes in one process (the container, :mod:`bb2_ros.container`).
* :func:`declare` -- a parameter with its description (``ParameterDescriptor``), so
  ``--ros-args --params-file F.yaml`` and ``-p name:=value`` apply as usual.
* :func:`check_remaps` -- a ``-r from:=to`` rule that names no topic of the node is reported (or is
  an error with ``strict_remaps: true``), so a typo in a remap never passes silently.
* :func:`mission_only` and :func:`build_piece` -- the mission file loaded, and the one piece a node needs
  built by the mission layer's own builders (:mod:`bb2_mission.components`, the runner's factory), so the
  graph equals the library runner, with the same clear errors.
* :class:`Throttle` -- wall-clock throttling of repeated warnings with a count of the suppressed ones.
* :func:`contract_publisher` -- a publisher of a contract topic (its type and QoS) that counts what it
  publishes; at exit :func:`run_nodes` writes the counts where the launcher asked (:data:`PUBLISHED_DIR_ENV`),
  so losses the recorder's sequence numbers cannot show (a writer silent towards the recorder from some point
  to the end) are still found (:func:`bb2_tools.bagfile.unrecorded_losses`).

Topic remapping is the standard ROS 2 one: ``--ros-args -r /bb2/odom:=/other/odom`` (optionally
``node_name:/bb2/odom:=...``).  Every node publishes and subscribes on the absolute contract names of
:mod:`bb2_msgs_py.contract`, which remapping rewrites.
"""
from __future__ import annotations

import faulthandler
import math
import os
import signal
import sys
import threading
import time
from enum import StrEnum
from typing import Any, Callable, Iterable, Sequence

from bb2_ros import heap
from bb2_ros.discovery_port import discovery_blocked

EXIT_OK = 0
EXIT_RUNTIME_ERROR = 1
EXIT_BAD_INPUT = 2


PUBLISHED_DIR_ENV = "BB2_PUBLISHED_DIR"
"""Environment variable: a directory where each node process writes, as it exits, how many messages it published
on each topic (``<process>-<pid>.json``: :func:`write_publication_counts`)."""


class NodeConfigError(ValueError):
    """A parameter, params file, remap or mission that a node cannot run with."""


# ----------------------------------------------------------------------------------------- parameters
LIVE_NOTE = " [live: takes effect when set at run time]"
READ_ONLY_NOTE = " [read-only: fixed at start-up (params file or -p); ros2 param set is refused]"


def declare(node, name: str, default: Any, description: str, *, on_set: Callable[[Any], None] | None = None,
            check: Callable[[Any], Any] | None = None, read_only: bool | None = None) -> Any:
    """Declare ``name`` with ``default`` and a description; return its (possibly overridden) value.

    A value of the wrong type in a params file raises :class:`NodeConfigError` naming the parameter, and so do a
    NaN/inf for a number and a ``-p name:=value`` of the command line (or the launcher) that is not of the
    parameter's type — rclpy would silently keep the params file's value or the default (issue 10).

    Parameters mean what they say (issue 13): a parameter with ``on_set`` is *live* — a set at run time
    (``ros2 param set``, the parameter services) is checked and then ``on_set(value)`` applies it; every other
    parameter is declared *read-only* (rclpy refuses the set, with the reason); the description says which.
    The type is static: a float parameter accepts an integer (turned into a float, in a params file, on the
    command line and at run time) and nothing else, any other parameter only its own type.  ``check(value)``
    (raising :class:`NodeConfigError` or ``ValueError``) refuses invalid values at start-up and at run time, with
    its message as the set's reason; numbers must be finite.
    """
    from rcl_interfaces.msg import ParameterDescriptor
    from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
    from rclpy.parameter import Parameter

    is_float = isinstance(default, float)
    live = on_set is not None
    read_only = not live if read_only is None else read_only
    overrides = getattr(node, "_parameter_overrides", None)
    if is_float and overrides is not None and name in overrides \
            and overrides[name].type_ == Parameter.Type.INTEGER:  # `rate_hz: 100` in a params file
        overrides[name] = Parameter(name, value=float(overrides[name].value))
    rules = _parameter_rules(node)
    try:
        p = node.declare_parameter(name, default, ParameterDescriptor(
            description=description + (READ_ONLY_NOTE if read_only else LIVE_NOTE), read_only=read_only))
    except (InvalidParameterTypeException, InvalidParameterValueException, TypeError) as exc:
        raise NodeConfigError(f"parameter {name!r}: {exc}") from None
    value = p.value
    raw = command_line_params().get(name)
    if raw is not None:
        _check_command_line_value(name, raw, default)
    if is_float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise NodeConfigError(f"parameter {name!r} must be a number, got {value!r}")
        value = float(value)
        if value != value or value in (float("inf"), float("-inf")):
            raise NodeConfigError(f"parameter {name!r} must be finite, got {value!r}")
    if check is not None:
        try:
            checked = check(value)
        except ValueError as exc:  # NodeConfigError is one
            raise NodeConfigError(str(exc) if name in str(exc) else f"parameter {name!r}: {exc}") from None
        value = value if checked is None else checked
    rules[name] = _ParameterRule(is_float, check, on_set)
    return value


class _ParameterRule:
    __slots__ = ("is_float", "check", "on_set")

    def __init__(self, is_float: bool, check, on_set):
        self.is_float, self.check, self.on_set = is_float, check, on_set


def _parameter_rules(node) -> dict[str, _ParameterRule]:
    """The node's rules, with its three set callbacks installed on first use: before a set, an integer for a
    float parameter becomes a float; on a set, values are checked (a refusal carries the reason); after it,
    the live parameter's ``on_set`` applies the value."""
    rules = getattr(node, "_bb2_parameter_rules", None)
    if rules is not None:
        return rules
    from rcl_interfaces.msg import SetParametersResult
    from rclpy.parameter import Parameter

    rules = {}
    node._bb2_parameter_rules = rules

    def pre_set(params):
        return [Parameter(p.name, value=float(p.value))
                if p.name in rules and rules[p.name].is_float and p.type_ == Parameter.Type.INTEGER else p
                for p in params]

    def on_set(params):
        for p in params:
            rule = rules.get(p.name)
            if rule is None:
                continue
            v = p.value
            if rule.is_float and not math.isfinite(v):
                return SetParametersResult(successful=False, reason=f"parameter {p.name!r} must be finite, got {v}")
            if rule.check is not None:
                try:
                    rule.check(v)
                except ValueError as exc:
                    return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def post_set(params):
        for p in params:
            rule = rules.get(p.name)
            if rule is not None and rule.on_set is not None:
                v = p.value
                if rule.check is not None:
                    checked = rule.check(v)
                    v = v if checked is None else checked
                rule.on_set(v)
                node.get_logger().info(f"parameter {p.name} set to {v!r} (live: in effect now)")

    node.add_pre_set_parameters_callback(pre_set)
    node.add_on_set_parameters_callback(on_set)
    node.add_post_set_parameters_callback(post_set)
    return rules


def ros_arguments(argv: Sequence[str]) -> list[str]:
    """The arguments inside the ``--ros-args`` scopes of ``argv`` (each scope ends at ``--`` or the end)."""
    out: list[str] = []
    in_ros = False
    for a in argv:
        if a == "--ros-args":
            in_ros = True
        elif a == "--":
            in_ros = False
        elif in_ros:
            out.append(a)
    return out


_node_argv: list[str] | None = None  # the argv run_node gave rclpy (for command_line_params)


def command_line_params(argv: Sequence[str] | None = None) -> dict[str, str]:
    """``name -> raw value`` of every ``-p``/``--param name:=value`` in the ROS arguments of ``argv`` (default
    the arguments :func:`run_node` started the node with, else ``sys.argv``; the last one of a name wins, as in
    rcl)."""
    out: dict[str, str] = {}
    args = ros_arguments((_node_argv if _node_argv is not None else sys.argv) if argv is None else argv)
    for i, a in enumerate(args):
        if a in ("-p", "--param") and i + 1 < len(args):
            name, sep, value = args[i + 1].partition(":=")
            if sep:
                out[name] = value
    return out


def _check_command_line_value(name: str, raw: str, default: Any) -> None:
    import yaml
    from bb2_sim.yaml_files import load as load_yaml

    try:  # read as rcl reads it (YAML 1.2: 1e3 is a double)
        v = load_yaml(raw) if raw != "" else ""
    except yaml.YAMLError:
        v = raw
    ok = True
    if isinstance(default, bool):
        ok = isinstance(v, bool)
    elif isinstance(default, float):
        ok = isinstance(v, (int, float)) and not isinstance(v, bool) and v == v and abs(v) != float("inf")
    elif isinstance(default, int):
        ok = isinstance(v, int) and not isinstance(v, bool)
    if not ok:
        kind = {bool: "true or false", float: "a finite number", int: "an integer"}[type(default)]
        raise NodeConfigError(f"parameter {name!r}: invalid value {raw!r} on the command line "
                              f"(-p {name}:={raw}); it must be {kind}")


def require_choice(name: str, value: str, choices: Iterable[str]) -> str:
    choices = tuple(choices)
    if value not in choices:
        raise NodeConfigError(f"parameter {name!r} must be one of {list(choices)}, got {value!r}")
    return value


def require_positive(name: str, value: float, *, allow_zero: bool = False) -> float:
    v = float(value)
    if not (v >= 0 if allow_zero else v > 0) or v != v or v == float("inf"):
        raise NodeConfigError(f"parameter {name!r} must be {'>= 0' if allow_zero else '> 0'} and finite, "
                              f"got {value!r}")
    return v


# ----------------------------------------------------------------------------------------- remaps
def remap_rules(argv: Sequence[str]) -> list[tuple[str | None, str, str]]:
    """``(node or None, from, to)`` of every ``-r``/``--remap`` rule in the ROS arguments of ``argv``."""
    rules: list[tuple[str | None, str, str]] = []
    it = iter(ros_arguments(argv))
    for a in it:
        if a in ("-r", "--remap"):
            rule = next(it, "")
            if ":=" not in rule:
                continue
            lhs, rhs = rule.split(":=", 1)
            node = None
            if ":" in lhs and not lhs.startswith("rosservice:") and not lhs.startswith("rostopic:"):
                node, lhs = lhs.split(":", 1)
            rules.append((node, lhs, rhs))
    return rules


def check_remaps(node, argv: Sequence[str], topics: Iterable[str], *, strict: bool) -> list[str]:
    """Report every remap rule for this node whose ``from`` is none of its ``topics``.

    Returns the messages; with ``strict`` raises :class:`NodeConfigError` instead.
    """
    from bb2_msgs_py.contract import node_topic_name

    known = set(topics) | {"/clock", "/diagnostics"}  # every node may use sim time and publishes diagnostics
    ns = node.get_namespace().rstrip("/")  # the names the node's topics resolve to in its namespace
    known |= {t.lstrip("/") for t in known} | {f"{ns}/{node_topic_name(t)}" for t in known
                                               if not node_topic_name(t).startswith("/")}
    bad = []
    for target, lhs, rhs in remap_rules(argv):
        if target is not None and target != node.get_name():
            continue
        if lhs in ("__node", "__name", "__ns", "__namespace") or lhs in known:
            continue
        bad.append(f"remap {lhs}:={rhs} matches no topic of node {node.get_name()!r} "
                   f"(its topics: {', '.join(sorted(t for t in known if t.startswith('/')))})")
    if bad and strict:
        raise NodeConfigError("; ".join(bad))
    for msg in bad:
        node.get_logger().warning(msg)
    return bad


# ----------------------------------------------------------------------------------------- throttling
class Throttle:
    """At most one log line per ``period_s`` of wall time per key; counts what it suppressed."""

    def __init__(self, logger, period_s: float = 2.0):
        self.logger, self.period_s = logger, float(period_s)
        self._last: dict[str, float] = {}
        self._suppressed: dict[str, int] = {}
        self.counts: dict[str, int] = {}

    def warn(self, key: str, message: str) -> None:
        self.counts[key] = self.counts.get(key, 0) + 1
        now = time.monotonic()
        if now - self._last.get(key, -1e18) >= self.period_s:
            extra = self._suppressed.pop(key, 0)
            self.logger.warning(message + (f" ({extra} similar suppressed)" if extra else ""))
            self._last[key] = now
        else:
            self._suppressed[key] = self._suppressed.get(key, 0) + 1


# ----------------------------------------------------------------------------------------- scheduling
CALLBACK_PRIORITY_REALTIME = 40
"""The controllers' ``callback_priority`` in real time, as ``bb2-launch`` and the launch files set it (the node's
default is 0, normal scheduling): below the simulator's stepping thread (its ``realtime_priority``, 50), above every
normally scheduled process (the recorder, a plotter, someone else's build).  Measured
(``benchmarks/graph_speed.py``): at 100 Hz, state -> plane command latency p99 3.5 -> 1.6 ms.  Not in lockstep: at
a real-time priority a lockstep graph's controllers took a core from the normally scheduled parts of a real-time
graph beside it (a HIL simulator's command reception, starved 1.7 s into its failsafe).  The simulator's own
``callback_priority`` (its command reception; real time only) is set to it too: normally scheduled, the reception
waited for a core past the command timeout beside two CPU hogs and two real-time busy loops (the HIL test: failed
2 of 2 runs; with it passed 3 of 3)."""
REALTIME_CONTROLLERS = ("path_following", "l1_autopilot", "mixer")
"""The nodes with a ``callback_priority``, which ``bb2-launch`` sets to CALLBACK_PRIORITY_REALTIME in real time."""


def _priority_check(name: str):
    def check(v):
        if isinstance(v, bool) or not 0 <= int(v) <= 99:
            raise NodeConfigError(f"{name} must be in 0..99, got {v}")
    return check


def declare_callback_priority(shell, *, applies: bool = True) -> int:
    """Declare ``callback_priority`` on a controller's shell (``shell.callback_priority``; :func:`run_nodes` applies
    the largest of a process's nodes' to the process, :func:`set_callback_priority`, and sets
    ``shell.callback_scheduling``, what its status says), and its ``cpus`` (:func:`declare_cpus`).  ``applies``
    False (the simulator in lockstep, where its ``lockstep_priority`` decides): declared, but 0 for the process,
    and ``callback_scheduling`` left as it is."""
    node = _node_of(shell)
    shell.callback_priority = int(declare(
        node, "callback_priority", 0,
        "SCHED_FIFO priority (1-99) of this node's process while it runs: the executor thread that runs its "
        "callbacks and the middleware's threads that deliver its messages, so an answer is not queued behind "
        "other processes; 0 = normal scheduling (bb2-launch and the launch files set 40 in real time); refused "
        "by the OS (no CAP_SYS_NICE / rtprio limit): a warning, normal scheduling.  Composed with the simulator "
        "in lockstep, the simulator's lockstep_priority decides",
        check=_priority_check("callback_priority")))
    declare_cpus(shell)
    if not applies:
        shell.callback_priority = 0
        return 0
    shell.callback_scheduling = "normal" if shell.callback_priority == 0 else "not yet set (the node is not spinning)"
    return shell.callback_priority


def parse_cpus(text: str, name: str = "cpus") -> frozenset[int]:
    """A CPU list as ``taskset -c`` takes it (``"1"``, ``"0,2"``, ``"0-3"``; ``""``: none given, the OS's choice),
    each CPU one this process may run on (:func:`os.sched_getaffinity`); else :class:`NodeConfigError` naming the
    parameter ``name``."""
    allowed = os.sched_getaffinity(0)
    cpus: set[int] = set()
    for part in (p.strip() for p in str(text).split(",")):
        if not part:
            continue
        lo, _, hi = part.partition("-")
        try:
            first, last = int(lo), int(hi if hi else lo)
        except ValueError:
            raise NodeConfigError(f"parameter {name!r}: {part!r} is not a CPU number or range (e.g. '1', '0,2', "
                                  "'0-3')") from None
        if first < 0 or last < first:
            raise NodeConfigError(f"parameter {name!r}: {part!r} is not a CPU range")
        cpus.update(range(first, last + 1))
    if not cpus <= allowed:
        raise NodeConfigError(f"parameter {name!r}: CPU(s) {sorted(cpus - allowed)} not available to this process "
                              f"(it may run on {format_cpus(allowed)})")
    if str(text).strip() and not cpus:
        raise NodeConfigError(f"parameter {name!r}: {text!r} names no CPU")
    return frozenset(cpus)


def format_cpus(cpus) -> str:
    """``"0,1"`` for the CPUs {0, 1}."""
    return ",".join(str(c) for c in sorted(cpus))


def declare_cpus(shell) -> frozenset[int]:
    """Declare ``cpus`` on a node of the control loop (``shell.cpus``; :func:`run_nodes` pins every thread of the
    process to the union of its nodes' before they spin, :func:`set_process_cpus`)."""
    shell.cpus = parse_cpus(declare(
        _node_of(shell), "cpus", "",
        "CPUs this node's process runs on (all its threads), as taskset -c takes them: '1', '0,2', '0-3'; '' = "
        "the OS's choice (default).  In real time, the controllers and the simulator's other threads on one CPU "
        "and the simulator's stepping thread on another (its stepping_cpus) keep a woken controller from waiting "
        "behind the stepping thread; a composed process takes the union of its nodes'"), "cpus")
    return shell.cpus


_main_thread_cpus_before_pinning: str | None = None
"""The process's CPUs from before :func:`pin_this_thread` gave the main thread CPUs of its own (the simulator stepping
on the executor's thread, ``stepping_cpus``), else None."""


def process_cpus() -> str:
    """The CPUs this process runs on, as its main thread (the executor's, under :func:`run_nodes`) may: ``"0,1"``
    (from any thread); once the main thread took CPUs of its own (:func:`pin_this_thread`), the process's as they
    were."""
    return _main_thread_cpus_before_pinning or format_cpus(os.sched_getaffinity(os.getpid()))


def pin_this_thread(cpus) -> str:
    """Pin the calling thread to ``cpus`` (a stepping thread's ``stepping_cpus``); returns its CPUs as the OS now
    says them.  OSError when the OS refuses.  On the main thread the process's CPUs are kept first, for
    :func:`process_cpus`."""
    global _main_thread_cpus_before_pinning
    if threading.current_thread() is threading.main_thread() and _main_thread_cpus_before_pinning is None:
        _main_thread_cpus_before_pinning = process_cpus()
    os.sched_setaffinity(0, cpus)
    return format_cpus(os.sched_getaffinity(0))


def set_process_cpus(cpus) -> None:
    """Pin every thread of this process to ``cpus`` (threads started later inherit their starter's CPUs)."""
    for tid in _thread_ids():
        try:
            os.sched_setaffinity(tid, cpus)
        except (ProcessLookupError, PermissionError):  # the thread ended; not ours to move
            continue


def declare_lockstep_priority(shell, *, lockstep: bool) -> int:
    """Declare the simulator's ``lockstep_priority``: in lockstep, the SCHED_FIFO priority of its process (executor
    and middleware threads; default 0, normal scheduling), which then also decides a composed process's (the
    simulator paces it: ``shell.process_priority``); in real time its stepping thread has ``realtime_priority`` and
    a composed process takes the controllers' ``callback_priority``."""
    node = _node_of(shell)
    value = int(declare(
        node, "lockstep_priority", 0,
        "lockstep: SCHED_FIFO priority (1-99) of the simulator's process (executor and middleware threads), and of "
        "a composed process holding it; 0 = normal scheduling.  At a real-time priority a lockstep graph runs "
        "faster (no waiting for a core behind other processes) but ahead of every reader outside the lockstep "
        "handshake (a plotter, ros2 topic echo) on a loaded machine: such a reader may then lose samples",
        check=_priority_check("lockstep_priority")))
    shell.process_priority = value if lockstep else None
    shell.callback_scheduling = "normal" if not lockstep or value == 0 else "not yet set (the node is not spinning)"
    return value


def _thread_ids() -> list[int]:
    """The native ids of this process's threads (/proc/self/task; without procfs: this thread only)."""
    try:
        return sorted(int(t) for t in os.listdir("/proc/self/task"))
    except OSError:
        return [threading.get_native_id()]


def _scheduled_threads() -> list[int]:
    """The threads a callback priority applies to: this one (the executor's: every callback runs on it) and the
    middleware's (Fast DDS names its threads ``dds.*``: receive, events, discovery).  Other threads (the BLAS
    pools of numpy and scipy, which may spin while they wait) stay as they are."""
    me = threading.get_native_id()
    out = [me]
    for tid in _thread_ids():
        if tid == me:
            continue
        try:
            with open(f"/proc/self/task/{tid}/comm", encoding="utf-8", errors="replace") as f:
                name = f.read().strip()
        except OSError:  # the thread ended
            continue
        if name.startswith("dds."):
            out.append(tid)
    return out


def set_callback_priority(priority: int) -> str:
    """Give the executor thread (the caller) and the middleware's threads of this process ``SCHED_FIFO``
    ``priority`` (0: nothing changes).  A thread already real-time (the simulator's stepping thread, composed with
    the controllers) keeps its own priority.  Returns what the process runs with, for the nodes' status and log:
    ``"SCHED_FIFO 40 (10 threads: the executor's and the middleware's)"``, ``"normal"`` or
    ``"normal (SCHED_FIFO 40 refused: ...)"``.  Threads the middleware starts later inherit the policy of the
    thread that starts them."""
    if priority <= 0:
        return "normal"
    rt = {os.SCHED_FIFO, os.SCHED_RR}
    reset = getattr(os, "SCHED_RESET_ON_FORK", 0)
    changed: list[int] = []
    for tid in _scheduled_threads():
        try:
            if os.sched_getscheduler(tid) & ~reset in rt:
                continue
            os.sched_setscheduler(tid, os.SCHED_FIFO, os.sched_param(priority))
            changed.append(tid)
        except ProcessLookupError:  # the thread ended meanwhile
            continue
        except (OSError, AttributeError) as exc:
            why = getattr(exc, "strerror", None) or str(exc)
            for done in changed:  # all or nothing (the rule that refused this thread refuses them all)
                try:
                    os.sched_setscheduler(done, os.SCHED_OTHER, os.sched_param(0))
                except OSError:
                    pass
            return f"normal (SCHED_FIFO {priority} refused: {why})"
    return f"SCHED_FIFO {priority} ({len(changed)} threads: the executor's and the middleware's)"


# ----------------------------------------------------------------------------------------- run
def _error(name: str, message: str) -> None:
    print(f"{name}: error: {message}", file=sys.stderr, flush=True)


def make_executor(context=None):
    """rclpy's EventsExecutor (C++ event queue, several times less overhead per callback than the
    SingleThreadedExecutor; rclpy.experimental in Jazzy) unless ``BB2_EXECUTOR=single``; on ``context``
    (default: rclpy's global one)."""
    from rclpy.executors import SingleThreadedExecutor

    if os.environ.get("BB2_EXECUTOR", "events") != "single":
        try:
            from rclpy.experimental import EventsExecutor

            return EventsExecutor(context=context)
        except ImportError:  # pragma: no cover - older rclpy
            pass
    return SingleThreadedExecutor(context=context)


def _profiler():
    """A running cProfile profiler when ``BB2_PROFILE_DIR`` is set (a developer's switch: the spin
    loop's profile (thread CPU time) is written to ``$BB2_PROFILE_DIR/<node>-<pid>.prof`` at exit; read it
    with pstats)."""
    if not os.environ.get("BB2_PROFILE_DIR"):
        return None
    import cProfile

    os.makedirs(os.environ["BB2_PROFILE_DIR"], exist_ok=True)
    # CPU time (not wall): what a node costs its core, blocking waits excluded
    prof = cProfile.Profile(time.thread_time)
    prof.enable()
    return prof


TEARDOWN_S = 5.0  # a node process still alive this long after it was told to stop exits by itself


class ExitWatchdog:
    """Bounds the time from a stop request to the end of a node process.  Once armed (the stop signal, or the end
    of the spin loop), a daemon thread waits ``TEARDOWN_S``; if the process is still there, the teardown is stuck
    (in the middleware: rclpy's node and context teardown, or the interpreter's exit; seen about once in a few
    hundred runs on a loaded machine): it writes every thread's stack and one line to stderr (the node's log) and
    ends the process with the exit code it was armed with.  A node's work is over once it is told to stop, so
    nothing is lost.  Should that thread never get the interpreter (a teardown stuck holding it), faulthandler's
    own thread does the same ``BACKSTOP_S`` later without it, with exit code 1 -- still before the launcher's
    SIGTERM (its SIGINT grace is 10 s)."""

    BACKSTOP_S = 3.0

    def __init__(self, process: str, timeout_s: float = TEARDOWN_S):
        self.process, self.timeout_s = process, timeout_s
        self.code = EXIT_OK
        self._armed = threading.Event()
        self._lock = threading.Lock()

    def arm(self, code: int) -> None:
        with self._lock:
            self.code = max(self.code, int(code))
            if self._armed.is_set():
                return
            self._armed.set()
        faulthandler.dump_traceback_later(self.timeout_s + self.BACKSTOP_S, exit=True)
        threading.Thread(target=self._run, name="bb2-exit-watchdog", daemon=True).start()

    def _run(self) -> None:
        time.sleep(self.timeout_s)
        faulthandler.dump_traceback(all_threads=True)
        print(f"{self.process}: still running {self.timeout_s:g} s after it was told to stop (stacks above): "
              f"exiting with code {self.code}", file=sys.stderr, flush=True)
        os._exit(self.code)


def stop_signals(stop: threading.Event, on_stop: Callable[[], None] | None = None) -> dict[int, Any]:
    """Install the stop handlers of a node process: SIGINT and SIGTERM set ``stop`` (and call ``on_stop`` once).
    Once told to stop, a further SIGTERM (what the launcher sends a node that did not stop on SIGINT within its
    grace) first writes the Python stack of every thread to stderr, the node's log, so a node that hangs at
    shutdown shows where.  Returns the previous handlers, for :func:`restore_signals`."""
    def on_signal(*_) -> None:
        if not stop.is_set():
            stop.set()
            faulthandler.register(signal.SIGTERM, all_threads=True, chain=True)
            if on_stop is not None:
                on_stop()

    return {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}


def restore_signals(previous: dict[int, Any], stop: threading.Event) -> None:
    """Undo :func:`stop_signals`.  A process told to stop ignores further stop signals until it has exited: Ctrl-C
    reaches the whole process group of `ros2 launch`, which then forwards its own SIGINT, and a KeyboardInterrupt
    raised while the interpreter tears the middleware down aborts the process (exit -6)."""
    faulthandler.unregister(signal.SIGTERM)
    for s, h in previous.items():
        signal.signal(s, signal.SIG_IGN if stop.is_set() else h)


def _node_of(shell):
    from rclpy.node import Node

    return shell if isinstance(shell, Node) else shell.node


_node_options: dict[str, Any] = {}  # what the node being built passes to rclpy's Node (see node_options)


def node_options() -> dict[str, Any]:
    """Keyword arguments for ``rclpy.node.Node.__init__`` of the node being built: none in a process of its own
    (the node reads the process's ROS arguments); in a container (:func:`run_nodes` with ``composed``), its own
    ROS arguments as ``cli_args`` and not the process's (``use_global_arguments=False``), so each composed node
    gets exactly the parameters and remaps it would get alone."""
    return dict(_node_options)


_counting_publisher_class = None


def counting_publisher_class():
    """``rclpy.publisher.Publisher`` that counts the messages it publishes (``published``; raw bytes too): DDS
    numbers a writer's samples 1, 2, 3, ..., so the count is the last publication sequence number it sent."""
    global _counting_publisher_class
    if _counting_publisher_class is None:
        from rclpy.publisher import Publisher

        class CountingPublisher(Publisher):
            published = 0

            def publish(self, msg) -> None:
                super().publish(msg)
                self.published += 1

        _counting_publisher_class = CountingPublisher
    return _counting_publisher_class


def contract_publisher(node, name: str, msg_type=None):
    """A publisher of contract topic ``name`` on ``node``: the contract's type (or ``msg_type``) and QoS,
    counting what it publishes (:func:`counting_publisher_class`)."""
    from bb2_msgs_py.contract import message_class, node_topic_name, qos_profile, topic

    return node.create_publisher(msg_type if msg_type is not None else message_class(topic(name).type),
                                 node_topic_name(name), qos_profile(name), publisher_class=counting_publisher_class())


def publication_counts(nodes) -> dict[str, int]:
    """Messages published per resolved topic name by the counting publishers of ``nodes`` (summed)."""
    cls = counting_publisher_class()
    out: dict[str, int] = {}
    for node in nodes:
        for pub in node.publishers:
            if isinstance(pub, cls):
                out[pub.topic_name] = out.get(pub.topic_name, 0) + int(pub.published)
    return dict(sorted(out.items()))


def write_publication_counts(process: str, nodes) -> None:
    """If :data:`PUBLISHED_DIR_ENV` names a directory, write ``{"process", "pid", "published": {topic: n}}``
    there as ``<process>-<pid>.json`` (atomically: a partial file is never read); best effort, never raises."""
    import json

    folder = os.environ.get(PUBLISHED_DIR_ENV)
    if not folder:
        return
    try:
        os.makedirs(folder, exist_ok=True)
        path = os.path.join(folder, f"{process}-{os.getpid()}.json")
        with open(path + ".tmp", "w", encoding="utf-8") as f:
            json.dump({"process": process, "pid": os.getpid(), "published": publication_counts(nodes)}, f)
        os.replace(path + ".tmp", path)
    except Exception as exc:  # pragma: no cover - a count we cannot write is a check we cannot make
        print(f"[{process}] cannot write its publication counts into {folder}: {exc}", file=sys.stderr)


DELIVERY_AT_EXIT_S = 1.0
"""Wall seconds a node process waits, once told to stop, for its reliable readers to acknowledge what its writers
published (:func:`deliver_pending`) before it destroys them."""


def deliver_pending(nodes, timeout_s: float | None = None) -> list[str]:
    """Wait at most ``timeout_s`` in all for every reliable writer of ``nodes`` to have each of its samples
    acknowledged by its matched readers: a writer destroyed with samples still on their way takes them with it (a
    node's last status, published by its timer just before the stop, was missing from a bag).  Returns the topics
    whose samples were not all acknowledged in time (a reader gone or frozen: nothing more can be done).
    ``timeout_s`` None: :data:`DELIVERY_AT_EXIT_S`."""
    from rclpy.duration import Duration

    deadline = time.monotonic() + (DELIVERY_AT_EXIT_S if timeout_s is None else timeout_s)
    late = []
    for node in nodes:
        for pub in list(getattr(node, "publishers", ())):
            try:
                if pub.get_subscription_count() == 0:
                    continue
                left = max(deadline - time.monotonic(), 0.0)
                if not pub.wait_for_all_acked(Duration(nanoseconds=int(left * 1e9))):
                    late.append(pub.topic_name)
            except Exception:  # noqa: BLE001 - a writer already gone or a middleware that cannot tell
                continue
    return late


def run_node(name: str, factory: Callable[[list[str]], Any], args: Sequence[str] | None = None) -> int:
    """Init rclpy with ``args`` (``sys.argv`` when None), build ``factory(argv)``, spin until SIGINT/SIGTERM.

    ``factory`` returns an ``rclpy.node.Node`` (or an object with ``.node``), optionally with ``close()``,
    ``done`` (a bool: stop spinning, e.g. the simulator's ``exit_at_end``) and ``exit_code`` (default 0).
    Exit status: 0 clean stop, 2 bad params file / parameter / mission, 1 runtime error (e.g. the
    simulation diverged).
    """
    argv = list(sys.argv if args is None else args)
    return run_nodes(name, [(name, factory, argv)], argv)


def run_nodes(process: str, nodes: Sequence[tuple[str, Callable[[list[str]], Any], list[str]]],
              init_args: Sequence[str], *, composed: bool = False) -> int:
    """:func:`run_node` for several nodes in one process and one executor: ``nodes`` are ``(name, factory,
    argv)``, built in order; rclpy is initialised with ``init_args``.  ``composed``: each node reads the ROS
    arguments of its own ``argv`` only (:func:`node_options`).  Spins until SIGINT/SIGTERM or until any node is
    ``done``; the exit status is the worst of the nodes' (2 > 1 > 0).  A node that cannot be built stops the
    process before it spins (exit 2, one line naming the node), and a domain whose discovery port another socket
    holds unshared (:func:`bb2_ros.discovery_port.discovery_blocked`: no node there would hear another) stops it
    before any node is built (no node says it is up there)."""
    from bb2_msgs_py.ros_env import ros_environment_or_error

    if (bad := ros_environment_or_error(process)) is not None:  # called directly from the venv: find ROS itself
        return bad
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    global _node_argv, _node_options
    try:
        rclpy.init(args=list(init_args), signal_handler_options=SignalHandlerOptions.NO)
    except Exception as exc:  # rcl's own message names the bad params file / argument
        _error(process, f"cannot start ROS (bad --ros-args or params file?): {exc}")
        return EXIT_BAD_INPUT
    watchdog = ExitWatchdog(process)
    stop = threading.Event()
    previous = stop_signals(stop, on_stop=lambda: watchdog.arm(EXIT_OK))
    shells: list[Any] = []
    code = EXIT_OK
    try:
        # before any node exists: deaf, it would wait for what never comes, and should not say it is up first
        if deaf := discovery_blocked(os.environ, rclpy.get_default_context().get_domain_id()):
            _error(process, deaf)
            return EXIT_BAD_INPUT
        for name, factory, argv in nodes:
            _node_argv = list(argv)
            _node_options = ({"cli_args": ["--ros-args", *ros_arguments(argv)], "use_global_arguments": False}
                             if composed else {})
            try:
                shells.append(factory(list(argv)))
            except NodeConfigError as exc:
                _error(name, str(exc))
                return EXIT_BAD_INPUT
            finally:
                _node_options = {}
        executor = make_executor()
        for shell in shells:
            executor.add_node(_node_of(shell))
        if (shared := share_sim_clock([_node_of(sh) for sh in shells])) > 1:
            _node_of(shells[0]).get_logger().info(f"{shared} nodes of this process on sim time take /clock through "
                                                  "one subscription")
        _apply_callback_priority(shells)
        cpus = frozenset().union(*(getattr(sh, "cpus", frozenset()) for sh in shells))
        if cpus:  # before the simulator's stepping thread takes its own (stepping_cpus) once the clock may start
            set_process_cpus(cpus)
        heap.settle()  # the start-up heap out of the collector's walk: no 30-45 ms pause while running
        profiler = _profiler()

        def keep_going() -> bool:
            return not stop.is_set() and rclpy.ok() and not any(getattr(sh, "done", False) for sh in shells)
        # a real-time simulator steps on this thread, spinning the executor between its deadlines
        driver = next((sh for sh in shells if getattr(sh, "drives_executor", False)), None)
        try:
            if driver is not None:
                driver.drive(executor, keep_going, lambda sched: _callbacks_on_stepping_thread(shells, sched))
            while keep_going():
                executor.spin_once(timeout_sec=0.1)
        finally:
            if profiler is not None:
                profiler.disable()
                profiler.dump_stats(os.path.join(os.environ["BB2_PROFILE_DIR"], f"{process}-{os.getpid()}.prof"))
        code = max((int(getattr(sh, "exit_code", EXIT_OK)) for sh in shells), default=EXIT_OK)
    except Exception as exc:
        _error(process, f"{type(exc).__name__}: {exc}")
        code = EXIT_RUNTIME_ERROR
    finally:
        watchdog.arm(code)  # from here on the process has TEARDOWN_S to be gone
        write_publication_counts(process, [_node_of(sh) for sh in shells])
        deliver_pending([_node_of(sh) for sh in shells])
        for shell in shells:
            try:
                if hasattr(shell, "close"):
                    shell.close()
                _node_of(shell).destroy_node()
            except Exception:  # pragma: no cover - best effort at shutdown
                pass
        if rclpy.ok():
            rclpy.shutdown()
        restore_signals(previous, stop)
    return code


USE_SIM_TIME_FIXED = ("use_sim_time is fixed while this process runs: its nodes on sim time share one /clock "
                      "subscription (composed); restart the process with the value you want")


def _refuse_use_sim_time_change(params) -> Any:
    from rcl_interfaces.msg import SetParametersResult

    for p in params:
        if p.name == "use_sim_time" and p.value is not True:
            return SetParametersResult(successful=False, reason=USE_SIM_TIME_FIXED)
    return SetParametersResult(successful=True)


def share_sim_clock(nodes: Sequence[Any]) -> int:
    """Let the nodes of one process that run on sim time take their clock topic through one subscription: of the
    nodes whose ``/clock`` resolves to the same topic (their remaps), the first one's time source (rclpy's
    ``TimeSource``) drives every other one's clock (``attach_clock``), and the others' own subscriptions are
    removed -- one delivery of each clock message per process instead of one per node, the same time in every
    node's clock. ``use_sim_time`` is then fixed for the process's life on the nodes sharing (a change is refused
    with the reason: a follower's clock would otherwise go on or off with the first node's). Returns the number of
    nodes sharing (0: no two on sim time with the same clock topic, or an rclpy without the time source this relies
    on, which then keeps one subscription per node)."""
    groups: dict[str, list[Any]] = {}
    for n in nodes:
        if n.get_parameter("use_sim_time").value is True:
            groups.setdefault(n.resolve_topic_name("/clock"), []).append(n)
    sharing = [g for g in groups.values() if len(g) > 1]
    sources = {id(n): getattr(n, "_time_source", None) for g in sharing for n in g}
    if not all(hasattr(ts, "attach_clock") and hasattr(ts, "detach_node") for ts in sources.values()):
        return 0
    for lead, *followers in sharing:
        for node in followers:
            sources[id(node)].detach_node()   # its clock subscription goes; its clock stays on ROS time
            sources[id(lead)].attach_clock(node.get_clock())
        for node in (lead, *followers):
            node.add_on_set_parameters_callback(_refuse_use_sim_time_change)  # runs before the time source's own
    return sum(len(g) for g in sharing)


def _apply_callback_priority(shells: Sequence[Any]) -> None:
    """The process's SCHED_FIFO priority, applied (:func:`set_callback_priority`) from the thread that will spin
    the executor: the simulator's in lockstep (``process_priority``: it paces the process), else the largest
    ``callback_priority`` of the process's nodes.  Each node that asked says the outcome in its log and status."""
    paced = [sh.process_priority for sh in shells if getattr(sh, "process_priority", None) is not None]
    asked = [sh for sh in shells if getattr(sh, "callback_priority", 0) > 0 or getattr(sh, "process_priority", 0)]
    if not asked:
        return
    if paced:
        priority = max(paced)
        outcome = set_callback_priority(priority) if priority > 0 else (
            f"normal (composed with the simulator in lockstep: its lockstep_priority {priority} decides)")
    else:
        priority = max(sh.callback_priority for sh in asked)
        outcome = set_callback_priority(priority)
    for sh in asked:
        sh.callback_scheduling = outcome
        logger = _node_of(sh).get_logger()
        if outcome.startswith("SCHED_FIFO"):
            logger.info(f"callbacks at {outcome}")
        elif "refused" in outcome:
            logger.warning(f"callbacks with {outcome}")
        else:
            logger.info(f"callbacks with {outcome}")


def _callbacks_on_stepping_thread(shells: Sequence[Any], scheduling: str) -> None:
    """A real-time simulator steps on the process's executor thread (``realtime_loop`` executor): every node's
    callbacks run with the stepping thread's ``scheduling``; their ``callback_priority`` still holds for the
    middleware's threads.  Each node's status says both."""
    for sh in shells:
        middleware = getattr(sh, "_middleware_scheduling", None) or getattr(sh, "callback_scheduling", "normal")
        sh._middleware_scheduling = middleware
        sh.callback_scheduling = (f"{scheduling} (on the simulator's stepping thread: realtime_loop executor; "
                                  f"the middleware's threads: {middleware})")


# ----------------------------------------------------------------------------------------- status
def cpu_times() -> dict[str, str]:
    """What every node's status says of its process's CPU use so far (s, as the kernel counts it): ``process_id``,
    ``cpu_process_s`` (all its threads: the middleware's receive and event threads too) and ``cpu_main_thread_s``
    (its main thread, which spins the executor under :func:`run_nodes`: every callback, and a real-time simulator's
    steps in its default loop).  Two statuses of a node give its CPU per step (``benchmarks/graph_speed.py``);
    nodes composed into one process say the same process's figures."""
    try:  # (read before the process's: never above it)
        main = time.clock_gettime(time.pthread_getcpuclockid(threading.main_thread().ident))
    except (AttributeError, OSError, TypeError):  # no per-thread CPU clock on this platform: left out
        main = None
    out = {"process_id": str(os.getpid()), "cpu_process_s": f"{time.process_time():.6f}"}
    if main is not None:
        out["cpu_main_thread_s"] = f"{main:.6f}"
    return out


class NodeStatus:
    """Publishes ``/bb2/status`` (``diagnostic_msgs/DiagnosticArray``) for a node every ``period_s`` wall
    seconds.  The header stamp is the node's clock (the simulation time with ``use_sim_time``).

    ``period_s`` None: no timer; the caller publishes (the recorder, which waits on a wait set of its own, not on an
    executor that would run a timer)."""

    def __init__(self, node, name: str, period_s: float | None, values: Callable[[], dict[str, str]]):
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.clock import Clock, ClockType

        self.node, self.name, self.values = node, name, values
        self.level, self.message = 0, "running"
        self.pub = contract_publisher(node, "/bb2/status", DiagnosticArray)
        # and on the standard /diagnostics (rqt_robot_monitor, diagnostic_aggregator)
        self.pub_diagnostics = contract_publisher(node, "/diagnostics", DiagnosticArray)
        self.timer = None if period_s is None else \
            node.create_timer(period_s, self.publish, clock=Clock(clock_type=ClockType.STEADY_TIME))

    def publish(self, now_ns: int | None = None) -> None:
        """Publish one status now; ``now_ns``: its stamp and ``node_time_s`` when the node keeps its time itself
        (the recorder's simulation time from /clock), else the node's clock."""
        from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
        from rclpy.time import Time
        from std_msgs.msg import Header

        now = self.node.get_clock().now() if now_ns is None else Time(nanoseconds=int(now_ns))
        vals = {"node_time_s": f"{now.nanoseconds * 1e-9:.6f}",
                "use_sim_time": str(self.node.get_parameter("use_sim_time").value).lower()}
        vals.update(self.values())
        vals.update(heap.PAUSES.status_values())
        vals["cpus"] = process_cpus()
        vals.update(cpu_times())
        st = DiagnosticStatus(level=bytes([self.level]), name=self.name, message=self.message,
                              hardware_id=self.node.get_fully_qualified_name(),
                              values=[KeyValue(key=k, value=str(v)) for k, v in vals.items()])
        msg = DiagnosticArray(header=Header(stamp=now.to_msg()), status=[st])
        self.pub.publish(msg)
        self.pub_diagnostics.publish(msg)


REPLAY_MIN_INTERVAL_S = 0.05
"""Wall seconds within which a node answers a copy of a state it answered only once: copies that close together are
a backlog (a node that was busy or starting finds the state re-sent many times in its reader's queue and takes the
copies at once), not the lockstep simulator's re-sends, which come ``lockstep_retry_s`` (0.1 s) apart.  Answering
every copy of such a backlog floods every reader: 55 copies of the state at t = 0 taken at once by a path follower
that had just started made 330 messages in 20 ms down the chain, more than a busy recorder's UDP receive buffer held,
and its reliable readers waited for the writers' repair, which that run's end (1 s later) did not.  A re-send that
comes sooner than this after the last answer is not lost: the next re-send is answered."""


class StampedCache:
    """The messages a node published for an input stamp, to replay them when the same input comes again
    (the lockstep simulator re-sends an unanswered state: every stage answers it again, identically,
    without stepping its controller twice).  A copy taken within :data:`REPLAY_MIN_INTERVAL_S` of the last time the
    answer went out is a backlog copy: handled, not answered again.

    Counts (the nodes' statuses): ``replayed`` answers published again, ``copies_skipped`` backlog copies not
    answered again, ``stale_ignored`` inputs older than the cached one."""

    def __init__(self, min_interval_s: float = REPLAY_MIN_INTERVAL_S, clock: Callable[[], float] = time.monotonic):
        self.stamp_ns: int | None = None
        self.messages: list[tuple[Any, Any]] = []
        self.min_interval_s = float(min_interval_s)
        self._clock = clock
        self._sent_at = -math.inf  # when the cached answer last went out (clock s)
        self.replayed = self.copies_skipped = self.stale_ignored = 0

    def replay(self, stamp_ns: int) -> bool:
        """Re-publish the cached answer if ``stamp_ns`` is the cached stamp (unless it went out less than
        ``min_interval_s`` ago); True if the input is handled (replayed, skipped as a backlog copy, or older than the
        cache and ignored)."""
        if self.stamp_ns is None or stamp_ns > self.stamp_ns:
            return False
        if stamp_ns < self.stamp_ns:
            self.stale_ignored += 1
            return True
        now = self._clock()
        if now - self._sent_at < self.min_interval_s:
            self.copies_skipped += 1
            return True
        self._sent_at = now
        self.replayed += 1
        for pub, msg in self.messages:
            pub.publish(msg)
        return True

    def store(self, stamp_ns: int, messages: list[tuple[Any, Any]],
              replay_also: list[tuple[Any, Any]] = ()) -> None:
        """Publish ``messages`` and keep them (with ``replay_also``, already published) for replays."""
        self.stamp_ns, self.messages = stamp_ns, list(replay_also) + list(messages)
        for pub, msg in messages:
            pub.publish(msg)
        self._sent_at = self._clock()

    def counts(self) -> dict[str, int]:
        """What became of the copies and stale inputs (status values)."""
        return {"replayed": self.replayed, "copies_skipped": self.copies_skipped, "stale_ignored": self.stale_ignored}


def mission_only(mission_file: str):
    """Load and validate the mission (no components), with the same clear errors as :func:`mission_pieces`."""
    if not mission_file:
        raise NodeConfigError("parameter 'mission_file' is empty: give the mission YAML "
                              "(the same file as `bb2-sim mission`), e.g. -p mission_file:=missions/canyon.yaml")
    from bb2_mission import load_mission

    try:
        return load_mission(mission_file)
    except (ValueError, KeyError, TypeError, OSError) as exc:
        raise NodeConfigError(f"mission file {mission_file!r}: {exc}") from None


def build_piece(mission, builder: Callable[[Any], Any]):
    """``builder(mission)`` -- one of :mod:`bb2_mission.components`' builders (the simulator, the stack, the
    mixer ...) -- with clear errors: a node builds only its own piece of the mission."""
    try:
        return builder(mission)
    except (ValueError, KeyError, TypeError, OSError) as exc:
        raise NodeConfigError(f"mission {getattr(mission, 'name', '?')!r}: {exc}") from None


def require_rate_stack(stack) -> None:
    """The node graph splits the rate stack (rate_pf_3d); the LOS stack runs in-process only."""
    from bb2_control.stacks import RatePathFollowingStack

    if not isinstance(stack, RatePathFollowingStack):
        raise NodeConfigError(
            f"stack {stack.name!r} ({stack.config.get('type')}) is not supported by the node graph: the graph "
            "carries q_c/r_c rate commands (stack type rate_pf_3d, e.g. rate_2022); fly it with `bb2-sim mission`")


class StateSource(StrEnum):
    """Where a controller node reads the vehicle state."""

    NATIVE = "native"      #: /bb2/state_native: exact, reliable; the lockstep trigger
    ODOMETRY = "odometry"  #: /bb2/odom: REP-103, sensor QoS (external tools, HIL)


STATE_SOURCES = tuple(s.value for s in StateSource)


NAV_STATE_TOPIC = "/bb2/nav/state_native"


def state_topic(mission) -> str:
    """The native state topic a controller flies on for ``mission``: ``/bb2/state_native`` (the truth, as the
    paper), or ``/bb2/nav/state_native`` (the navigation filter's estimate) with ``navigation: sensors``."""
    return NAV_STATE_TOPIC if getattr(mission, "navigation", "truth") == "sensors" else "/bb2/state_native"


def node_frame(node, frame: str) -> str:
    """``frame`` of the vehicle whose nodes run in ``node``'s namespace (``base_link`` in the root namespace,
    ``boat1/base_link`` in ``/boat1``; the world frames as they are): :func:`bb2_msgs_py.contract.vehicle_frame`."""
    from bb2_msgs_py.contract import frame_prefix, vehicle_frame

    return vehicle_frame(frame, frame_prefix(node.get_namespace()))


def subscribe_state(node, source: str, callback: Callable[[Any, int], None], native_topic: str = "/bb2/state_native"):
    """Subscribe to the vehicle state: ``native`` = ``native_topic`` (``/bb2/state_native``: exact, reliable; the
    lockstep trigger; or the navigation estimate, :func:`state_topic`) or ``odometry`` = ``/bb2/odom``
    (REP-103, sensor QoS, quaternion -> Euler rounding; for external tools / HIL: the truth, so refused with a
    navigation estimate).  ``callback(state: VehicleState, stamp_ns)``."""
    from bb2_msgs_py import conversions as cv
    from bb2_msgs_py.contract import message_class, node_topic_name, qos_profile

    native = StateSource(require_choice("state_source", source, STATE_SOURCES)) is StateSource.NATIVE
    if not native and native_topic != "/bb2/state_native":
        raise NodeConfigError(f"state_source odometry reads the truth (/bb2/odom): with navigation: sensors the "
                              f"controllers fly on {native_topic} (state_source native)")
    if native:
        def on_native(msg):
            try:
                s = cv.state_native_from_message(msg)
            except cv.ConversionError as exc:
                node.get_logger().warning(f"ignored {native_topic}: {exc}", throttle_duration_sec=2.0)
                return
            callback(s, cv.seconds_to_ns(s.t))
        return node.create_subscription(message_class("std_msgs/msg/Float64MultiArray"),
                                        node_topic_name(native_topic), on_native,
                                        qos_profile(native_topic, reader=True))

    from bb2_msgs_py.contract import FRAME_BASE_LINK

    base_link = node_frame(node, FRAME_BASE_LINK)

    def on_odom(msg):
        try:
            s = cv.odometry_to_state(msg, child_frame_id=base_link)
        except cv.ConversionError as exc:
            node.get_logger().warning(f"ignored /bb2/odom: {exc}", throttle_duration_sec=2.0)
            return
        callback(s, cv.stamp_to_ns(msg.header.stamp))
    return node.create_subscription(message_class("nav_msgs/msg/Odometry"), node_topic_name("/bb2/odom"), on_odom,
                                    qos_profile("/bb2/odom", reader=True))


def take_all(subscription) -> list[tuple[bytes, dict]]:
    """Every message waiting on a raw (``raw=True``) subscription, oldest first, each with its message info
    (``source_timestamp``, ``received_timestamp``, ...): for readers that wait or poll themselves instead of
    taking an executor callback per message (the recorder, the launcher's monitor, the benchmark's probe)."""
    out = []
    while (got := subscription.handle.take_message(subscription.msg_type, True)) is not None:
        out.append(got)
    return out


def time_msg(stamp_ns: int):
    """``builtin_interfaces/Time`` of integer nanoseconds (exact, no float round trip)."""
    from builtin_interfaces.msg import Time

    return Time(sec=int(stamp_ns) // 1_000_000_000, nanosec=int(stamp_ns) % 1_000_000_000)
