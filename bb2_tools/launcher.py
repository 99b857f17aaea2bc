"""bb2-launch: fly a mission through the BB2 ROS 2 node graph, one process per node.

The launcher starts every node at once (their imports and mission builds overlap): in lockstep the
simulator publishes its first state only once the recorder reads every topic it publishes, then waits
for the controllers; in real time it starts last, once the recorder is subscribed to every contract
topic, and steps on the failsafe until commands come.  Each node runs in its own process and process
group, on an isolated ``ROS_DOMAIN_ID`` (a random free one unless ``--domain-id``).  A
small rclpy monitor node inside the launcher shows sim time (``/clock``), mission progress
(``/bb2/mission/progress``) and the real-time factor on one line.

It stops the graph cleanly when the mission ends (``--end-at``: the progress reaches 1, or the
simulator reports the end of the mission duration on ``/bb2/status`` or exits with code 0), when
the simulator reports that it stopped (diverged), on Ctrl-C (SIGINT) or SIGTERM, after
``--timeout``, or when a node dies.  Stopping sends SIGINT to the process groups, then SIGTERM, then SIGKILL
after grace periods; the recorder is stopped last and gets the longest grace so it finishes its
bag.  A node that dies is reported with its exit code or signal and its last log lines, and is
handled by its restart policy (``--restart NODE=stop|restart[:N]|ignore``; default ``stop``).

Every child's stdout and stderr go to ``<run>/logs/<node>.log`` (and a ring buffer of the last
lines).  ``<run>`` is the bag directory ``<bag-dir>/<mission>_<YYYYmmdd_HHMMSS>/`` (metadata.yaml
and the .mcap beside ``logs/``).

How a node is started (``--runner``): ``ros2`` (``ros2 run <pkg> <exe>``, when the ROS 2 CLI is
on PATH and the package is in the ament index), ``lib`` (``<prefix>/lib/<pkg>/<exe>`` from the
ament index, exactly what ``ros2 run`` executes; see ``bb2_ros_ws/install_into_venv.py``),
``python`` (the package entry point in this interpreter); ``auto`` picks the first that works.

Exit codes: 0 mission complete; 1 a node failed, the timeout passed, or the recorder had to be
killed; 2 bad input; 130 interrupted (Ctrl-C / SIGTERM).

The process supervision (:class:`Supervisor`) is usable on its own, from Python and tests.
"""
from __future__ import annotations

import argparse
import collections
import ctypes
import os
import random
import shutil
import signal
import struct
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterable, Mapping, Sequence

from bb2_ros.node_common import take_all

POLICIES = ("stop", "restart", "ignore")
DEFAULT_MAX_RESTARTS = 3
RECORDER_NODE_NAME = "bb2_recorder"
SAFE_DOMAIN_IDS = range(1, 102)  # ROS 2 docs: 0..101 never collide with Linux ephemeral ports


class LaunchError(ValueError):
    """Bad launcher input (mission, params file, restart policy, domain id ...)."""


# ============================================================================ the node table
@dataclass(frozen=True)
class GraphNode:
    """One node of the BB2 graph: its ROS 2 package/executable and its Python entry point."""

    name: str
    package: str
    executable: str
    entry_point: str  # "module:function"


GRAPH_NODES: tuple[GraphNode, ...] = (
    GraphNode("recorder", "bb2_tools", "recorder", "bb2_tools.recorder:main"),
    GraphNode("planner", "bb2_ros", "planner", "bb2_ros.planner:main"),
    GraphNode("path_following", "bb2_ros", "path_following", "bb2_ros.path_following:main"),
    GraphNode("l1_autopilot", "bb2_ros", "l1_autopilot", "bb2_ros.l1_autopilot:main"),
    GraphNode("mixer", "bb2_ros", "mixer", "bb2_ros.mixer:main"),
    GraphNode("simulator", "bb2_ros", "simulator", "bb2_ros.simulator:main"),
)
"""The graph's nodes (:func:`graph_specs` decides the start order)."""

RUNNERS = ("auto", "ros2", "lib", "python")


def _lib_executable(package: str, executable: str) -> Path | None:
    """``<prefix>/lib/<package>/<executable>`` from the ament index (what ``ros2 run`` runs)."""
    try:
        from ament_index_python.packages import PackageNotFoundError, get_package_prefix
    except ImportError:
        return None
    try:
        prefix = Path(get_package_prefix(package))
    except (PackageNotFoundError, ValueError, LookupError):
        return None
    path = prefix / "lib" / package / executable
    return path if path.is_file() and os.access(path, os.X_OK) else None


def node_command(node: GraphNode, runner: str = "auto") -> list[str]:
    """The argv prefix that starts ``node`` (arguments are appended by the caller)."""
    if runner not in RUNNERS:
        raise LaunchError(f"--runner must be one of {RUNNERS}, got {runner!r}")
    lib = _lib_executable(node.package, node.executable) if runner in ("auto", "ros2", "lib") else None
    ros2 = shutil.which("ros2") if runner in ("auto", "ros2") else None
    if ros2 and lib:
        return [ros2, "run", node.package, node.executable]
    if runner == "ros2":
        raise LaunchError(f"--runner ros2: {'no ros2 on PATH' if not ros2 else 'package not found'} "
                          f"for {node.package}/{node.executable}")
    if lib:
        return [str(lib)]
    if runner == "lib":
        raise LaunchError(f"--runner lib: no {node.package}/lib/{node.package}/{node.executable} in the "
                          "ament index (AMENT_PREFIX_PATH); run bb2_ros_ws/install_into_venv.py")
    module, func = node.entry_point.split(":")
    code = (f"import sys; sys.argv[0] = {node.executable!r}; from {module} import {func}; "
            f"sys.exit({func}())")
    return [sys.executable, "-c", code]


# ============================================================================ restart policies
@dataclass(frozen=True)
class RestartPolicy:
    """What to do when a node exits on its own: ``stop`` the graph, ``restart`` it up to
    ``max_restarts`` times (then stop), or ``ignore`` it."""

    action: str = "stop"
    max_restarts: int = DEFAULT_MAX_RESTARTS

    def __post_init__(self):
        if self.action not in POLICIES:
            raise LaunchError(f"restart policy must be one of {POLICIES}, got {self.action!r}")
        if self.max_restarts < 0:
            raise LaunchError(f"max restarts must be >= 0, got {self.max_restarts}")


def parse_restart_policies(specs: Iterable[str], known: Iterable[str],
                           default_max: int = DEFAULT_MAX_RESTARTS) -> dict[str, RestartPolicy]:
    """Parse ``["simulator=stop,recorder=restart:5", "mixer=ignore"]`` into policies per node."""
    known = list(known)
    out: dict[str, RestartPolicy] = {}
    for spec in specs:
        for item in filter(None, (s.strip() for s in spec.split(","))):
            name, sep, value = item.partition("=")
            if not sep or not name or not value:
                raise LaunchError(f"--restart expects NODE=POLICY items, got {item!r}")
            if name not in known and name != "all":
                raise LaunchError(f"--restart: unknown node {name!r}; nodes: {', '.join(known)}")
            action, _, n = value.partition(":")
            try:
                max_n = int(n) if n else default_max
            except ValueError:
                raise LaunchError(f"--restart: bad restart count in {item!r}") from None
            if n and action != "restart":
                raise LaunchError(f"--restart: a count only goes with 'restart', got {item!r}")
            policy = RestartPolicy(action, max_n)
            for target in (known if name == "all" else [name]):
                out[target] = policy
    return out


# ============================================================================ supervision
@dataclass
class ProcessSpec:
    """A supervised process.

    ``command`` is an argv, or a function of the attempt number (0 first, 1 first restart ...)
    returning one.  ``finishes_graph``: exit code 0 means the job is done (the rest is stopped
    cleanly, not a failure).  ``stop_stage``: lower stages are stopped first (the recorder is
    stopped last).  ``ready``: optional readiness probe used by :meth:`Supervisor.start`.
    """

    name: str
    command: Sequence[str] | Callable[[int], Sequence[str]]
    policy: RestartPolicy = field(default_factory=RestartPolicy)
    finishes_graph: bool = False
    stop_stage: int = 0
    sigint_grace_s: float = 10.0
    sigterm_grace_s: float = 3.0
    ready: Callable[[], bool] | None = None
    env: Mapping[str, str] | None = None
    nice: int = 0  # niceness increment (> 0: yields the CPU to the control loop; e.g. the recorder)
    early: bool = False  # started at once by run_graph, alongside the ready-gated ones (needs nothing before it)

    def argv(self, attempt: int) -> list[str]:
        cmd = self.command(attempt) if callable(self.command) else self.command
        return [str(c) for c in cmd]


def signal_name(returncode: int | None) -> str | None:
    """``"SIGKILL"`` for a return code of -9 (Popen's convention for death by signal)."""
    if returncode is None or returncode >= 0:
        return None
    try:
        return signal.Signals(-returncode).name
    except ValueError:
        return f"signal {-returncode}"


def exit_cause(returncode: int | None) -> str:
    """``"exit code 3"`` or ``"killed by SIGKILL"``."""
    if returncode is None:
        return "still running"
    sig = signal_name(returncode)
    return f"killed by {sig}" if sig else f"exit code {returncode}"


@dataclass
class NodeExit:
    """A process that ended, and what the supervisor did about it.

    ``action``: ``stop`` (it failed, the graph is stopped), ``restart``, ``ignore``,
    ``finished`` (a ``finishes_graph`` process exited 0) or ``shutdown`` (it ended while the
    supervisor was stopping everything).
    """

    name: str
    returncode: int
    attempt: int
    action: str
    last_lines: list[str]
    log_path: Path
    wall_time: float

    @property
    def cause(self) -> str:
        return exit_cause(self.returncode)

    def report(self, n_lines: int = 10) -> str:
        """A human report: which node, why, its last log lines and where the full log is."""
        head = f"node '{self.name}' ended ({self.cause})"
        if self.attempt:
            head += f" on restart {self.attempt}"
        tail = self.last_lines[-n_lines:]
        body = "".join(f"\n    | {line}" for line in tail) if tail else "\n    | (no output)"
        return f"{head}; last log lines:{body}\n    full log: {self.log_path}"


def _set_parent_death_signal() -> None:  # runs in the child between fork and exec
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG: die with the launcher
    except Exception:
        pass


class _Child:
    """A running process with a thread copying its output into a log file and a ring buffer."""

    def __init__(self, spec: ProcessSpec, attempt: int, log_path: Path, ring_lines: int,
                 env: Mapping[str, str], cwd: Path | None, echo: Callable[[str, str], None] | None):
        self.spec, self.attempt, self.log_path = spec, attempt, log_path
        self.ring: collections.deque[str] = collections.deque(maxlen=ring_lines)
        self.argv = spec.argv(attempt)
        self.started = time.monotonic()
        self.log = open(log_path, "ab", buffering=0)
        stamp = time.strftime("%Y-%m-%d %H:%M:%S")
        self.log.write(f"---- {stamp} attempt {attempt}: {' '.join(self.argv)}\n".encode())
        full_env = dict(env)
        full_env.update(spec.env or {})
        nice = int(spec.nice)

        def preexec() -> None:  # in the child between fork and exec
            if sys.platform.startswith("linux"):
                _set_parent_death_signal()
            if nice > 0:
                os.nice(nice)
        try:
            self.popen = subprocess.Popen(self.argv, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                          stderr=subprocess.STDOUT, env=full_env, cwd=cwd,
                                          start_new_session=True, preexec_fn=preexec)
        except OSError as exc:
            self.log.close()
            raise LaunchError(f"cannot start node '{spec.name}' ({self.argv[0]}): {exc}") from None
        self.pgid = self.popen.pid
        self._echo = echo
        self.reader = threading.Thread(target=self._copy_output, name=f"log-{spec.name}", daemon=True)
        self.reader.start()

    def _copy_output(self) -> None:
        assert self.popen.stdout is not None
        for raw in iter(self.popen.stdout.readline, b""):
            try:
                self.log.write(raw)
            except ValueError:  # log closed
                break
            line = raw.decode("utf-8", "replace").rstrip("\r\n")
            self.ring.append(line)
            if self._echo:
                self._echo(self.spec.name, line)

    def signal(self, sig: int) -> None:
        try:
            os.killpg(self.pgid, sig)
        except (ProcessLookupError, PermissionError):
            pass

    def finish(self) -> list[str]:
        """After exit: make sure nothing of its group survives, drain the output, close the log."""
        self.signal(signal.SIGKILL)  # leftovers in the group (e.g. the node under `ros2 run`)
        self.reader.join(timeout=2.0)
        rc = self.popen.returncode
        try:
            self.log.write(f"---- exited: {exit_cause(rc)}\n".encode())
        except ValueError:
            pass
        self.log.close()
        return list(self.ring)


class Supervisor:
    """Starts, watches, restarts and stops a set of processes (see :class:`ProcessSpec`).

    Typical use::

        with Supervisor(specs, log_dir) as sup:
            sup.start()
            while not sup.done:
                for ev in sup.poll():
                    print(ev.report())
                time.sleep(0.1)
        # leaving the block stops whatever still runs

    ``done`` is true once a process failed under the ``stop`` policy (:attr:`failure`), a
    ``finishes_graph`` process exited 0 (:attr:`finished`), or nothing is left running.
    """

    def __init__(self, specs: Sequence[ProcessSpec], log_dir: str | os.PathLike, *,
                 env: Mapping[str, str] | None = None, cwd: str | os.PathLike | None = None,
                 ring_lines: int = 200, restart_delay_s: float = 0.5,
                 echo: Callable[[str, str], None] | None = None):
        names = [s.name for s in specs]
        if len(set(names)) != len(names):
            raise LaunchError(f"duplicate process names in {names}")
        self.specs = {s.name: s for s in specs}
        self.order = names
        self.log_dir = Path(log_dir)
        self.log_dir.mkdir(parents=True, exist_ok=True)
        self.env = dict(os.environ if env is None else env)
        self.env.setdefault("PYTHONUNBUFFERED", "1")
        self.cwd = Path(cwd) if cwd else None
        self.ring_lines = ring_lines
        self.restart_delay_s = restart_delay_s
        self.echo = echo
        self.children: dict[str, _Child] = {}
        self.attempts: dict[str, int] = {}
        self.exits: list[NodeExit] = []
        self.failure: NodeExit | None = None
        self.finished: NodeExit | None = None
        self.stopping = False
        self._pending_restarts: dict[str, float] = {}

    # ------------------------------------------------------------------ starting
    def log_path(self, name: str) -> Path:
        return self.log_dir / f"{name}.log"

    def start(self, names: Iterable[str] | None = None, *, ready_timeout_s: float = 30.0,
              interrupted: Callable[[], bool] = lambda: False) -> None:
        """Start ``names`` (default: all, in order); for a spec with ``ready``, wait until it is
        ready (or raise :class:`LaunchError` if ``ready_timeout_s`` passes).  Returns early when
        a started process dies (:meth:`poll` reports it) or ``interrupted()`` becomes true."""
        for name in (self.order if names is None else list(names)):
            if interrupted():
                return
            self._spawn(name, 0)
            if self.specs[name].ready is not None and not self.wait_ready(name, ready_timeout_s, interrupted):
                return

    def wait_ready(self, name: str, timeout_s: float,
                   interrupted: Callable[[], bool] = lambda: False) -> bool:
        """Wait until ``name`` is ready; False if it died or ``interrupted()`` first."""
        spec, child = self.specs[name], self.children[name]
        deadline = time.monotonic() + timeout_s
        while not spec.ready():
            if child.popen.poll() is not None or interrupted():
                return False
            if time.monotonic() > deadline:
                raise LaunchError(f"node '{name}' not ready after {timeout_s:g} s; log: {child.log_path}")
            time.sleep(0.05)
        return True

    def _spawn(self, name: str, attempt: int) -> None:
        if name in self.children:
            raise LaunchError(f"node '{name}' is already running")
        self.attempts[name] = attempt
        self.children[name] = _Child(self.specs[name], attempt, self.log_path(name), self.ring_lines,
                                     self.env, self.cwd, self.echo)

    # ------------------------------------------------------------------ watching
    def running(self) -> list[str]:
        return [n for n in self.order if n in self.children and self.children[n].popen.poll() is None]

    def pid(self, name: str) -> int:
        return self.children[name].popen.pid

    def last_lines(self, name: str, n: int = 20) -> list[str]:
        child = self.children.get(name)
        return list(child.ring)[-n:] if child else []

    @property
    def done(self) -> bool:
        return (self.failure is not None or self.finished is not None
                or (not self.children and not self._pending_restarts))

    def poll(self) -> list[NodeExit]:
        """Collect processes that ended, apply their policies; return what happened."""
        events: list[NodeExit] = []
        now = time.monotonic()
        for name in list(self.children):
            child = self.children[name]
            rc = child.popen.poll()
            if rc is None:
                continue
            lines = child.finish()
            del self.children[name]
            spec = self.specs[name]
            if self.stopping:
                action = "shutdown"
            elif rc == 0 and spec.finishes_graph:
                action = "finished"
            elif spec.policy.action == "restart" and child.attempt < spec.policy.max_restarts:
                action = "restart"
            elif spec.policy.action == "ignore":
                action = "ignore"
            else:
                action = "stop"
            ev = NodeExit(name, rc, child.attempt, action, lines, child.log_path, now - child.started)
            events.append(ev)
            self.exits.append(ev)
            if action == "restart":
                self._pending_restarts[name] = now + self.restart_delay_s * (child.attempt + 1)
            elif action == "finished" and self.finished is None:
                self.finished = ev
            elif action == "stop" and self.failure is None:
                self.failure = ev
        if not self.stopping and self.failure is None:
            for name, when in list(self._pending_restarts.items()):
                if now >= when:
                    del self._pending_restarts[name]
                    self._spawn(name, self.attempts[name] + 1)
        return events

    # ------------------------------------------------------------------ stopping
    def stop(self, *, hurry: bool | Callable[[], bool] = False) -> list[NodeExit]:
        """Stop everything still running, stage by stage (SIGINT, then SIGTERM, then SIGKILL after
        each spec's grace periods; ``hurry`` -- or ``hurry()`` becoming true, e.g. on a second
        Ctrl-C -- shortens them to 1 s).  Returns the exits."""
        self.stopping = True
        self._pending_restarts.clear()
        first = len(self.exits)
        stages = sorted({self.specs[n].stop_stage for n in self.children})
        for stage in stages:
            group = [c for n, c in self.children.items() if self.specs[n].stop_stage == stage]
            self._terminate(group, hurry=hurry)
            self.poll()  # exits are recorded stage by stage
        return self.exits[first:]

    def _terminate(self, group: list[_Child], *, hurry: bool | Callable[[], bool]) -> None:
        hurried = hurry if callable(hurry) else (lambda: bool(hurry))
        for sig, grace_attr in ((signal.SIGINT, "sigint_grace_s"), (signal.SIGTERM, "sigterm_grace_s"),
                                (signal.SIGKILL, None)):
            alive = [c for c in group if c.popen.poll() is None]
            if not alive:
                return
            for c in alive:
                c.log.write(f"---- launcher: sending {signal.Signals(sig).name}\n".encode())
                c.signal(sig)
            grace = 5.0 if grace_attr is None else max(getattr(c.spec, grace_attr) for c in alive)
            start = time.monotonic()
            while any(c.popen.poll() is None for c in alive):
                waited = time.monotonic() - start
                if waited > grace or (hurried() and waited > 1.0):
                    break
                time.sleep(0.02)

    def __enter__(self) -> "Supervisor":
        return self

    def __exit__(self, *exc) -> None:
        self.stop(hurry=exc[0] is not None)


# ============================================================================ the monitor node
def _cdr_unpack(fmt: str, data: bytes) -> tuple:
    """Unpack a fixed-layout CDR payload (after the 4-byte encapsulation header)."""
    endian = "<" if len(data) > 1 and data[1] & 1 else ">"
    return struct.unpack_from(endian + fmt, data, 4)


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
                 end_at: str = "either"):
        if end_at not in END_AT:
            raise LaunchError(f"end_at must be one of {END_AT}, got {end_at!r}")
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.qos import HistoryPolicy
        from rclpy.signals import SignalHandlerOptions

        from bb2_msgs_py.contract import message_class, qos_profile

        self.domain_id = domain_id
        self.node_name = node_name
        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain_id, signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node(node_name, context=self.context, start_parameter_services=False,
                                      enable_rosout=False)
        self._lock = threading.Lock()
        self.sim_time_s: float | None = None
        self.progress: float | None = None
        self.status_end = False  # the simulator's status says the mission duration is over
        self.sim_error: str | None = None  # the simulator's status says it stopped on an error
        self.end_at = end_at
        self._samples: collections.deque[tuple[float, float]] = collections.deque()
        self._first: tuple[float, float] | None = None  # the first /clock (start-up handshake at t0)
        self._first_step: tuple[float, float] | None = None  # the first /clock after t0 (stepping started)
        self.rtf_window_s = rtf_window_s
        n = self.node
        n.create_subscription(message_class("diagnostic_msgs/msg/DiagnosticArray"), "/bb2/status",
                              self._on_status, qos_profile("/bb2/status"))
        # /clock and the progress come once per step (hundreds per wall second in lockstep): they are not
        # spun (a Python callback each would take CPU from the graph) but polled, the latest sample only,
        # from a second node that no executor waits on.
        self.poll_node_name = node_name + "_poll"
        self._poll_node = rclpy.create_node(self.poll_node_name, context=self.context,
                                            start_parameter_services=False, enable_rosout=False)

        def latest_only(name):
            q = qos_profile(name)
            q.history, q.depth = HistoryPolicy.KEEP_LAST, 1
            return q

        self._clock_sub = self._poll_node.create_subscription(
            message_class("rosgraph_msgs/msg/Clock"), "/clock", _unused, latest_only("/clock"), raw=True)
        self._progress_sub = self._poll_node.create_subscription(
            message_class("std_msgs/msg/Float64"), "/bb2/mission/progress", _unused,
            latest_only("/bb2/mission/progress"), raw=True)
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
        """Take the latest /clock and progress (if new ones came)."""
        for sub, handler in ((self._clock_sub, self._on_clock), (self._progress_sub, self._on_progress)):
            got = take_all(sub)
            if got:
                data, info = got[-1]
                handler(data, int(info.get("source_timestamp", 0)) * 1e-9 or time.time())

    def _on_clock(self, data: bytes, wall: float) -> None:
        """``wall``: the DDS source timestamp (the simulator's wall clock when it published this /clock)."""
        sec, nsec = _cdr_unpack("iI", data)
        t = sec + nsec * 1e-9
        with self._lock:
            self.sim_time_s = t
            if self._first is None:
                self._first = (wall, t)
            elif self._first_step is None and t != self._first[1]:
                self._first_step = (wall, t)
            self._samples.append((wall, t))
            while len(self._samples) > 2 and wall - self._samples[0][0] > self.rtf_window_s:
                self._samples.popleft()

    def _on_progress(self, data: bytes, _wall: float = 0.0) -> None:
        (p,) = _cdr_unpack("d", data)
        with self._lock:
            self.progress = p

    def _on_status(self, msg) -> None:
        for st in msg.status:
            if "simulator" not in st.name:
                continue
            vals = {kv.key: kv.value for kv in st.values}
            state = vals.get("state", "").lower()
            if state in END_WORDS:
                self.status_end = True
            elif state == "diverged":
                self.sim_error = vals.get("error") or st.message or "diverged"

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
        """Whether ``node_name`` has a subscription on each of ``topics`` (as discovered here)."""
        for t in topics:
            if not any(i.node_name == node_name for i in self.node.get_subscriptions_info_by_topic(t)):
                return False
        return True

    def close(self) -> None:
        import rclpy

        self._stop.set()
        self._thread.join(timeout=2.0)
        try:
            self.executor.shutdown(timeout_sec=1.0)
            self._poll_node.destroy_node()
            self.node.destroy_node()
        finally:
            if self.context.ok():
                rclpy.shutdown(context=self.context)


def free_domain_id(*, rng: random.Random | None = None, tries: int = 8, listen_s: float = 0.5,
                   **monitor_kw) -> GraphMonitor:
    """A :class:`GraphMonitor` on a random domain id (1..101) where no other node is seen."""
    rng = rng or random.Random()
    candidates = rng.sample(list(SAFE_DOMAIN_IDS), tries)
    for d in candidates:
        mon = GraphMonitor(d, **monitor_kw)
        time.sleep(listen_s)
        if not mon.node_names():
            return mon
        mon.close()
    raise LaunchError(f"no free ROS_DOMAIN_ID among {candidates}; give one with --domain-id")


# ============================================================================ the run loop
def format_status(sim_time_s: float | None, progress: float | None, rtf: float | None,
                  up: int, total: int, wall_s: float) -> str:
    """The one progress line."""
    t = "--" if sim_time_s is None else f"{sim_time_s:8.2f} s"
    p = "--" if progress is None else f"{100.0 * progress:5.1f} %"
    r = "--" if rtf is None else f"{rtf:6.1f}x"
    return f"[bb2-launch] sim {t} | progress {p} | RTF {r} | nodes {up}/{total} | wall {wall_s:6.1f} s"


@dataclass
class RunResult:
    """How a :func:`run_graph` ended."""

    exit_code: int
    reason: str
    exits: list[NodeExit]
    sim_time_s: float | None
    progress: float | None
    rtf_overall: float | None  # sim s per wall s while stepping (GraphMonitor.rtf(overall=True))
    wall_s: float
    stepping_wall_s: float | None = None  # wall s from the first step to the last /clock


class _StopFlag:
    """SIGINT/SIGTERM handling for the run loop: first signal stops, second hurries."""

    def __init__(self):
        self.count = 0
        self.signame = ""

    def __call__(self, signum, _frame) -> None:
        self.count += 1
        self.signame = signal.Signals(signum).name


def run_graph(sup: Supervisor, monitor: GraphMonitor | None, *, first: Sequence[str] = (),
              ready_timeout_s: float = 30.0, timeout_s: float | None = None, status_period_s: float = 5.0,
              out=sys.stderr, handle_signals: bool = True) -> RunResult:
    """Start the ``early`` specs at once, then ``first`` one by one (waiting for readiness), then the rest;
    supervise until the mission ends, a node fails, a signal arrives or ``timeout_s`` passes; stop
    everything; return the result."""
    flag = _StopFlag()
    previous = {}
    if handle_signals and threading.current_thread() is threading.main_thread():
        previous = {s: signal.signal(s, flag) for s in (signal.SIGINT, signal.SIGTERM)}
    tty = hasattr(out, "isatty") and out.isatty()
    t0 = time.monotonic()
    last_status = 0.0
    reason, code = "", 0

    def say(msg: str) -> None:
        print(("\r\033[K" if tty else "") + msg, file=out, flush=True)

    def report(events: Sequence[NodeExit]) -> None:
        for ev in events:
            if ev.action in ("restart", "ignore"):
                say(f"[bb2-launch] {ev.report()}\n[bb2-launch] policy '{ev.action}' for '{ev.name}'")

    try:
        try:
            interrupted = lambda: bool(flag.count)  # noqa: E731
            early = [n for n in sup.order if sup.specs[n].early and n not in first]
            sup.start(early, interrupted=interrupted)  # they import and build while the gated ones come up
            sup.start(first, ready_timeout_s=ready_timeout_s, interrupted=interrupted)
            report(sup.poll())
            if not interrupted() and sup.failure is None:
                sup.start([n for n in sup.order if n not in first and n not in early], interrupted=interrupted)
        except LaunchError as exc:
            reason, code = f"start-up failed: {exc}", 1
        while not reason:
            report(sup.poll())
            now = time.monotonic()
            if sup.failure:
                reason, code = f"node '{sup.failure.name}' failed ({sup.failure.cause})", 1
            elif sup.finished:
                reason = f"node '{sup.finished.name}' finished (exit code 0)"
            elif monitor is not None and monitor.sim_error:
                reason, code = f"the simulator stopped: {monitor.sim_error}", 1
            elif monitor is not None and monitor.mission_complete:
                reason = "mission complete"
            elif not sup.running() and sup.done:
                reason, code = "no node left running", 1
            elif flag.count:
                reason, code = f"interrupted ({flag.signame})", 130
            elif timeout_s and now - t0 > timeout_s:
                reason, code = f"timeout after {timeout_s:g} s", 1
            if reason:
                break
            if monitor is not None and (tty or now - last_status >= status_period_s):
                line = format_status(monitor.sim_time_s, monitor.progress, monitor.rtf(),
                                     len(sup.running()), len(sup.order), now - t0)
                if tty:
                    print("\r\033[K" + line, end="", file=out, flush=True)
                else:
                    print(line, file=out, flush=True)
                last_status = now
            time.sleep(0.1)
        if tty:
            print(file=out)
        say(f"[bb2-launch] stopping: {reason}")
        if sup.failure:
            say(f"[bb2-launch] {sup.failure.report()}")
        stopped = sup.stop(hurry=lambda: flag.count > 1)
        for ev in stopped:
            if ev.returncode != 0 and ev.returncode != -signal.SIGINT:
                say(f"[bb2-launch] during shutdown: {ev.report(5)}")
            if ev.returncode == -signal.SIGKILL and sup.specs[ev.name].stop_stage > 0:
                code = code or 1
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
    return RunResult(code, reason, list(sup.exits),
                     monitor.sim_time_s if monitor else None, monitor.progress if monitor else None,
                     monitor.rtf(overall=True) if monitor else None, time.monotonic() - t0,
                     monitor.stepping_span()[1] if monitor else None)


# ============================================================================ the BB2 graph
RECORDED_TOPICS_NOTE = "the recorder is ready when it subscribes to every non-bag-only contract topic"


def _load_yaml_mapping(path: Path, what: str) -> dict:
    import yaml

    if not path.is_file():
        raise LaunchError(f"{what} {path} does not exist")
    try:
        data = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise LaunchError(f"{what} {path} is not valid YAML: {exc}") from None
    if not isinstance(data, dict):
        raise LaunchError(f"{what} {path} must be a YAML mapping, got {type(data).__name__}")
    return data


def check_mission(path: Path) -> None:
    """Validate the mission file with ``bb2_mission.load_mission`` (when available)."""
    _load_yaml_mapping(path, "mission file")
    try:
        from bb2_mission import load_mission
    except ImportError:
        return
    try:
        load_mission(path)
    except (ValueError, OSError) as exc:
        msg = str(exc)
        raise LaunchError(msg if str(path) in msg else f"mission {path}: {msg}") from None


def check_params_file(path: Path) -> None:
    """A ROS 2 params file: a mapping of node names (or ``/**``) to ``{ros__parameters: {...}}``."""
    data = _load_yaml_mapping(path, "params file")
    for node, body in data.items():
        if not isinstance(body, dict) or not isinstance(body.get("ros__parameters"), dict):
            raise LaunchError(f"params file {path}: entry {node!r} needs a 'ros__parameters' mapping")


BACKGROUND_NICE = 10
BACKGROUND_NODES = ("recorder", "planner")
"""Nodes off the control loop (state -> commands -> step), started with ``nice +BACKGROUND_NICE``: on a
machine with fewer cores than busy processes they take the CPU the loop leaves (the recorder's deep queues
absorb the delay; the planner only publishes the path), not the loop's."""


def graph_specs(mission: Path, run_dir: Path, *, mode: str = "lockstep", params: Path | None = None,
                record: bool = True, runner: str = "auto",
                policies: Mapping[str, RestartPolicy] | None = None,
                monitor: GraphMonitor | None = None) -> list[ProcessSpec]:
    """The process specs of the BB2 graph for one mission, in start order.

    The planner and the controllers, and in lockstep the simulator, are ``early``: :func:`run_graph`
    starts them at once (each takes a second or two to import and build its part of the mission, which
    then overlap).  The recorder has a ``ready`` probe (subscribed to every contract topic); in lockstep
    the simulator, started with ``wait_for_readers``, publishes its first state only once every topic
    it publishes has a reader (the recorder), so the bag misses nothing, and then waits for the
    controllers (re-sending the state until they answer).  Without a recorder the simulator starts at
    once.  In real time the simulator starts last, once the recorder is ready (it steps on the wall
    clock from its first tick, on the failsafe until commands arrive).  ``monitor`` gives the recorder
    its readiness probe.
    """
    from bb2_msgs_py.contract import select_topics

    if mode not in ("lockstep", "realtime"):
        raise LaunchError(f"--mode must be lockstep or realtime, got {mode!r}")
    policies = dict(policies or {})
    specs: list[ProcessSpec] = []
    for node in GRAPH_NODES:
        base = node_command(node, runner)
        policy = policies.get(node.name, RestartPolicy())
        if node.name == "recorder":
            if not record:
                continue
            topics = [t.name for t in select_topics()]

            def rec_cmd(attempt: int, base=base) -> list[str]:
                out = run_dir if attempt == 0 else run_dir.with_name(f"{run_dir.name}_r{attempt}")
                return [*base, "--out", str(out), "--overwrite", "--use-sim-time"]

            ready = (lambda m=monitor, t=topics: m.subscribed(RECORDER_NODE_NAME, t)) if monitor else None
            specs.append(ProcessSpec(node.name, rec_cmd, policy, stop_stage=1, sigint_grace_s=30.0,
                                     sigterm_grace_s=10.0, ready=ready, nice=BACKGROUND_NICE))
            continue
        # The params file goes first: for '/**' keys the last source wins, so the launcher's own -p values
        # (mission, time mode, sim time) must come after it.
        ros = ["--ros-args"] + (["--params-file", str(params)] if params is not None else [])
        ros += ["-p", f"mission_file:={mission}"]
        if node.name == "simulator":
            ros += ["-p", f"time_mode:={mode}"]
            if mode == "lockstep" and record:
                ros += ["-p", "wait_for_readers:=true"]
        else:
            ros += ["-p", "use_sim_time:=true"]
        specs.append(ProcessSpec(node.name, [*base, *ros], policy, finishes_graph=node.name == "simulator",
                                 nice=BACKGROUND_NICE if node.name in BACKGROUND_NODES else 0,
                                 early=node.name != "simulator" or mode == "lockstep"))
    first = [s for s in specs if s.ready is not None]
    return first + [s for s in specs if s.ready is None]


def recorder_bags(run_dir: Path, exits: Sequence[NodeExit]) -> list[Path]:
    """The bag directories the recorder attempts wrote (the first is ``run_dir``)."""
    attempts = sorted({e.attempt for e in exits if e.name == "recorder"} | {0})
    bags = [run_dir if a == 0 else run_dir.with_name(f"{run_dir.name}_r{a}") for a in attempts]
    return [b for b in bags if b.is_dir()]


def repair_bags(bags: Sequence[Path]) -> list[str]:
    """Recover bags without metadata.yaml (recorder killed); return what was done."""
    notes = []
    for b in bags:
        if (b / "metadata.yaml").is_file():
            continue
        try:
            from bb2_tools.bagfile import recover

            rep = recover(b)
            notes.append(f"recovered {b}: {rep.message_count} messages ({rep.problem or 'ok'})")
        except Exception as exc:  # report, never hide the run's own result
            notes.append(f"could not recover {b}: {exc}")
    return notes


def _parse(argv: Sequence[str]) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="bb2-launch", description=__doc__.split("\n\n")[0],
                                epilog=__doc__.split("\n\n", 1)[1],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("mission", type=Path, nargs="?", help="mission YAML (as for `bb2-sim mission`)")
    p.add_argument("--mode", choices=("lockstep", "realtime"), default="lockstep",
                   help="simulator time mode (default lockstep)")
    p.add_argument("--params", type=Path, default=None, help="ROS 2 params file passed to every node")
    p.add_argument("--bag-dir", type=Path, default=Path("bags"), help="where run directories go (default bags/)")
    p.add_argument("--out", type=Path, default=None,
                   help="run (bag) directory; default <bag-dir>/<mission>_<YYYYmmdd_HHMMSS>")
    p.add_argument("--no-record", action="store_true", help="do not start the recorder")
    p.add_argument("--domain-id", type=int, default=None,
                   help="ROS_DOMAIN_ID (0..232); default a random free one in 1..101")
    p.add_argument("--restart", action="append", default=[], metavar="NODE=POLICY[,...]",
                   help="per-node policy when a node dies: stop (default), restart[:N], ignore; "
                        "NODE may be 'all'")
    p.add_argument("--max-restarts", type=int, default=DEFAULT_MAX_RESTARTS,
                   help=f"default N for 'restart' (default {DEFAULT_MAX_RESTARTS})")
    p.add_argument("--end-at", choices=END_AT, default="either",
                   help="the mission is over when the simulator reports the end of the mission duration, "
                        "when the progress reaches 1 (path flown), or either (default)")
    p.add_argument("--timeout", type=float, default=None, help="wall-clock limit in seconds (exit 1)")
    p.add_argument("--ready-timeout", type=float, default=60.0,
                   help="seconds to wait for the recorder's subscriptions and (lockstep) the simulator's "
                        "publishers (default 60)")
    p.add_argument("--runner", choices=RUNNERS, default="auto", help="how nodes are started (default auto)")
    p.add_argument("--echo", action="store_true", help="also print every node's output, prefixed")
    p.add_argument("--install-ros-ws", action="store_true",
                   help="install the bb2_ros_ws packaging into this venv (lib/<pkg>/<exe>, ament index) "
                        "and exit")
    return p.parse_args(argv)


def main(argv: Sequence[str] | None = None) -> int:
    """Console script ``bb2-launch``."""
    args = _parse(list(sys.argv[1:] if argv is None else argv))
    if args.install_ros_ws:
        ws = Path(__file__).resolve().parents[1] / "bb2_ros_ws" / "install_into_venv.py"
        if not ws.is_file():
            print(f"bb2-launch: error: {ws} not found (run from a source checkout)", file=sys.stderr)
            return 2
        return subprocess.call([sys.executable, str(ws)])
    try:
        if args.mission is None:
            raise LaunchError("a mission file is required")
        if args.domain_id is not None and not 0 <= args.domain_id <= 232:
            raise LaunchError(f"--domain-id must be in 0..232, got {args.domain_id}")
        if args.timeout is not None and args.timeout <= 0:
            raise LaunchError("--timeout must be > 0")
        policies = parse_restart_policies(args.restart, [n.name for n in GRAPH_NODES], args.max_restarts)
        mission = args.mission.resolve()
        params = args.params.resolve() if args.params else None
        if params is not None:
            check_params_file(params)
        check_mission(mission)
        run_dir = (args.out or args.bag_dir / f"{mission.stem}_{time.strftime('%Y%m%d_%H%M%S')}").resolve()
        if run_dir.exists() and any(run_dir.iterdir()):
            raise LaunchError(f"run directory {run_dir} exists and is not empty")
        for n in GRAPH_NODES:  # resolve runners early: one clear error, before anything starts
            node_command(n, args.runner)
    except LaunchError as exc:
        print(f"bb2-launch: error: {exc}", file=sys.stderr)
        return 2

    os.environ.setdefault("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")
    os.environ.setdefault("AMENT_PREFIX_PATH", sys.prefix)
    try:
        monitor = (GraphMonitor(args.domain_id, end_at=args.end_at) if args.domain_id is not None
                   else free_domain_id(end_at=args.end_at))
    except LaunchError as exc:
        print(f"bb2-launch: error: {exc}", file=sys.stderr)
        return 2
    log_dir = run_dir / "logs"
    env = dict(os.environ)
    env["ROS_DOMAIN_ID"] = str(monitor.domain_id)
    env["ROS_LOG_DIR"] = str(log_dir / "ros")
    specs = graph_specs(mission, run_dir, mode=args.mode, params=params, record=not args.no_record,
                        runner=args.runner, policies=policies, monitor=monitor)
    echo = (lambda name, line: print(f"[{name}] {line}", file=sys.stderr, flush=True)) if args.echo else None
    print(f"[bb2-launch] mission {mission} | mode {args.mode} | ROS_DOMAIN_ID={monitor.domain_id} | "
          f"run {run_dir}", file=sys.stderr, flush=True)
    sup = Supervisor(specs, log_dir, env=env, echo=echo)
    try:
        result = run_graph(sup, monitor, first=[s.name for s in specs if s.ready is not None],
                           ready_timeout_s=args.ready_timeout, timeout_s=args.timeout)
    finally:
        sup.stop(hurry=True)
        monitor.close()
    bags = recorder_bags(run_dir, result.exits) if not args.no_record else []
    for note in repair_bags(bags):
        print(f"[bb2-launch] {note}", file=sys.stderr)
    rtf = f"{result.rtf_overall:.1f}x" if result.rtf_overall else "--"
    t = f"{result.sim_time_s:.2f} s" if result.sim_time_s is not None else "--"
    print(f"[bb2-launch] {result.reason}: sim time {t}, RTF {rtf}, wall {result.wall_s:.1f} s, "
          f"exit code {result.exit_code}", file=sys.stderr)
    for b in bags:
        print(f"[bb2-launch] bag:   {b}", file=sys.stderr)
    print(f"[bb2-launch] logs:  {log_dir}", file=sys.stderr)
    if bags:
        print(f"[bb2-launch] plots: bb2-analyze {bags[0]}", file=sys.stderr)
    return result.exit_code


if __name__ == "__main__":
    sys.exit(main())
