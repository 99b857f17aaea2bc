"""The BB2 graph, one boat: ``ros2 launch bb2_bringup bb2_graph.launch.py [argument:=value ...]``.

Arguments (``ros2 launch bb2_bringup bb2_graph.launch.py --show-args``):

  mission      canyon (a mission installed in share/bb2_bringup/missions, without .yaml) or a mission FILE
  time_mode    lockstep | realtime
  record       true | false: the recorder writes every topic to a rosbag2 MCAP bag
  bag          the bag directory ('' = <bag_dir>/<mission>_<YYYYmmdd_HHMMSS>[_<namespace>][_2, _3 ...: the first
               free one]): a new or empty directory, claimed for this run as bb2-launch claims its run directory
  bag_dir      where bags go when bag is '' (default bags, relative to the working directory)
  namespace    '' or NAME: the boat's nodes run in /NAME and its topics are /NAME/bb2/... and /NAME/clock
               (several boats side by side without crosstalk; fleet.launch.py starts several)
  params_file  the graph's params file (default share/bb2_bringup/config/bb2_graph.yaml)
  compose      true | false: the planner, the controllers and the simulator composed into one process
               (``ros2 run bb2_ros container``, one executor; bb2-launch --compose), the recorder alone
  group        '' or NODE,NODE[,...][;NODE,NODE...]: each group of planner, path_following, l1_autopilot, mixer,
               simulator composed into one container process of its own, the nodes in no group each alone
               (bb2-launch --group, once per group), e.g. group:=path_following,l1_autopilot,mixer: the control
               loop in one process, the simulator, the planner and the recorder each in theirs; it sets the
               grouping whatever compose says
  foxglove     true | false: serve every topic live to Foxglove (``ros2 run bb2_tools foxglove_bridge``, a
               WebSocket on 127.0.0.1:foxglove_port; bb2-launch --foxglove)
  foxglove_port  the Foxglove WebSocket port (default 8765)
  without      '' or NODE[,NODE...] of planner, path_following, l1_autopilot, mixer: those nodes are not started, for
               nodes of your own in their place on the contract's topics (your autopilot: without:=l1_autopilot,mixer;
               run it with ``ros2 run`` on the same ROS_DOMAIN_ID). In lockstep the simulator waits for the answer to
               each step (the first up to startup_timeout_s, 30 s), in real time for the first command.
  restart      '' or NODE=POLICY[,NODE=POLICY...] (bb2-launch --restart): what a node's death before the run's end
               does -- stop (the default: every node stopped, the launch fails), restart[:N] (launch's respawn, up to
               N times, default 3; a restarted path follower rejoins the run where it stands) or ignore (said, the run
               goes on); NODE is a node, a group's process (path_following+l1_autopilot+mixer) or all; the simulator
               takes stop only (its exit is the run's end), the recorder stop or ignore (a new one would write over
               the run's bag)
  timeout      '' or wall s (bb2-launch --timeout): a run not ended by then is stopped (every node, the bag
               finished) and the launch fails
  stall_timeout  wall s (default 60; 0 = never) of stepping on the failsafe without a break -- no controller
               answers: your node not started, or on another domain -- after which the simulator stops the run as
               stalled and the launch fails (bb2-launch --stall-timeout), rather than crawl on neutral planes;
               it sets the simulator's stall_timeout_s, over a params file's /** value, with a warning (as
               time_mode sets time_mode); a node's own entry that sets it otherwise is refused (it would win).

It starts what ``bb2-launch`` starts — simulator, planner, path_following, l1_autopilot, mixer and (record) the
recorder, each its own process, the recorder and the planner at nice +10 — with the same parameters: the
params file, then the mission, the time mode, use_sim_time (the simulator is the clock) and, with a recorder,
``wait_for_readers`` (the bag misses nothing from the first step) and in lockstep ``recorder_ack_window`` (the graph
waits for a stalled recorder rather than lose messages), in real time ``wait_for_commands`` (the clock starts once
the controllers answer, not on the start-up failsafe).  The simulator ends the run where bb2-launch does (the
mission duration, or ``end_at_progress``: the path flown) and exits; its exit stops the whole launch (the
recorder finishes its bag on the SIGINT).  A simulator that exits with an error (the run failed: the boat diverged,
or a parameter's value was refused) makes ``ros2 launch`` exit 1.  A node that dies before the run's end stops the
graph and fails the launch too (without a controller the simulator would step on held planes, one step a second;
without the recorder it waits for a reader); the Foxglove server alone may go (said; the run goes on).  A node
killed by a signal left Fast DDS's shared-memory files in /dev/shm: they are removed as it exits (``fastdds shm
clean``), as bb2-launch removes them.  The mission, the params file (a node or a parameter the graph does not have:
ROS would ignore it), the bag directory and the Foxglove port are checked before any node starts, as bb2-launch
checks them.  Ctrl-C stops every node cleanly.  With ``compose:=true`` the same nodes with the same arguments run in
one ``container`` process (each node's ROS arguments apply to it alone), whose exit ends the launch; with
``group:=`` each group runs in a container process of its own (named for its nodes, ``path_following+l1_autopilot+
mixer``), the process holding the simulator ends the launch and any other's death before the run's end fails it,
as a node's does.
"""
from __future__ import annotations

import contextlib
import math
import shutil
import time
from pathlib import Path

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import (DeclareLaunchArgument, EmitEvent, ExecuteProcess, LogInfo, OpaqueFunction,
                            RegisterEventHandler, TimerAction)
from launch.event_handlers import OnProcessExit
from launch.events import Shutdown, matches_action
from launch.events.process import ShutdownProcess
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from launch_ros.substitutions import ExecutableInPackage

from bb2_msgs_py.contract import RECORDER_ACK_WINDOW, check_namespace
from bb2_sim.names import did_you_mean
from bb2_sim.outputs import OutputError, claim_run_dir
from bb2_ros.node_common import CALLBACK_PRIORITY_REALTIME, REALTIME_CONTROLLERS
from bb2_tools.dds_shm import clean_after_kill
from bb2_tools.launcher import (BACKGROUND_NODES, COMPOSABLE, DEFAULT_STALL_TIMEOUT_S, REJOINING, check_foxglove_port,
                                check_mission, check_params_file, check_restart_policies, check_stall_timeout,
                                check_without, compose_groups, launcher_parameters, params_overridden, process_name,
                                process_names, process_of)
from bb2_tools.supervisor import RestartPolicy, parse_restart_policies

SHARE = Path(get_package_share_directory("bb2_bringup"))
BACKGROUND = "nice -n 10"  # off the control loop, as bb2-launch starts them

ARGUMENTS = {
    "mission": ("canyon", "a mission in share/bb2_bringup/missions (name without .yaml) or a mission file"),
    "time_mode": ("lockstep", "lockstep | realtime"),
    "record": ("true", "true | false: record every topic to a rosbag2 MCAP bag"),
    "bag": ("", "a new or empty bag directory ('' = <bag_dir>/<mission>_<YYYYmmdd_HHMMSS>[_<namespace>][_2 ...])"),
    "bag_dir": ("bags", "where bags go when bag is ''"),
    "namespace": ("", "'' or NAME: nodes in /NAME, topics /NAME/bb2/... and /NAME/clock"),
    "params_file": (str(SHARE / "config" / "bb2_graph.yaml"), "the graph's ROS 2 params file"),
    "compose": ("false", "true | false: planner, controllers and simulator in one process (the container)"),
    "group": ("", "'' or NODE,NODE[,...][;NODE,NODE...] of planner, path_following, l1_autopilot, mixer, simulator: "
                  "each group in one container process, the others alone (e.g. path_following,l1_autopilot,mixer)"),
    "foxglove": ("false", "true | false: serve every topic live to Foxglove (WebSocket on 127.0.0.1:foxglove_port)"),
    "foxglove_port": ("8765", "the Foxglove WebSocket port"),
    "without": ("", "'' or NODE[,NODE...] of planner, path_following, l1_autopilot, mixer: left out, for nodes of "
                    "your own in their place (your autopilot: without:=l1_autopilot,mixer)"),
    "stall_timeout": (f"{DEFAULT_STALL_TIMEOUT_S:g}", "wall s of stepping on the failsafe (no controller answers) "
                      "after which the run stops as stalled and the launch fails; 0 = never"),
    "timeout": ("", "'' or wall s: a run not ended by then is stopped (the bag finished) and the launch fails"),
    "restart": ("", "'' or NODE=POLICY[,...]: a node's death before the run's end stops the graph and fails the launch "
                    "(stop, the default), restarts it (restart[:N], N default 3) or is said (ignore); NODE may be all"),
}
RESPAWN_DELAY_S = 0.5
"""Wall s before launch respawns a node under a ``restart`` policy (bb2-launch's first restart delay)."""


def installed_or_file(value: str, folder: Path, what: str) -> Path:
    """A file installed in ``folder`` named without .yaml (``canyon``), or a file (``x.yaml``, ``dir/x``)."""
    p = Path(value).expanduser()
    if p.suffix in (".yaml", ".yml") or "/" in value:
        if not p.is_file():
            raise RuntimeError(f"{what} file {p} does not exist")
        return p.resolve()
    f = folder / f"{value}.yaml"
    if not f.is_file():
        names = sorted(m.stem for m in folder.glob("*.yaml"))
        raise RuntimeError(f"no {what} {value!r} in {folder}{did_you_mean(value, names)} (there: "
                           f"{', '.join(names) or 'none'})")
    return f


def mission_file(value: str) -> Path:
    """A mission name (installed in share/bb2_bringup/missions) or a file."""
    return installed_or_file(value, SHARE / "missions", "mission")


def checked_params_file(value: str) -> str:
    """'' (no params file) or the params file ``value``, checked as ``bb2-launch --params`` checks it: it exists,
    it is ROS 2's layout, and its node names and parameters are the graph's (launch_ros only warns of a missing
    file and starts the nodes without it; ROS ignores a parameter no node declares).  Like every check here it
    raises bb2-launch's own error: any exception is what makes ``ros2 launch`` say it and exit 1."""
    if not value.strip():
        return ""
    path = Path(value).expanduser().resolve()
    check_params_file(path, SHARE / "config" / "bb2_graph.yaml")
    return str(path)


def overridden_by_arguments(params_file: str, a: dict, stall_timeout_s: float, mission: Path | None = None) -> list:
    """A warning (LogInfo) for each parameter the params file sets under ``/**`` (other than its default) that a
    launch argument sets otherwise (the argument wins without a word, as in bb2-launch); a node's own entry that
    does is refused (it would win for that node alone): :func:`bb2_tools.launcher.params_overridden`.  ``mission``:
    None for a fleet (each boat's own)."""
    if not params_file:
        return []
    given = launcher_parameters(mission or Path(), a["time_mode"], a, stall_timeout_s)
    if mission is None:
        del given["*"]
    return [LogInfo(msg=f"[bb2_bringup] warning: {w}") for w in params_overridden(Path(params_file), given)]


def flag(value: str, name: str) -> bool:
    v = value.strip().lower()
    if v not in ("true", "false"):
        raise RuntimeError(f"launch argument {name} must be true or false, got {value!r}")
    return v == "true"


def remappings(namespace: str) -> list[tuple[str, str]]:
    """A boat in /NAMESPACE has a clock of its own: ``/clock`` (absolute, as rclpy's time source reads it) ->
    ``/NAMESPACE/clock``; none without a namespace.  Its other topics go under /NAMESPACE by themselves: the nodes
    name them relative to their namespace (``bb2_msgs_py.contract.node_topic_name``), ``/diagnostics`` and ``/tf``
    stay every boat's."""
    ns = namespace.strip("/")
    return [("/clock", f"/{ns}/clock")] if ns else []


def fail(message: str) -> OpaqueFunction:
    """An action that fails the launch with ``message``: an exception is how a launch file makes ``ros2 launch``
    exit 1 (it logs "Caught exception in launch ...: message" and stops every node, as a shutdown does)."""
    def raise_it(_context):
        raise RuntimeError(message)
    return OpaqueFunction(function=raise_it)


def _ros_value(v) -> str:
    return str(v).lower() if isinstance(v, bool) else str(v)


def container_arguments(nodes: list[tuple[str, dict]], params: list[str], ns: str) -> list[str]:
    """The ``container`` command line of ``nodes`` (executable, parameters): each node's own ROS arguments,
    what ``Node`` gives it in a process of its own (params files, parameters, remaps, namespace)."""
    out: list[str] = []
    for executable, values in nodes:
        out += ["--node", executable, "--ros-args"]
        for f in params:
            out += ["--params-file", f]
        for k, v in values.items():
            out += ["-p", f"{k}:={_ros_value(v)}"]
        for a, b in remappings(ns):
            out += ["-r", f"{a}:={b}"]
        if ns:
            out += ["-r", f"__ns:=/{ns}"]
        out.append("--")
    return out


def boat(mission: Path, *, time_mode: str, record: bool, bag: Path | None, namespace: str, params_file: str,
         stop_launch: bool = True, compose: bool = False, foxglove_port: int | None = None,
         own_recorder: bool = True, without: tuple[str, ...] = (),
         stall_timeout_s: float = DEFAULT_STALL_TIMEOUT_S, groups: list[tuple[str, ...]] | None = None,
         restart: dict[str, RestartPolicy] | None = None) -> list:
    """The actions of one boat's graph (the nodes; with ``stop_launch`` the simulator's exit ends the launch,
    without it the simulator's exit stops this boat's other nodes;
    ``compose``: every node but the recorder (and those left out) in one container process; ``groups``
    (:func:`checked_groups`; over ``compose``): each group of nodes in a container process of its own, the others
    alone; ``restart``: the processes' policies when they die before the run's end (:func:`checked_restart`);
    ``foxglove_port``: the live Foxglove
    server on that port; ``record`` without ``own_recorder``: recorded by a recorder of the caller's, a fleet's
    (:func:`fleet_recorder`), which the simulator waits for as for its own; ``without``: nodes not started, a
    user's own in their place, :func:`bb2_tools.launcher.check_without`; ``stall_timeout_s``: the simulator stops
    the run as stalled after stepping on its failsafe this long, 0 = never)."""
    check_time_mode(time_mode)
    ns = namespace.strip("/")
    common = {"mission_file": str(mission)}
    params = [params_file] if params_file else []

    policies = restart or {}

    def respawn(name: str) -> dict:
        """launch's respawn of process ``name`` under a ``restart`` policy (as many times as it allows)."""
        pol = policies.get(name)
        if pol is None or pol.action != "restart":
            return {}
        return {"respawn": True, "respawn_delay": RESPAWN_DELAY_S, "respawn_max_retries": pol.max_restarts}

    def node(package, executable, extra, *, background=False, arguments=()):
        return Node(package=package, executable=executable, name=executable, namespace=ns or None,
                    parameters=[*params, {**common, **extra}] if package == "bb2_ros" else [extra],
                    remappings=remappings(ns), arguments=list(arguments), output="screen",
                    prefix=BACKGROUND if background else None, **respawn(executable))

    actions = []
    run_over: list[bool] = []   # [True] once this boat's simulator has exited: its nodes may go after it
    who = (lambda exe: f"/{ns}/{exe}") if ns else (lambda exe: f"the {exe}")
    if record and own_recorder:
        assert bag is not None
        # (overwrite: the directory holds the claim file of claim_bag, as bb2-launch's run directory does)
        actions.append(node("bb2_tools", "recorder", {"bag_directory": str(bag), "use_sim_time": True,
                                                      "overwrite": True}, background=True))
        actions.append(watch(actions[-1], who("recorder"), lambda: bool(run_over), policy=policies.get("recorder")))
    if foxglove_port is not None:
        actions.append(node("bb2_tools", "foxglove_bridge", {"port": int(foxglove_port), "use_sim_time": True},
                            background=True))
        actions.append(watch(actions[-1], who("foxglove_bridge"), lambda: bool(run_over), essential=False))
    sim_values = {"use_sim_time": False, "time_mode": time_mode, "exit_at_end": True, "end_at_progress": True,
                  "stall_timeout_s": float(stall_timeout_s),
                  "wait_for_readers": record, "wait_for_commands": time_mode == "realtime",
                  "recorder_ack_window": RECORDER_ACK_WINDOW if record and time_mode == "lockstep" else 0}
    controllers = [(exe, bg) for exe, bg in (("planner", True), ("path_following", False), ("l1_autopilot", False),
                                             ("mixer", False)) if exe not in without]
    # in real time the controllers' answers do not wait for a core, nor the simulator's reception of them (as
    # bb2-launch sets them)
    rt = {"callback_priority": CALLBACK_PRIORITY_REALTIME} if time_mode == "realtime" else {}
    sim_values.update(rt)
    if groups is None:
        groups = [tuple(n for n in COMPOSABLE if n not in without)] if compose else []
    groups = [g for g in groups if len(g) > 1]        # a group of one node is that node alone
    grouped = {n for g in groups for n in g}
    values = {exe: {"use_sim_time": True, **(rt if exe in REALTIME_CONTROLLERS else {})} for exe, _bg in controllers}
    values["simulator"] = sim_values
    # a restarted node rejoins the run where it stands (bb2-launch sets it on a restart only; launch's respawn runs
    # the same command, and the first start answers the state of t = 0, which rejoins nothing)
    for name, param in REJOINING.items():
        if name in values and getattr(policies.get(process_of(name, groups)), "action", None) == "restart":
            values[name] = {**values[name], param: True}
    what = process_of("simulator", groups)   # the process whose exit is the run's end
    sim = None
    for exe, bg in controllers:
        if exe not in grouped:
            actions.append(node("bb2_ros", exe, values[exe], background=bg))
            actions.append(watch(actions[-1], who(exe), lambda: bool(run_over), policy=policies.get(exe)))
    for g in groups:   # each group's nodes in a container process of its own, in the graph's start order
        name = process_name(g)
        proc = ExecuteProcess(cmd=[ExecutableInPackage("container", "bb2_ros"),
                                   *container_arguments([(exe, {**common, **values[exe]}) for exe in g], params, ns)],
                              name=name + (f"_{ns}" if ns else ""), output="screen",
                              prefix=BACKGROUND if set(g) <= set(BACKGROUND_NODES) else None, **respawn(name))
        if name == what:
            sim = proc
        else:
            actions.append(proc)
            actions.append(watch(proc, who(name), lambda: bool(run_over), policy=policies.get(name)))
    if sim is None:
        sim = node("bb2_ros", "simulator", sim_values)
    # the boat's other nodes (not a fleet's recorder) go with its run: in a fleet the other boats may fly on (as
    # each boat's bb2-launch stops its own graph); alone the whole launch stops anyway
    own = [act for act in actions if isinstance(act, (Node, ExecuteProcess))]

    def over(event, context):
        run_over.append(True)
        said = cleaned_after_kill(event.returncode, who(what))
        if stop_launch or context.is_shutdown:
            return said or None
        return [*said, *(EmitEvent(event=ShutdownProcess(process_matcher=matches_action(act))) for act in own)]

    actions.append(RegisterEventHandler(OnProcessExit(target_action=sim, on_exit=over)))
    if stop_launch:
        def on_exit(event, context):
            said = LogInfo(msg=f"[bb2_bringup] {what}{' of ' + ns if ns else ''} exited (code {event.returncode}): "
                               "stopping the graph")
            if event.returncode != 0 and not context.is_shutdown:
                return [said, fail(f"the {what}{' of ' + ns if ns else ''} exited with code {event.returncode}: "
                                   "the run failed (its log above says why)")]
            return [said, EmitEvent(event=Shutdown(reason="the simulator ended the run"))]

        actions.append(RegisterEventHandler(OnProcessExit(target_action=sim, on_exit=on_exit)))
    actions.append(sim)   # last: the caller's (a fleet's) handle on this boat's simulator
    return actions


def checked_groups(value: str, compose: bool, without: tuple[str, ...] = ()) -> list[tuple[str, ...]]:
    """The container processes of launch arguments ``group`` (``;``-separated groups of comma-separated nodes, as
    many ``bb2-launch --group``) and ``compose`` (with no group: every node but the recorder and those ``without``
    in one), checked as bb2-launch checks them (:func:`bb2_tools.launcher.compose_groups`: an unknown node, the
    recorder, a node in two groups), and a node both grouped and left out refused.  A group of one node is that
    node alone (none is returned)."""
    parts = [g for g in value.split(";") if g.strip()]
    if not parts:
        groups = [tuple(n for n in COMPOSABLE if n not in without)] if compose else []
    else:
        groups = compose_groups(parts, "launch argument group")
        if clash := [n for g in groups for n in g if n in without]:
            raise RuntimeError(f"launch arguments without and group both name {', '.join(clash)}: a node left out "
                               "cannot be composed")
    return [g for g in groups if len(g) > 1]


def checked_restart(value: str, groups: list[tuple[str, ...]], record: bool,
                    without: tuple[str, ...] = ()) -> dict[str, RestartPolicy]:
    """The restart policies of launch argument ``restart`` (``NODE=POLICY,...``, bb2-launch ``--restart``'s words:
    :func:`bb2_tools.supervisor.parse_restart_policies`) for the processes of this graph (its nodes, ``groups``'
    processes, not those ``without`` leaves out), refused as bb2-launch refuses them (the simulator restarted), and
    what a launch file cannot do: the process holding the simulator ignored (its exit is the run's end), the recorder
    restarted (a new one would write over the run's bag: bb2-launch starts a bag of its own for it)."""
    option = "launch argument restart"
    names = [n for n in process_names(groups) if n not in without and (record or n != "recorder")]
    policies = parse_restart_policies([value], names, option=option)
    check_restart_policies(policies, groups, option=option)
    holder = process_of("simulator", groups)
    if getattr(policies.get(holder), "action", None) == "ignore":
        raise RuntimeError(f"{option}: {holder}=ignore: the {holder}'s exit is the run's end (stop, its default)")
    if getattr(policies.get("recorder"), "action", None) == "restart":
        raise RuntimeError(f"{option}: restarting the recorder is refused here: a new recorder would write over the "
                           "run's bag (bb2-launch --restart recorder=restart gives it a bag of its own); use "
                           "recorder=stop or recorder=ignore")
    return policies


def wall_timeout(value: str) -> list:
    """The actions of launch argument ``timeout`` (``''``: none; wall seconds > 0, as ``bb2-launch --timeout``): a
    timer that fails the launch (every node stopped, as by Ctrl-C: the recorder finishes its bag) if the run has not
    ended by then; cancelled by the launch's own end."""
    if not value.strip():
        return []
    try:
        t = float(value)
    except ValueError:
        raise RuntimeError(f"launch argument timeout must be wall seconds (or '' for none), got {value!r}") from None
    if not (t > 0 and math.isfinite(t)):
        raise RuntimeError(f"launch argument timeout must be > 0 and finite, got {value}")
    return [TimerAction(period=t, actions=[fail(f"timeout after {t:g} s of wall time (launch argument timeout:="
                                                f"{value.strip()}): the run had not ended; stopping the graph")])]


def check_time_mode(time_mode: str) -> str:
    if time_mode not in ("lockstep", "realtime"):
        raise RuntimeError(f"launch argument time_mode must be lockstep or realtime, got {time_mode!r}")
    return time_mode


def watch(action, who: str, run_over, *, essential: bool = True,
          policy: RestartPolicy | None = None) -> RegisterEventHandler:
    """A handler of ``action``'s exit (a node's process; ``who`` names it) before the run is over (``run_over()``
    false) and the launch is not stopping: an ``essential`` node's fails the launch (exit 1, every node stopped:
    without a controller the simulator would step on held planes, one step a second, and without the recorder
    it waits for a reader; bb2-launch stops the graph the same way); any other's is said and the run goes on.
    A process killed by a signal (whenever) left its Fast DDS shared-memory files: they go at once
    (:func:`cleaned_after_kill`), as bb2-launch removes them after its run.  ``policy`` (launch argument
    ``restart``): ``ignore`` makes the node not essential; ``restart`` says each of its ``max_restarts`` restarts
    (launch respawns it: :func:`boat`) and fails the launch at the next death."""
    restarts = [0]

    def on_exit(event, context):
        rc = event.returncode
        said = cleaned_after_kill(rc, who)
        if context.is_shutdown or run_over():
            return said or None
        how = f"was killed by signal {-rc}" if rc < 0 else f"exited (code {rc})"
        if not essential or (policy is not None and policy.action == "ignore"):
            return [*said, LogInfo(msg=f"[bb2_bringup] {who} {how}: the run goes on without it")]
        if policy is not None and policy.action == "restart" and restarts[0] < policy.max_restarts:
            restarts[0] += 1
            return [*said, LogInfo(msg=f"[bb2_bringup] {who} {how} before the run's end: restarting it (restart "
                                       f"{restarts[0]} of {policy.max_restarts})")]
        return [*said, fail(f"{who} {how} before the run's end: stopping the graph (the run is not whole; its log "
                            "above says why)")]
    return RegisterEventHandler(OnProcessExit(target_action=action, on_exit=on_exit))


def cleaned_after_kill(returncode: int | None, who: str) -> list:
    """A process that ended by a signal left its Fast DDS shared-memory files in /dev/shm: ``fastdds shm clean``
    removes those whose owner is gone (:func:`bb2_tools.dds_shm.clean_after_kill`); a LogInfo saying so, when it
    removed any."""
    line = clean_after_kill(who) if returncode is not None and returncode < 0 else None
    return [LogInfo(msg=f"[bb2_bringup] {line}")] if line else []


def fleet_recorder(bag: Path, boats: list[str]) -> Node:
    """The one recorder of a fleet: every boat's topics under its namespace in one bag (``/boat1/bb2/odom``,
    ``/boat1/clock``, one ``/tf``), each boat logged on its own clock and acknowledged on its
    ``/boat1/bb2/recorder/ack``."""
    # (overwrite: the bag directory holds its claim file and the boats' mission files, missions/, as a run directory
    # does)
    return Node(package="bb2_tools", executable="recorder", name="recorder", output="screen", prefix=BACKGROUND,
                parameters=[{"bag_directory": str(bag), "use_sim_time": True, "boats": list(boats),
                             "overwrite": True}])


def claim_bag(bag: str, bag_dir: str, stem: str) -> Path:
    """The run's bag directory, claimed for it as ``bb2-launch`` claims its run directory
    (:func:`bb2_sim.outputs.claim_run_dir`: ``os.mkdir`` is atomic, the directory holds a claim file naming the
    run): ``bag`` (a new or empty directory; its parent writable), else ``<bag_dir>/<stem>`` or, taken (two
    launches in the same second), ``<stem>_2``, ``_3`` ... The recorder then writes into it (``overwrite``)."""
    try:
        if bag:
            return claim_run_dir(path=Path(bag).expanduser().resolve())
        return claim_run_dir(Path(bag_dir).expanduser().resolve(), stem)
    except OutputError as exc:  # said before any node starts (the recorder refused it once the nodes were up)
        what = "launch argument bag" if bag else "launch argument bag_dir"
        raise OutputError(f"{what}: {str(exc).replace('run directory', 'bag directory')}"
                          + (": choose another bag:=, or leave bag:='' for a new one under bag_dir" if bag else "")
                          ) from None


@contextlib.contextmanager
def released_on_error(bag: Path | None):
    """The bag directory this launch claimed (:func:`claim_bag`) goes again if what follows raises: the launch is
    refused, and the directory holds only what it wrote (its claim file, a fleet's missions)."""
    try:
        yield
    except BaseException:
        if bag is not None:
            shutil.rmtree(bag, ignore_errors=True)
        raise


def _graph(context):
    a = {k: LaunchConfiguration(k).perform(context) for k in ARGUMENTS}
    mission = mission_file(a["mission"])
    warning = check_mission(mission)   # as bb2-launch checks it: else every node refused it, one by one
    params_file = checked_params_file(a["params_file"])
    record = flag(a["record"], "record")
    without = check_without(a["without"], "launch argument without")
    stall = check_stall_timeout(a["stall_timeout"], "launch argument stall_timeout")
    fox = flag(a["foxglove"], "foxglove")
    try:
        fox_port = int(a["foxglove_port"]) if fox else None
    except ValueError:
        raise RuntimeError(f"launch argument foxglove_port must be a port number, got {a['foxglove_port']!r}") from None
    if fox_port is not None:  # out of range or taken: said now, as bb2-launch --foxglove says it
        check_foxglove_port(fox_port, "launch argument foxglove_port")
    check_time_mode(a["time_mode"])
    ns = check_namespace(a["namespace"], "launch argument namespace")  # (launch_ros refuses it later, in its words)
    compose = flag(a["compose"], "compose")
    groups = checked_groups(a["group"], compose, without)
    restart = checked_restart(a["restart"], groups, record, without)
    timer = wall_timeout(a["timeout"])
    overridden = overridden_by_arguments(params_file, a, stall, mission)
    # claimed last, every other check passed: a refused launch leaves no directory behind
    # (a nested namespace as bb2-launch names it: one directory, boat_a_b)
    stem = f"{mission.stem}_{time.strftime('%Y%m%d_%H%M%S')}" + (f"_{ns.replace('/', '_')}" if ns else "")
    bag = claim_bag(a["bag"], a["bag_dir"], stem) if record else None
    with released_on_error(bag):
        acts = boat(mission, time_mode=a["time_mode"], record=record, bag=bag, namespace=ns,
                    params_file=params_file, foxglove_port=fox_port, without=without, stall_timeout_s=stall,
                    groups=groups, restart=restart)
    said = LogInfo(msg=f"[bb2_bringup] mission {mission} | {a['time_mode']}"
                       + (f" | composed: {', '.join(map(process_name, groups))}" if groups else "")
                       + (f" | namespace /{ns}" if ns else "")
                       + (f" | without {', '.join(without)} (your nodes in their place)" if without else "")
                       + (f" | bag {bag}" if bag else " | not recorded")
                       + (f" | foxglove ws://127.0.0.1:{fox_port}" if fox else ""))
    return [*overridden, *([LogInfo(msg=f"[bb2_bringup] warning: {warning}")] if warning else []), said, *acts,
            *timer]


def generate_launch_description():
    return LaunchDescription([*(DeclareLaunchArgument(k, default_value=d, description=h)
                                for k, (d, h) in ARGUMENTS.items()),
                              OpaqueFunction(function=_graph)])
