"""bb2-launch: fly a mission through the BB2 ROS 2 node graph, one process per node (or composed).

The launcher starts every node at once (their imports and mission builds overlap): in lockstep the
simulator publishes its first state only once the recorder reads every topic it publishes, then waits
for the controllers; in real time it starts last, once the recorder is subscribed to every contract
topic, and starts its clock once the controllers answer its first state (``wait_for_commands``).  Each node
runs in its own process and process group, on an isolated ``ROS_DOMAIN_ID`` (a random free one unless
``--domain-id``).  A small rclpy monitor node inside the launcher shows sim time (``/clock``), mission progress
(``/bb2/mission/progress``) and the real-time factor on one line.

It stops the graph cleanly when the mission ends (``--end-at``: the progress reaches 1, or the
simulator reports the end of the mission duration on ``/bb2/status`` or exits with code 0), when
the simulator reports that it stopped (diverged), on Ctrl-C (SIGINT) or SIGTERM, after
``--timeout``, or when a node dies.  Stopping sends SIGINT to the process groups, then SIGTERM, then SIGKILL
after grace periods (at the end of the mission, once the recorder holds the last step: :func:`caught_up`); the
recorder is stopped last and gets the longest grace so it finishes its
bag.  A node that dies is reported with its exit code or signal and its last log lines, and is
handled by its restart policy (``--restart NODE=stop|restart[:N]|ignore``; default ``stop``).

Composition (``--compose``, ``--group NODE,NODE``): nodes run in one process and one executor
(:mod:`bb2_ros.container`), each with the parameters, remaps and topics it has alone; the recorder always runs in a
process of its own.  A composed process is started, restarted (``--restart container=...``; refused while it holds
the simulator), stopped and reported by its name: ``container`` for all the composable nodes, else its nodes
joined by ``+`` (``path_following+l1_autopilot+mixer``).

Live view (``--foxglove [PORT]``): :mod:`bb2_tools.foxglove_live` beside the graph, a Foxglove WebSocket server on
127.0.0.1:PORT (default 8765) serving every topic; restarted if it dies (a viewer never stops the mission); a
taken port is refused before anything starts.

A boat of several (``--namespace NAME``): every node in /NAME with a clock of its own -- topics /NAME/bb2/... and
/NAME/clock, frames NAME/base_link, NAME/odom under map -- so launches of several boats on one ``--domain-id`` make
one graph without crosstalk, each boat in lockstep with its own controllers (its run equals the same mission flown
alone); its recorder writes the boat's topics under the contract's names (``/bb2/odom``: the bag analyses as a
single boat's, its frames prefixed) and leaves ``/diagnostics`` (every boat's) out; the run directory ends in
``_NAME``.

Your node in place of ours (``--without NODE[,NODE...]``: ``planner``, ``path_following``, ``l1_autopilot``,
``mixer``): those nodes are not started; yours, started on the run's ``--domain-id``, answers in their place on the
contract's topics.  Until it does, the simulator steps on its failsafe and the status line says ``FAILSAFE``.

A fleet file (``bb2-launch FLEET.yaml``, :mod:`bb2_mission.fleet`): every boat flown as ``--namespace BOAT`` on one
domain, one recorder for all boats into one bag (:mod:`bb2_tools.fleet_launcher`, dispatched by the command,
:mod:`bb2_tools.launch_cli`; ``--external-recorder`` is how each boat's launch is told its recorder runs elsewhere).

Every child's stdout and stderr go to ``<run>/logs/<node>.log`` (and a ring buffer of the last
lines).  ``<run>`` is the bag directory ``<bag-dir>/<mission>_<YYYYmmdd_HHMMSS>[_NAME]/`` (metadata.yaml
and the .mcap beside ``logs/``).

How a node is started (``--runner``): ``ros2`` (``ros2 run <pkg> <exe>``, when the ROS 2 CLI is
on PATH and the package is in the ament index), ``lib`` (``<prefix>/lib/<pkg>/<exe>`` from the
ament index, exactly what ``ros2 run`` executes; see ``bb2_ros_ws/install_into_venv.py``),
``python`` (the package entry point in this interpreter); ``auto`` picks the first that works.

Exit codes: 0 mission complete; 1 a node failed, the timeout passed, or the recorder had to be
killed; 2 bad input; 130 interrupted (Ctrl-C / SIGTERM).

The process supervision (:mod:`bb2_tools.supervisor`) and the monitor node (:mod:`bb2_tools.graph_monitor`)
are usable on their own, from Python and tests.
"""
from __future__ import annotations

import argparse
import math
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

from bb2_sim.names import did_you_mean
from bb2_sim.outputs import OutputError, claim_run_dir, run_cli

from bb2_ros.container import NODE_CLASSES
from bb2_msgs_py.contract import RECORDER_ACK_WINDOW
from bb2_ros.node_common import CALLBACK_PRIORITY_REALTIME, PUBLISHED_DIR_ENV, REALTIME_CONTROLLERS
from bb2_tools.bagfile import PUBLICATION_COUNTS_FILE, RECORDER_STATUS_NAME, status_source
from bb2_tools.dds_shm import clean_after_kill
from bb2_tools.graph_monitor import END_AT, GraphMonitor, domain_monitor, format_status
from bb2_tools.supervisor import (DEFAULT_MAX_RESTARTS, LaunchError, NodeExit, ProcessSpec, RestartPolicy,
                                  Supervisor, parse_restart_policies, uses_default_max)

RECORDER_NODE_NAME = "recorder"  # bb2_tools.recorder.NODE_NAME


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
    # as the console scripts start it (bb2_ros.entry: a SIGINT while it imports ends it quietly)
    code = (f"import sys; sys.argv[0] = {node.executable!r}; from bb2_ros.entry import run; "
            f"sys.exit(run({node.entry_point!r}))")
    return [sys.executable, "-c", code]


# ============================================================================ the run loop
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


RECORDER_CATCH_UP_S = 30.0
"""Wall seconds the launcher waits, at the end of a mission, for a recorder behind the graph to hold the last
step before it stops the nodes (a writer that exits takes its undelivered samples with it)."""


def caught_up(monitor: GraphMonitor, say, *, interrupted=lambda: False, limit_s: float = RECORDER_CATCH_UP_S) -> bool:
    """Wait until the recorder acknowledges the graph's last step (``/bb2/recorder/ack`` up to the last ``/clock``):
    in real time nothing holds the graph back for a recorder starved of CPU, which may be seconds behind when the
    mission ends; stopping the nodes then would lose what it has not received yet.  Says how far behind it was
    and, after ``limit_s`` (or an interruption), that the tail may be missing; returns whether it caught up."""
    target = monitor.sim_time_s
    if target is None:
        return True
    t0 = time.monotonic()
    said = False
    while (-math.inf if monitor.recorder_ack_s is None else monitor.recorder_ack_s) < target - 1e-9:
        waited = time.monotonic() - t0
        if waited > limit_s or interrupted():
            ack = monitor.recorder_ack_s
            say(f"[bb2-launch] warning: the recorder still holds steps only to "
                f"{'--' if ack is None else f'{ack:.2f}'} s of the last {target:.2f} s after {waited:.0f} s: "
                "stopping anyway (the bag's gaps say what is missing)")
            return False
        if not said and waited > 0.5:
            ack = monitor.recorder_ack_s
            say(f"[bb2-launch] waiting for the recorder to record the last steps "
                f"({'--' if ack is None else f'{ack:.2f}'} s of {target:.2f} s)")
            said = True
        time.sleep(0.05)
    if said:
        say(f"[bb2-launch] the recorder holds every step after {time.monotonic() - t0:.1f} s")
    return True


def run_graph(sup: Supervisor, monitor: GraphMonitor | None, *, first: Sequence[str] = (),
              ready_timeout_s: float = 30.0, timeout_s: float | None = None, status_period_s: float = 5.0,
              out=sys.stderr, handle_signals: bool = True, stall_timeout_s: float | None = None,
              recorder_outside: bool = False) -> RunResult:
    """Start the ``early`` specs at once, then ``first`` one by one (waiting for readiness), then the rest;
    supervise until the mission ends, a node fails, a signal arrives, ``timeout_s`` passes or (with
    ``stall_timeout_s``) the sim time has not advanced for that many wall seconds since it last moved, or has
    not started ``ready_timeout_s + stall_timeout_s`` after every process was started (the time its nodes have
    to come up, then the stall timeout), or the simulator has stepped on its failsafe for that many wall seconds
    (every controller silent: reported as stalled, exit 1); stop everything; return the result.
    ``recorder_outside``: the boat is recorded by a recorder of another process (a fleet's), whose
    acknowledgement the end waits for as for its own (:func:`caught_up`)."""
    flag = _StopFlag()
    previous = {}
    if handle_signals and threading.current_thread() is threading.main_thread():
        previous = {s: signal.signal(s, flag) for s in (signal.SIGINT, signal.SIGTERM)}
    tty = hasattr(out, "isatty") and out.isatty()
    t0 = time.monotonic()
    last_status = 0.0
    reason, code = "", 0
    last_sim: tuple[float | None, float] = (None, t0)  # (sim time, wall time it was first seen)
    failsafe_since: float | None = None  # wall time the simulator's status first said FAILSAFE, this time

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
        all_started = time.monotonic()  # a graph whose sim time never starts is stalled from here
        frozen: dict[str, float] = {}  # node -> wall time it was first seen stopped
        next_frozen_check = 0.0
        while not reason:
            report(sup.poll())
            now = time.monotonic()
            if now >= next_frozen_check:  # a frozen node is said, and when it runs again
                next_frozen_check = now + FROZEN_CHECK_S
                stopped = sup.stopped()
                for n in sorted(stopped - set(frozen)):
                    frozen[n] = now
                    say(f"[bb2-launch] node '{n}' is stopped (process state T: SIGSTOP or Ctrl-Z): alive, not working")
                for n in sorted(set(frozen) - stopped):
                    say(f"[bb2-launch] node '{n}' runs again after {now - frozen.pop(n):.1f} s stopped")
            if sup.failure:
                # a node that exits 2 before the first step refused its input (a parameter, its mission) or its
                # environment (a blocked domain): the launch's bad input, exit 2 as the launcher's own checks
                refused = sup.failure.returncode == 2 and (monitor is None or not monitor.stepping_started)
                reason, code = f"node '{sup.failure.name}' failed ({sup.failure.cause})", 2 if refused else 1
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
            elif stall_timeout_s and monitor is not None and not monitor.stepping_started:
                # no step yet: the simulator still waiting for a reader gone, or at the start-up handshake of t0 while
                # the controllers build their missions (tens of seconds on a loaded machine): its nodes had
                # ready_timeout_s to come up
                if now - all_started > ready_timeout_s + stall_timeout_s:
                    reason, code = (f"stalled: the sim time has not started {now - all_started:.0f} s of wall "
                                    f"time after every node was started (--stall-timeout {stall_timeout_s:g})"), 1
            elif stall_timeout_s and monitor is not None:
                if monitor.sim_time_s != last_sim[0]:
                    last_sim = (monitor.sim_time_s, now)
                elif now - last_sim[1] > stall_timeout_s:
                    reason, code = (f"stalled: sim time stuck at {monitor.sim_time_s:.2f} s for "
                                    f"{now - last_sim[1]:.0f} s of wall time (--stall-timeout {stall_timeout_s:g})"), 1
            if monitor is not None:
                failsafe_since = None if monitor.failsafe is None else failsafe_since or now
            if (not reason and stall_timeout_s and failsafe_since is not None
                    and now - failsafe_since > stall_timeout_s + FAILSAFE_BACKSTOP_S):
                # the run goes on, but as no run: in lockstep one step a second (lockstep_timeout_s) on held or
                # neutral planes, in real time the boat flying on its failsafe alone
                reason, code = (f"{FAILSAFE_STALL} for {now - failsafe_since:.0f} s of wall time "
                                f"({monitor.failsafe}; --stall-timeout {stall_timeout_s:g})"), 1
            if monitor is not None and (reason or tty or now - last_status >= status_period_s):
                # a status line every status_period_s, and always one when the run ends (a graph that flew within
                # its start-up, before the first period, still shows where it stopped and how many nodes ran)
                line = format_status(monitor.sim_time_s, monitor.progress, monitor.rtf(),
                                     sum(sup.specs[n].nodes for n in sup.running()),
                                     sum(sup.specs[n].nodes for n in sup.order), now - t0, monitor.failsafe)
                print("\r\033[K" + line if tty else line, end="" if tty else "\n", file=out, flush=True)
                last_status = now
            if reason:
                break
            time.sleep(0.1)
        if tty:
            print(file=out)
        if reason == "mission complete" and ("recorder" in sup.running() or recorder_outside) and monitor is not None:
            caught_up(monitor, say, interrupted=lambda: bool(flag.count))
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
    from bb2_sim.yaml_files import load as load_yaml

    if not path.is_file():
        raise LaunchError(f"{what} {path} does not exist")
    try:
        data = load_yaml(path.read_text(encoding="utf-8"))
    except yaml.YAMLError as exc:
        raise LaunchError(f"{what} {path} is not valid YAML: {exc}") from None
    except UnicodeDecodeError as exc:
        raise LaunchError(f"{what} {path} is not UTF-8 text (byte {exc.start})") from None
    except OSError as exc:
        raise LaunchError(f"{what} {path}: cannot read it ({exc.strerror or exc})") from None
    if not isinstance(data, dict):
        raise LaunchError(f"{what} {path} must be a YAML mapping, got {type(data).__name__}")
    return data


def check_mission(path: Path) -> str:
    """Validate the mission file with ``bb2_mission.load_mission`` (when available); returns '' or a warning to say
    before the flight (``bb2_mission.mission_warnings``: a mission faster than its ROM sub-steps fly, a sea steeper
    than any deep-water wave)."""
    _load_yaml_mapping(path, "mission file")
    try:
        from bb2_mission import load_mission
    except ImportError:
        return ""
    try:
        from bb2_mission.components import check_initial_state, mission_warnings

        m = load_mission(path)
        check_initial_state(m)   # above the surface / inside the sea floor: refused up front
    except (ValueError, OSError) as exc:
        msg = str(exc)
        raise LaunchError(msg if str(path) in msg else f"mission {path}: {msg}") from None
    try:
        return "; ".join(mission_warnings(m))
    except Exception:  # noqa: BLE001 -- a warning never stops a launch (the simulator node builds the same)
        return ""


GRAPH_PARAMS_FILE = Path(__file__).resolve().parents[1] / "config" / "bb2_graph.yaml"
"""Every parameter the graph's nodes declare, with its default (``tests/ros/test_params_file.py`` keeps it so)."""
ROS_OWN_PARAMETERS = frozenset({"use_sim_time", "start_type_description_service", "qos_overrides"})
"""Parameters rclpy declares on every node (``qos_overrides.<topic>...`` as a prefix)."""


def _parameter_names(params: Mapping, prefix: str = "") -> list[str]:
    """The dotted names of a ``ros__parameters`` mapping (nested mappings are dotted, as rcl reads them)."""
    out: list[str] = []
    for k, v in params.items():
        name = f"{prefix}{k}"
        out += _parameter_names(v, name + ".") if isinstance(v, Mapping) else [name]
    return out


def _known_parameters(graph_params_file: Path = GRAPH_PARAMS_FILE) -> dict[str, frozenset[str]] | None:
    """Node name -> the parameters it may be given (``/**``: any node's), or None when the graph's params file
    (``graph_params_file``, every declared parameter) is not there (an installed copy without its source)."""
    if not graph_params_file.is_file():
        return None
    from bb2_sim.yaml_files import load as load_yaml
    from bb2_tools.recorder import PARAMETERS as RECORDER_PARAMETERS

    doc = load_yaml(graph_params_file.read_text(encoding="utf-8"))
    every = frozenset(_parameter_names(doc["/**"]["ros__parameters"]))
    graph = {n.name: every for n in GRAPH_NODES if n.name != RECORDER_NODE_NAME}
    graph[RECORDER_NODE_NAME] = frozenset(RECORDER_PARAMETERS)
    graph["/**"] = every | graph[RECORDER_NODE_NAME]
    return graph


def check_params_file(path: Path, graph_params_file: Path = GRAPH_PARAMS_FILE) -> None:
    """A ROS 2 params file: a mapping of node names (or ``/**``) to ``{ros__parameters: {...}}``, whose node names
    are the graph's and whose parameters some node declares: ROS ignores a parameter no node declares, so a typo
    (``rate_hzz``, a node ``simulatr``) flew the mission on the defaults without a word.  ``graph_params_file``:
    the graph's own params file, which lists every declared parameter (the launch files pass the installed
    share/bb2_bringup/config/bb2_graph.yaml)."""
    data = _load_yaml_mapping(path, "params file")
    for node, body in data.items():
        if not isinstance(body, dict) or not isinstance(body.get("ros__parameters"), dict):
            raise LaunchError(f"params file {path}: entry {node!r} needs a 'ros__parameters' mapping")
    known = _known_parameters(graph_params_file)
    if known is None:
        return
    for node, body in data.items():
        key = str(node)
        name = "/**" if "*" in key.rsplit("/", 1)[-1] else key.rsplit("/", 1)[-1]   # '/boat1/simulator' -> simulator
        if name not in known:
            if name in (CONTAINER.name, FOXGLOVE.name):
                continue
            raise LaunchError(f"params file {path}: {key!r} is no node of the graph" + did_you_mean(name, known)
                              + f"; nodes: {', '.join(n for n in known if n != '/**')}, or '/**'")
        for param in _parameter_names(body["ros__parameters"]):
            if param in known[name] or param.split(".", 1)[0] in ROS_OWN_PARAMETERS:
                continue
            raise LaunchError(f"params file {path}: {key}: parameter {param!r} is declared by "
                              + ("no node of the graph" if name == "/**" else f"no {name}")
                              + did_you_mean(param, known[name])
                              + "; ROS would ignore it")


def params_overridden(path: Path, given: Mapping[str, Mapping[str, tuple[Any, str, str]]],
                      graph_params_file: Path = GRAPH_PARAMS_FILE) -> list[str]:
    """The parameters that the params file ``path`` sets and the launcher sets otherwise (``given``: node name,
    ``*`` for every node -> parameter -> (the launcher's value, the option or argument that sets it, how the user
    chooses it: '' when the launcher alone does)).

    * Under ``/**``: the launcher's value comes after the file's and wins, without a word from ROS: one warning
      each, unless the file's value is the graph's default (a copy of the shipped file).
    * Under a node's own name (``simulator:``, ``/boat1/simulator:``, ``/**/simulator:``): rcl applies a node's
      own entry after every ``/**`` value, the launcher's ``-p`` included, so that node alone would take the
      file's value (a simulator in real time beside controllers in lockstep, or flying another mission):
      :class:`LaunchError` naming the way to choose it."""
    data = _load_yaml_mapping(path, "params file")
    defaults: Mapping[str, Any] = {}
    if graph_params_file.is_file():
        from bb2_sim.yaml_files import load as load_yaml

        defaults = load_yaml(graph_params_file.read_text(encoding="utf-8"))["/**"]["ros__parameters"]
    out: list[str] = []
    for key, body in data.items():
        name = "/**" if "*" in str(key).rsplit("/", 1)[-1] else str(key).rsplit("/", 1)[-1]
        if name == "/**":
            set_here = {p: v for node_values in given.values() for p, v in node_values.items()}
        else:
            set_here = {**given.get("*", {}), **given.get(name, {})}
        for param, value in body["ros__parameters"].items():
            if param not in set_here or _same_value(param, value, set_here[param][0]):
                continue
            launched, source, choose = set_here[param]
            if name != "/**":
                raise LaunchError(f"params file {path}: {key}: {param} {value!r} conflicts with {source}, which sets "
                                  f"it to {launched!r} for the graph (a node's own entry would win over it for that "
                                  f"node alone): " + (f"choose it with {choose}" if choose else "leave it out")
                                  + " and remove it from the file")
            if not (param in defaults and _same_value(param, value, defaults[param])):
                out.append(f"params file {path}: {key}: {param} {value!r} is overridden by {source}")
    return out


def launcher_parameters(mission: Path, mode: str, arguments: Mapping[str, str] | None = None,
                        stall_timeout_s: float | None = None) -> dict[str, dict[str, tuple[Any, str, str]]]:
    """What the launcher sets for the graph that a params file may also set (:func:`params_overridden`):
    ``bb2-launch``'s, or with ``arguments`` (the launch files' arguments, as given) theirs; ``stall_timeout_s``
    the simulator's (None: not set)."""
    if arguments is None:
        by, said = "bb2-launch", {"mission_file": (f"the mission bb2-launch flies ({mission})", "the MISSION argument"),
                                  "time_mode": (f"--mode {mode}", "--mode"),
                                  "stall_timeout_s": (f"--stall-timeout {stall_timeout_s:g}"
                                                      if stall_timeout_s is not None else "", "--stall-timeout")}
    else:
        by = "the launch file"
        said = {"mission_file": (f"launch argument mission:={arguments.get('mission', '')}", "mission:="),
                "time_mode": (f"launch argument time_mode:={arguments['time_mode']}", "time_mode:="),
                "stall_timeout_s": (f"launch argument stall_timeout:={arguments['stall_timeout']}", "stall_timeout:=")}
    sim_time = (True, f"{by} (the graph runs on the simulator's clock)", "")
    simulator = {"time_mode": (mode, *said["time_mode"]),
                 "use_sim_time": (False, f"{by} (the simulator is the graph's clock)", "")}
    if stall_timeout_s is not None:
        simulator["stall_timeout_s"] = (float(stall_timeout_s), *said["stall_timeout_s"])
    return {"*": {"mission_file": (str(mission), *said["mission_file"])}, "simulator": simulator,
            **{n.name: {"use_sim_time": sim_time} for n in GRAPH_NODES if n.name not in ("simulator", "recorder")}}


def _same_value(param: str, a: Any, b: Any) -> bool:
    """Equal as ROS parameters: numbers by value, a mission file by the file it names, the rest by text."""
    numbers = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in (a, b))
    if numbers:
        return float(a) == float(b)
    if param == "mission_file" and str(a).strip() and str(b).strip():
        return Path(str(a)).expanduser().resolve() == Path(str(b)).expanduser().resolve()
    return str(a) == str(b)


BACKGROUND_NICE = 10
BACKGROUND_NODES = ("recorder", "planner")
"""Nodes off the control loop (state -> commands -> step), started with ``nice +BACKGROUND_NICE``: on a
machine with fewer cores than busy processes they take the CPU the loop leaves (the recorder's deep queues
absorb the delay; the planner only publishes the path), not the loop's."""


CONTAINER = GraphNode("container", "bb2_ros", "container", "bb2_ros.container:main")
"""The process that runs several nodes composed (:mod:`bb2_ros.container`)."""
FOXGLOVE = GraphNode("foxglove_bridge", "bb2_tools", "foxglove_bridge", "bb2_tools.foxglove_live:main")
"""The live Foxglove WebSocket server (``--foxglove``): every graph topic, as :mod:`bb2_tools.foxglove_live`."""
COMPOSABLE = tuple(n.name for n in GRAPH_NODES if n.name in NODE_CLASSES)
"""The nodes ``--compose`` may put into one process (the container's, in start order; the recorder waits on its own
wait set: a process of its own)."""


def compose_groups(groups: Sequence[str] | None, option: str = "--group") -> list[tuple[str, ...]]:
    """The process groups of a composed launch: ``groups`` are comma-separated node names (``--group``), each one
    process; ``[]`` (``--compose`` alone) puts every composable node into one.  Nodes in no group run alone.
    Unknown, repeated or non-composable names are a :class:`LaunchError` naming ``option`` (the launch files':
    ``launch argument group``)."""
    if groups is None:
        return []
    if not groups:
        return [COMPOSABLE]
    out: list[tuple[str, ...]] = []
    seen: set[str] = set()
    for g in groups:
        names = tuple(n.strip() for n in g.split(",") if n.strip())
        if not names:
            raise LaunchError(f"{option} {g!r}: no node named")
        for n in names:
            if n == RECORDER_NODE_NAME:
                raise LaunchError(f"{option}: the recorder cannot be composed (it waits on its own wait set); it "
                                  "runs in a process of its own")
            if n not in COMPOSABLE:
                raise LaunchError(f"{option}: unknown node {n!r}" + did_you_mean(n, COMPOSABLE)
                                  + f"; composable: {', '.join(COMPOSABLE)}")
            if n in seen:
                raise LaunchError(f"{option}: node {n!r} is in two groups")
            seen.add(n)
        out.append(tuple(sorted(names, key=COMPOSABLE.index)))
    return out


REPLACEABLE = ("planner", "path_following", "l1_autopilot", "mixer")
"""The nodes a user may leave out, to run a node of their own in its place (``without:=`` of the launch files): the
contract's topics are its interface (``bb2_msgs_py.contract``); in lockstep the simulator waits for its answer to
each step (the first for up to ``startup_timeout_s``), in real time for its first command (``wait_for_commands``)."""


def check_without(value: str | Sequence[str], option: str = "without") -> tuple[str, ...]:
    """The node names of ``value`` (comma-separated, or a sequence) checked against :data:`REPLACEABLE`:
    :class:`LaunchError` naming an unknown one (with the likely one), one named twice, the simulator (the boat
    itself) or the recorder (not recording is ``record:=false`` / ``--no-record``)."""
    names = [n.strip() for n in (value.split(",") if isinstance(value, str) else value) if n.strip()]
    for n in names:
        if n == "simulator":
            raise LaunchError(f"{option}: the simulator is the boat itself and cannot be left out")
        if n == RECORDER_NODE_NAME:
            raise LaunchError(f"{option}: leave the recorder out with "
                              + ("--no-record" if option.startswith("--") else "record:=false"))
        if n not in REPLACEABLE:
            raise LaunchError(f"{option}: unknown node {n!r}" + did_you_mean(n, REPLACEABLE)
                              + f"; nodes that may be left out: {', '.join(REPLACEABLE)}")
        if names.count(n) > 1:
            raise LaunchError(f"{option}: node {n!r} is named twice")
    return tuple(sorted(names, key=REPLACEABLE.index))


def check_stall_timeout(value: str | float, option: str = "--stall-timeout") -> float:
    """The stall timeout of ``value`` (wall s, a number >= 0 and finite; 0 = no stall check): :class:`LaunchError`
    naming ``option`` otherwise."""
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise LaunchError(f"{option} must be a number of wall seconds (0 = never), got {value!r}") from None
    if not (out >= 0 and math.isfinite(out)):
        raise LaunchError(f"{option} must be >= 0 and finite, got {value}")
    return out


def process_name(group: Sequence[str]) -> str:
    """The name of the process that runs ``group`` (its log file, its restart policy, its reports): the node's
    own for a node alone, ``container`` for every composable node, else the nodes joined by ``+``."""
    if len(group) == 1:
        return group[0]
    return CONTAINER.name if tuple(group) == COMPOSABLE else "+".join(group)


def process_of(node: str, groups: Sequence[Sequence[str]]) -> str:
    """The name of the process that runs ``node`` with these groups (:func:`process_name` of its group, or its own
    when it is in none)."""
    return process_name(next((g for g in groups if node in g), (node,)))


def process_names(groups: Sequence[Sequence[str]]) -> list[str]:
    """Every process of the graph for these groups (the recorder included), in the node table's order."""
    grouped = {n for g in groups for n in g}
    names = [process_name(g) for g in groups]
    return [n.name for n in GRAPH_NODES if n.name not in grouped] + names


def clean_after_killed(exits: list[NodeExit], say: Callable[[str], None]) -> None:
    """A node process that ended by a signal (killed: by hand, a crash, the stop's SIGKILL) left its Fast DDS
    shared-memory files in /dev/shm (memory); Fast DDS's own tool removes those whose owner is gone
    (:mod:`bb2_tools.dds_shm`), said when it removed any."""
    killed = sorted({ev.name for ev in exits if ev.returncode < 0})
    if killed and (line := clean_after_kill(", ".join(killed))):
        say(line)


def graph_specs(mission: Path, run_dir: Path, *, mode: str = "lockstep", params: Path | None = None,
                record: bool = True, runner: str = "auto",
                policies: Mapping[str, RestartPolicy] | None = None,
                monitor: GraphMonitor | None = None,
                groups: Sequence[Sequence[str]] = (), foxglove_port: int | None = None,
                namespace: str = "", own_recorder: bool = True, without: Sequence[str] = (),
                stall_timeout_s: float | None = None) -> list[ProcessSpec]:
    """The process specs of the BB2 graph for one mission, in start order.

    The planner and the controllers, and in lockstep the simulator, are ``early``: :func:`run_graph`
    starts them at once (each takes a second or two to import and build its part of the mission, which
    then overlap).  The recorder has a ``ready`` probe (subscribed to every contract topic); in lockstep
    the simulator, started with ``wait_for_readers``, publishes its first state only once every topic
    it publishes has a reader (the recorder), so the bag misses nothing, and then waits for the
    controllers (re-sending the state until they answer).  Without a recorder the simulator starts at
    once.  In real time the simulator starts last, once the recorder is ready (it steps on the wall
    clock once the controllers answer its first state: ``wait_for_commands``).  ``monitor`` gives the recorder
    its readiness probe.  ``groups`` (:func:`compose_groups`): nodes composed into one process each
    (:mod:`bb2_ros.container`, every node with the arguments it has alone); such a process starts, finishes
    the graph, restarts and is reported as the nodes it holds would be.  ``foxglove_port``: the live Foxglove
    server on that port (:data:`FOXGLOVE`, off the control loop, started with the others).  ``namespace``: every
    node (the recorder and the Foxglove server too) in /NAMESPACE with a clock of its own (:func:`namespace_args`):
    the boat's topics are /NAMESPACE/bb2/... and /NAMESPACE/clock, so boats of several launches on one
    ``--domain-id`` fly side by side without crosstalk.  ``record`` without ``own_recorder``: the boat is recorded by
    a recorder started elsewhere (a fleet's, :mod:`bb2_tools.fleet_launcher`), which the simulator waits for as for
    its own (its readers, its acknowledgements on the boat's ``bb2/recorder/ack``).  ``without``: nodes not started
    (:func:`check_without`), a user's own in their place.  ``stall_timeout_s``: the simulator's own, which stops
    the run as stalled after stepping on its failsafe that long (its status says why, in the bag; 0 = never); None:
    not set (a params file's, else never).
    """
    from bb2_msgs_py.contract import boat_topic

    if mode not in ("lockstep", "realtime"):
        raise LaunchError(f"--mode must be lockstep or realtime, got {mode!r}")
    policies = dict(policies or {})
    ns = check_namespace(namespace)
    ns_args = namespace_args(ns)

    def node_args(name: str, attempt: int) -> list[str]:
        """The ROS arguments of node ``name`` (``attempt`` > 0: a restart, which rejoins the run)."""
        # The params file goes first: for '/**' keys the last source wins, so the launcher's own -p values
        # (mission, time mode, sim time) must come after it.
        ros = ["--ros-args"] + (["--params-file", str(params)] if params is not None else [])
        ros += ["-p", f"mission_file:={mission}"]
        if name == "simulator":
            ros += ["-p", f"time_mode:={mode}"]
            if stall_timeout_s is not None:  # the run stops as stalled, said by the simulator (status, bag, analysis)
                ros += ["-p", f"stall_timeout_s:={float(stall_timeout_s)}"]
            if record:  # the bag misses nothing from the first step on (its readers matched first)
                ros += ["-p", "wait_for_readers:=true"]
            if mode == "lockstep" and record:  # nor when the recorder stalls: the graph waits for it
                ros += ["-p", f"recorder_ack_window:={RECORDER_ACK_WINDOW}"]
            if mode == "realtime":  # the clock starts once the controllers answer, not on the start-up failsafe;
                # their commands are received at the controllers' priority (not queued behind other processes)
                ros += ["-p", "wait_for_commands:=true", "-p", f"callback_priority:={CALLBACK_PRIORITY_REALTIME}"]
        else:
            ros += ["-p", "use_sim_time:=true"]
            if mode == "realtime" and name in REALTIME_CONTROLLERS:  # their answers do not wait for a core
                ros += ["-p", f"callback_priority:={CALLBACK_PRIORITY_REALTIME}"]
        ros += ns_args
        if attempt > 0 and name in REJOINING:  # a node with state along the run joins the run where it stands
            ros += ["-p", f"{REJOINING[name]}:=true"]
        return ros

    grouped = {n: g for g in groups for n in g}
    specs: list[ProcessSpec] = []
    for node in GRAPH_NODES:
        if node.name in without:
            continue
        if node.name == "recorder":
            if not record or not own_recorder:
                continue
            base = node_command(node, runner)
            topics = [boat_topic(t, ns) for t in recorded_topics(ns)]

            def rec_cmd(attempt: int, base=base) -> list[str]:
                out = run_dir if attempt == 0 else run_dir.with_name(f"{run_dir.name}_r{attempt}")
                return [*base, "--out", str(out), "--overwrite", "--use-sim-time",
                        *(["--ros-args", *ns_args] if ns_args else [])]

            ready = (lambda m=monitor, t=topics: m.subscribed(RECORDER_NODE_NAME, t)) if monitor else None
            specs.append(ProcessSpec(node.name, rec_cmd, policies.get(node.name, RestartPolicy()), stop_stage=1,
                                     sigint_grace_s=30.0, sigterm_grace_s=10.0, ready=ready, nice=BACKGROUND_NICE))
            continue
        group = grouped.get(node.name, (node.name,))
        if node.name != group[-1]:  # a composed process is added with its last node (start order: the simulator's)
            continue
        if len(group) == 1:
            base = node_command(node, runner)

            def command(attempt: int, base=base, name=node.name) -> list[str]:
                return [*base, *node_args(name, attempt)]
        else:
            base = node_command(CONTAINER, runner)

            def command(attempt: int, base=base, group=group) -> list[str]:
                return [*base, *(a for n in group for a in ("--node", n, *node_args(n, attempt), "--"))]
        name = process_name(group)
        specs.append(ProcessSpec(name, command, policies.get(name, RestartPolicy()),
                                 finishes_graph="simulator" in group,
                                 nice=BACKGROUND_NICE if set(group) <= set(BACKGROUND_NODES) else 0,
                                 early="simulator" not in group or mode == "lockstep", nodes=len(group)))
    if foxglove_port is not None:
        base = node_command(FOXGLOVE, runner)
        fox = [*base, "--ros-args", "-p", f"port:={int(foxglove_port)}", "-p", "use_sim_time:=true", *ns_args]
        # a viewer that dies comes back (clients reconnect) and never stops the mission
        specs.insert(0, ProcessSpec(FOXGLOVE.name, lambda attempt, fox=fox: list(fox), RestartPolicy("restart"),
                                    nice=BACKGROUND_NICE, early=True))
    first = [s for s in specs if s.ready is not None]
    return first + [s for s in specs if s.ready is None]


def recorded_topics(namespace: str = "") -> list[str]:
    """The topics the graph's recorder records (:func:`bb2_tools.recorder.default_topics`)."""
    from bb2_tools.recorder import default_topics

    return [t.name for t in default_topics(namespace)]


def check_namespace(namespace: str) -> str:
    """``namespace`` without its slashes (``''`` for the root namespace); a :class:`LaunchError` naming the rule when
    it is not a ROS 2 namespace (:func:`bb2_msgs_py.contract.check_namespace`)."""
    from bb2_msgs_py.contract import ContractError
    from bb2_msgs_py.contract import check_namespace as check

    try:
        return check(namespace, "--namespace")
    except ContractError as exc:
        raise LaunchError(str(exc)) from None


def namespace_args(namespace: str) -> list[str]:
    """The ROS arguments that put a node into /NAMESPACE with the boat's own clock: ``-r __ns:=/boat1
    -r /clock:=/boat1/clock`` (its other topics follow the namespace by themselves: the nodes name them relative
    to it); none for the root namespace."""
    ns = namespace.strip("/")
    return ["-r", f"__ns:=/{ns}", "-r", f"/clock:=/{ns}/clock"] if ns else []


FOXGLOVE_DEFAULT_PORT = 8765


def check_foxglove_port(port: int, option: str = "--foxglove") -> None:
    """Refuse, before anything starts, a Foxglove port out of range or already taken on 127.0.0.1
    (:class:`LaunchError`; ``option``: how the user gave it, named in the message)."""
    import socket

    if not 1 <= port <= 65535:
        raise LaunchError(f"{option} must be a port in 1..65535, got {port}")
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        try:
            s.bind(("127.0.0.1", int(port)))
        except OSError as exc:
            raise LaunchError(f"{option} {port}: the port is not free on 127.0.0.1 ({exc.strerror})") from None


def gap_lines(bag: Path) -> list[str]:
    """What a bag's recording lost, for the summary: its gaps (:func:`bb2_tools.bagfile.bag_gaps`), one line per
    topic (how many lost, the largest gap during the run, those before its first recorded message), or that it
    lost nothing."""
    from bb2_tools.bagfile import BagError, BagReader, bag_gaps, gaps_by_topic

    try:
        gaps = bag_gaps(BagReader(bag))
    except BagError as exc:
        return [f"cannot check {bag} for gaps: {exc}"]
    if gaps is None:
        return [f"{bag}: no publication sequence numbers: gaps cannot be checked"]
    if not gaps:
        return ["recording complete: no gaps (every message published while recording is in the bag)"]
    lines = [f"RECORDING GAPS: {len(gaps)} gap(s), {sum(g.missing for g in gaps)} message(s) lost before "
             f"reaching the recorder (bag metadata custom_data bb2_gaps and {PUBLICATION_COUNTS_FILE}; bb2-analyze "
             "says what they affect):"]
    for topic, gs in sorted(gaps_by_topic(gaps).items(), key=lambda kv: -sum(g.missing for g in kv[1])):
        mid = [g for g in gs if not g.head and not g.unrecorded]
        head = sum(g.missing for g in gs if g.head)
        parts = []
        if mid:
            big = max(mid, key=lambda g: g.missing)
            parts.append(f"{len(mid)} gap(s) during the run (largest {big.missing} at log time {big.after_log_s:.3f} "
                         f"s, published over {big.duration_s:.3f} s of wall time)")
        if head:
            parts.append(f"{head} before its first recorded message")
        parts += [f"{g.missing} published and never recorded, " +
                  ("none recorded at all" if g.after_log_s is None else
                   f"after its last recorded message (log time {g.after_log_s:.3f} s)") +
                  f" (its publishers counted {g.before_sequence})" for g in gs if g.unrecorded]
        text = f"  {topic}: {sum(g.missing for g in gs)} lost, " + ", ".join(parts)
        lines.append(text)
    return lines


def merge_publication_counts(bag: Path, counts_dir: Path, exits: Sequence[NodeExit], topics: Sequence[str],
                             namespace: str = "") -> str:
    """Merge the node processes' publication counts (``counts_dir``, :func:`bb2_ros.node_common.
    write_publication_counts`) over ``topics`` (those the recorder records) into ``bag``'s
    :data:`~bb2_tools.bagfile.PUBLICATION_COUNTS_FILE`, atomically; return a line for the summary when some
    process left no count (killed: losses on its topics may go unseen), else ''.  The processes count resolved
    names (``/boat1/bb2/odom`` in ``namespace`` boat1); the bag and the file name the contract's (``/bb2/odom``)."""
    import json

    records = []
    for f in sorted(counts_dir.glob("*.json")):
        try:
            record = json.loads(f.read_text(encoding="utf-8"))
        except (OSError, ValueError):  # a file a process could not finish: that process is uncounted
            continue
        if record.get("process") != FOXGLOVE.name:  # the viewer publishes nothing of the graph's
            records.append(record)
    from bb2_msgs_py.contract import boat_topic

    wanted = {boat_topic(t, namespace): t for t in topics}
    published: dict[str, int] = {}
    for r in records:
        for resolved, n in dict(r.get("published") or {}).items():
            if (name := wanted.get(resolved)) is not None:
                published[name] = published.get(name, 0) + int(n)
    node_exits = [e for e in exits if e.name not in ("recorder", FOXGLOVE.name)]
    # the recorder counts its own statuses too (they are in its bag), but a node's missing count is a node's
    node_records = [r for r in records if r.get("process") != RECORDER_NODE_NAME]
    uncounted = ([f"{e.name} (attempt {e.attempt}: {e.cause})" for e in node_exits if e.returncode < 0]
                 if len(node_records) < len(node_exits) else [])
    doc = {"published": dict(sorted(published.items())), "processes": records, "uncounted": uncounted}
    if len(node_records) == len(records):  # a killed recorder counted none of its statuses in the bag: left out
        fqn = f"/{namespace}/{RECORDER_NODE_NAME}" if namespace else f"/{RECORDER_NODE_NAME}"
        doc["uncounted_sources"] = [status_source(RECORDER_STATUS_NAME, fqn)]
    tmp = bag / (PUBLICATION_COUNTS_FILE + ".tmp")
    tmp.write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
    os.replace(tmp, bag / PUBLICATION_COUNTS_FILE)
    if len(node_records) < len(node_exits):
        who = ", ".join(uncounted) or f"{len(node_exits) - len(node_records)} process(es)"
        return f"publication counts missing from {who}: a loss at the end of its topics cannot be checked"
    return ""


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


FROZEN_CHECK_S = 0.5
"""How often (wall s) run_graph looks for stopped node processes (:meth:`Supervisor.stopped`)."""

FAILSAFE_STALL = "stalled: the simulator has stepped on its failsafe"
FAILSAFE_BACKSTOP_S = 5.0
"""Wall seconds past ``--stall-timeout`` after which ``run_graph`` stops a graph stepping on its failsafe itself: the
simulator, given the same timeout (:func:`graph_specs`), stops the run first and says why in its status (in the
bag: ``bb2-analyze`` says ``end: stalled``); this is the watch for a simulator that did not."""
DEFAULT_STALL_TIMEOUT_S = 60.0
"""Wall seconds without the sim time advancing after which ``bb2-launch`` stops the graph as stalled (the
simulator's own lockstep timeout steps on held commands after 0.5 s by default, so a graph that lives never
stands still this long), or stepping on the simulator's failsafe (its status says FAILSAFE: no controller answers;
in lockstep one step a second)."""

REJOINING = {"path_following": "rejoin_run"}
"""Nodes with state along the run, and the parameter that makes a restarted one rejoin the run where it stands (the
path following's virtual time from the vehicle's closest path point).  The other controllers rejoin from the current
state by themselves: the L1 autopilot's predictor starts at the first measurement, the mixer is stateless, the
planner re-publishes its latched path."""

NOT_RESTARTABLE = {
    "simulator": "a new simulator starts again at t = 0 from the mission's initial state while the rest of the "
                 "graph stands at the run's time (it cannot rejoin the run); use simulator=stop",
}
"""Nodes whose ``restart`` policy is refused up front, and why (one line each)."""


def check_restart_policies(policies: Mapping[str, RestartPolicy], groups: Sequence[Sequence[str]] = (),
                           option: str = "--restart") -> None:
    """Refuse, before anything starts, a restart policy that could not rejoin the run (:data:`NOT_RESTARTABLE`),
    also for a composed process holding such a node (it restarts as a whole); ``option``: what the error names."""
    for name, why in NOT_RESTARTABLE.items():
        proc = process_of(name, groups)
        pol = policies.get(proc)
        if pol is not None and pol.action == "restart":
            where = "" if proc == name else f" (composed in '{proc}', which restarts as a whole)"
            raise LaunchError(f"{option}: restarting the {name}{where} is refused: {why}")


def parse_args(argv: Sequence[str]) -> argparse.Namespace:
    """The options of ``bb2-launch`` (a mission's and a fleet's)."""
    p = argparse.ArgumentParser(prog="bb2-launch", description=__doc__.split("\n\n")[0],
                                epilog=__doc__.split("\n\n", 1)[1],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("mission", type=Path, nargs="?", help="mission YAML (as for `bb2-sim mission`), or a fleet "
                   "file (bb2_mission.fleet: every boat in its namespace, one recorder for all), or a shipped "
                   "mission's or fleet's name (canyon, canyon_pair)")
    p.add_argument("--mode", choices=("lockstep", "realtime"), default="lockstep",
                   help="simulator time mode (default lockstep)")
    p.add_argument("--params", type=Path, default=None, help="ROS 2 params file passed to every node")
    p.add_argument("--bag-dir", type=Path, default=Path("bags"), help="where run directories go (default bags/)")
    p.add_argument("--out", type=Path, default=None,
                   help="run (bag) directory; default <bag-dir>/<mission>_<YYYYmmdd_HHMMSS>")
    p.add_argument("--no-record", action="store_true", help="do not start the recorder")
    p.add_argument("--external-recorder", action="store_true",
                   help="the boat is recorded by a recorder started elsewhere (a fleet's: bb2-record --boats; "
                        "bb2-launch FLEET.yaml starts one): no recorder here, but the simulator waits for that "
                        "one's readers and acknowledgements as for its own")
    p.add_argument("--namespace", default="", metavar="NAME",
                   help="run the boat's nodes in /NAME with a clock of its own (topics /NAME/bb2/..., /NAME/clock, "
                        "frames NAME/base_link ...): boats of several launches on one --domain-id fly side by side")
    p.add_argument("--domain-id", type=int, default=None,
                   help="ROS_DOMAIN_ID (0..232); default a random free one in 1..101")
    p.add_argument("--restart", action="append", default=[], metavar="NODE=POLICY[,...]",
                   help="per-node policy when a node dies: stop (default), restart[:N], ignore; "
                        "NODE may be 'all'")
    p.add_argument("--max-restarts", type=int, default=DEFAULT_MAX_RESTARTS,
                   help=f"N for a --restart NODE=restart without its own :N (default {DEFAULT_MAX_RESTARTS}; >= 0)")
    p.add_argument("--end-at", choices=END_AT, default="either",
                   help="the mission is over when the simulator reports the end of the mission duration, "
                        "when the progress reaches 1 (path flown), or either (default)")
    p.add_argument("--timeout", type=float, default=None, help="wall-clock limit in seconds (exit 1)")
    p.add_argument("--stall-timeout", type=float, default=DEFAULT_STALL_TIMEOUT_S, metavar="S",
                   help="stop the graph as stalled (exit 1) when the sim time has not advanced for S wall "
                        "seconds, or has not started S seconds after --ready-timeout (the nodes' start-up), or "
                        "the simulator has stepped on its failsafe (no controller answering) for S wall seconds "
                        f"(default {DEFAULT_STALL_TIMEOUT_S:g}; 0 = never)")
    p.add_argument("--status-period", type=float, default=5.0, metavar="S",
                   help="print the graph's status line (sim time, real-time factor, nodes) every S wall seconds "
                        "when stderr is not a terminal (default 5)")
    p.add_argument("--ready-timeout", type=float, default=60.0,
                   help="seconds to wait for the recorder's subscriptions and (lockstep) the simulator's "
                        "publishers (default 60)")
    p.add_argument("--compose", action="store_true",
                   help="compose the nodes into one process ('container': planner, controllers and simulator in "
                        "one executor; the recorder in its own process); see --group")
    p.add_argument("--group", action="append", default=None, metavar="NODE,NODE[,...]",
                   help="with or without --compose: these nodes composed into one process (repeatable; nodes in "
                        "no group run alone), e.g. --group path_following,l1_autopilot,mixer")
    p.add_argument("--foxglove", type=int, nargs="?", const=FOXGLOVE_DEFAULT_PORT, default=None, metavar="PORT",
                   help="serve the graph live to Foxglove (WebSocket on 127.0.0.1:PORT, default "
                        f"{FOXGLOVE_DEFAULT_PORT}; Foxglove: Open connection -> Foxglove WebSocket)")
    p.add_argument("--without", default="", metavar="NODE[,NODE...]",
                   help=f"leave these nodes out ({', '.join(REPLACEABLE)}), for nodes of your own in their place on "
                        "the contract's topics, on the run's ROS_DOMAIN_ID (give it with --domain-id): your "
                        "autopilot, --without l1_autopilot,mixer.  Lockstep waits for their answer to each step "
                        "(the first up to the simulator's startup_timeout_s, 30 s)")
    p.add_argument("--runner", choices=RUNNERS, default="auto", help="how nodes are started (default auto)")
    p.add_argument("--echo", action="store_true", help="also print every node's output, prefixed")
    p.add_argument("--install-ros-ws", action="store_true",
                   help="install the bb2_ros_ws packaging into this venv (lib/<pkg>/<exe>, ament index) "
                        "and exit")
    args = p.parse_args(argv)
    if args.mission is not None:  # a shipped mission's or fleet's name, as bb2-sim mission and ros2 launch take it
        from bb2_mission.fleet import run_file

        args.mission = run_file(args.mission)
    return args


def check_run_options(args: argparse.Namespace) -> None:
    """The options of a run's limits and domain (a mission's or a fleet's): :class:`LaunchError` naming a bad one."""
    if args.domain_id is not None and not 0 <= args.domain_id <= 232:
        raise LaunchError(f"--domain-id must be in 0..232, got {args.domain_id}")
    if args.timeout is not None and not (args.timeout > 0 and math.isfinite(args.timeout)):
        raise LaunchError(f"--timeout must be > 0 and finite, got {args.timeout}")
    check_stall_timeout(args.stall_timeout)
    if not (args.status_period > 0 and math.isfinite(args.status_period)):
        raise LaunchError(f"--status-period must be > 0 and finite, got {args.status_period}")
    if not (args.ready_timeout > 0 and math.isfinite(args.ready_timeout)):
        raise LaunchError(f"--ready-timeout must be > 0 and finite, got {args.ready_timeout}")
    if args.max_restarts < 0:
        raise LaunchError(f"--max-restarts must be >= 0, got {args.max_restarts}")
    if args.max_restarts != DEFAULT_MAX_RESTARTS and not uses_default_max(args.restart):
        raise LaunchError(f"--max-restarts {args.max_restarts} applies to no node: it counts the restarts of a "
                          "--restart NODE=restart without a count of its own (NODE=restart:N)")


def main(argv: Sequence[str] | None = None) -> int:
    """Console script ``bb2-launch``: exit 0 mission complete, 1 a node failed / the timeout passed, 2 bad input
    or an OS error (one line naming the file), 130 interrupted."""
    return run_cli("bb2-launch", lambda: _main(argv))


def _main(argv: Sequence[str] | None) -> int:
    args = parse_args(list(sys.argv[1:] if argv is None else argv))
    if args.install_ros_ws:
        ws = Path(__file__).resolve().parents[1] / "bb2_ros_ws" / "install_into_venv.py"
        if not ws.is_file():
            print(f"bb2-launch: error: {ws} not found (run from a source checkout)", file=sys.stderr)
            return 2
        return subprocess.call([sys.executable, str(ws)])
    from bb2_msgs_py.ros_env import ros_environment_or_error

    # called directly from the venv (not through run.sh): the venv's ament prefix and middleware, before the
    # ament index is read; the nodes inherit them
    if (bad := ros_environment_or_error("bb2-launch")) is not None:
        return bad
    try:
        if args.mission is None:
            raise LaunchError("a mission file is required")
        from bb2_mission.fleet import is_fleet_file, run_file_hint

        if not args.mission.exists():  # (a shipped name was taken by parse_args): the likely one
            raise LaunchError(f"mission file {args.mission.resolve()} does not exist{run_file_hint(args.mission)}")

        if is_fleet_file(args.mission):
            raise LaunchError(f"{args.mission} is a fleet file: run it with bb2-launch "
                              "(python -m bb2_tools.launch_cli)")
        check_run_options(args)
        namespace = check_namespace(args.namespace)
        if args.external_recorder and args.no_record:
            raise LaunchError("--external-recorder (recorded elsewhere) and --no-record (not recorded) contradict")
        groups = compose_groups(args.group if args.group is not None else [] if args.compose else None)
        without = check_without(args.without, "--without")
        if args.compose and args.group is None and without:  # every composable node but those left out
            groups = [tuple(n for n in g if n not in without) for g in groups]
        if clash := [n for g in groups for n in g if n in without]:
            raise LaunchError(f"--without {','.join(clash)} and --group {','.join(clash)}: a node left out cannot be "
                              "composed")
        policies = parse_restart_policies(args.restart, [n for n in process_names(groups) if n not in without],
                                          args.max_restarts)
        check_restart_policies(policies, groups)
        mission = args.mission.resolve()
        params = args.params.resolve() if args.params else None
        overridden: list[str] = []
        if params is not None:
            check_params_file(params)
            overridden = params_overridden(params, launcher_parameters(mission, args.mode,
                                                                       stall_timeout_s=args.stall_timeout))
        mission_warning = check_mission(mission)
        if args.foxglove is not None:
            check_foxglove_port(args.foxglove)
        for n in (*GRAPH_NODES, *((CONTAINER,) if groups else ()), *((FOXGLOVE,) if args.foxglove else ())):
            node_command(n, args.runner)  # one clear error, before anything starts
        # the run directory is claimed atomically (os.mkdir): two launches in the same second never share one
        if args.out is not None:
            run_dir = claim_run_dir(path=args.out.resolve())
        else:
            run_dir = claim_run_dir(args.bag_dir.resolve(), f"{mission.stem}_{time.strftime('%Y%m%d_%H%M%S')}"
                                    + (f"_{namespace.replace('/', '_')}" if namespace else ""))
    except (LaunchError, OutputError) as exc:
        print(f"bb2-launch: error: {exc}", file=sys.stderr)
        return 2

    try:
        monitor = domain_monitor(args.domain_id, end_at=args.end_at, namespace=namespace)
        if args.domain_id is not None and monitor.domain_lock_fd is None and not namespace:
            print(f"[bb2-launch] warning: another bb2-launch runs on ROS_DOMAIN_ID={args.domain_id}: the two "
                  "graphs will see each other's topics (give each its own --namespace)", file=sys.stderr)
    except LaunchError as exc:
        print(f"bb2-launch: error: {exc}", file=sys.stderr)
        return 2
    log_dir = run_dir / "logs"
    env = dict(os.environ)
    env["ROS_DOMAIN_ID"] = str(monitor.domain_id)
    env["ROS_LOG_DIR"] = str(log_dir / "ros")
    env[PUBLISHED_DIR_ENV] = str(log_dir / "published")  # each node process's counts, compared with the bag
    specs = graph_specs(mission, run_dir, mode=args.mode, params=params, record=not args.no_record,
                        runner=args.runner, policies=policies, monitor=monitor, groups=groups,
                        foxglove_port=args.foxglove, namespace=namespace, own_recorder=not args.external_recorder,
                        without=without, stall_timeout_s=args.stall_timeout)
    echo = (lambda name, line: print(f"[{name}] {line}", file=sys.stderr, flush=True)) if args.echo else None
    print(f"[bb2-launch] mission {mission} | mode {args.mode} | ROS_DOMAIN_ID={monitor.domain_id} | "
          + (f"namespace /{namespace} | " if namespace else "") + f"run {run_dir}", file=sys.stderr, flush=True)
    for warning in (*overridden, mission_warning):
        if warning:
            print(f"[bb2-launch] warning: {warning}", file=sys.stderr, flush=True)
    if without:
        from bb2_msgs_py.contract import node_interface

        print(f"[bb2-launch] without: {', '.join(without)} (not started: your nodes answer in their place on "
              f"ROS_DOMAIN_ID={monitor.domain_id}" + (f", in /{namespace}" if namespace else "")
              + "; until they do, the status line says FAILSAFE)", file=sys.stderr, flush=True)
        for name in without:
            pubs, subs = node_interface(name)
            print(f"[bb2-launch]   in place of the {name}: publish "
                  + ", ".join(f"{t.name} ({t.type})" for t in pubs) + "; it reads "
                  + ", ".join(t.name for t in subs), file=sys.stderr, flush=True)
    for g in groups:
        print(f"[bb2-launch] composed: process '{process_name(g)}' runs {', '.join(g)}", file=sys.stderr, flush=True)
    if args.foxglove is not None:
        print(f"[bb2-launch] foxglove: ws://127.0.0.1:{args.foxglove} (Foxglove: Open connection -> Foxglove "
              "WebSocket)", file=sys.stderr, flush=True)
    sup = Supervisor(specs, log_dir, env=env, echo=echo)
    try:
        result = run_graph(sup, monitor, first=[s.name for s in specs if s.ready is not None],
                           ready_timeout_s=args.ready_timeout, timeout_s=args.timeout,
                           status_period_s=args.status_period, stall_timeout_s=args.stall_timeout or None,
                           recorder_outside=args.external_recorder and not args.no_record)
    finally:
        sup.stop(hurry=True)
        monitor.close()
    bags = recorder_bags(run_dir, result.exits) if not (args.no_record or args.external_recorder) else []
    for note in repair_bags(bags):
        print(f"[bb2-launch] {note}", file=sys.stderr)
    clean_after_killed(sup.exits, lambda line: print(f"[bb2-launch] {line}", file=sys.stderr))
    counts_note = ""
    if len(bags) == 1 and bags[0].is_dir():  # a restarted recorder splits the run: its bags are not compared
        try:
            counts_note = merge_publication_counts(bags[0], log_dir / "published", result.exits,
                                                   recorded_topics(namespace), namespace)
        except OSError as exc:
            counts_note = f"cannot write {bags[0] / PUBLICATION_COUNTS_FILE}: {exc}"
    if without and (result.reason.startswith(FAILSAFE_STALL) or monitor.sim_error_state == "stalled"):
        print(f"[bb2-launch] nothing answered in place of the {', '.join(without)} (--without): start your nodes on "
              f"ROS_DOMAIN_ID={monitor.domain_id}" + (f" in /{namespace}" if namespace else "") + " with the launch, "
              "or give --stall-timeout 0 to fly on the failsafe", file=sys.stderr)
    rtf = f"{result.rtf_overall:.1f}x" if result.rtf_overall else "--"
    t = f"{result.sim_time_s:.2f} s" if result.sim_time_s is not None else "--"
    print(f"[bb2-launch] {result.reason}: sim time {t}, RTF {rtf}, wall {result.wall_s:.1f} s, "
          f"exit code {result.exit_code}", file=sys.stderr)
    for b in bags:
        print(f"[bb2-launch] bag:   {b}", file=sys.stderr)
        for line in gap_lines(b) + ([counts_note] if counts_note and b == bags[0] else []):
            print(f"[bb2-launch]        {line}", file=sys.stderr)
    print(f"[bb2-launch] logs:  {log_dir}", file=sys.stderr)
    if bags:
        print(f"[bb2-launch] plots: bb2-analyze {bags[0]}", file=sys.stderr)
    return result.exit_code


if __name__ == "__main__":
    sys.exit(main())
