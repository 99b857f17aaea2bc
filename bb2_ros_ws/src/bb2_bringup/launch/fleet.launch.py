"""Several BB2 boats in one launch: ``ros2 launch bb2_bringup fleet.launch.py boats:=boat1,boat2 [argument:=value]``
or ``fleet:=canyon_pair|FILE`` (a fleet file: every boat with its own mission, :mod:`bb2_mission.fleet`).

Each boat is the graph of ``bb2_graph.launch.py`` in its own namespace (nodes /boat1/simulator ..., topics
/boat1/bb2/odom ..., its own /boat1/clock), so the boats fly side by side without crosstalk, each in lockstep
with its own controllers (deterministic: a boat's run equals the same mission flown alone).  Arguments:

  fleet        '' or a fleet file (a shipped fleet's name, share/bb2_bringup/missions/fleets/, or a file): its boats
               and their missions (each boat's mission written to <bag>/missions/<boat>.yaml); replaces boats, missions
  boats        comma-separated namespaces (default boat1,boat2)
  missions     one mission (name or file) for every boat, or one per boat, comma-separated (default canyon)
  time_mode    lockstep | realtime
  record       true | false: one bag of every boat, <bag_dir>/<fleet>_<date>[_2 ...: the first free one] (its
               topics /boat1/bb2/odom ...; ``bb2-analyze`` of it reports every boat)
  bag_dir      default bags
  params_file  the graph's params file
  without      '' or NODE[,NODE...]: those nodes of every boat are not started, yours answer in their place in
               each boat's namespace (as in bb2_graph.launch.py)
  stall_timeout  wall s (default 60; 0 = never) of stepping on the failsafe after which a boat's simulator stops
               its run as stalled (an error: the launch fails once every boat has ended; bb2_graph.launch.py)
  compose      true | false: each boat's planner, controllers and simulator in one container process of its own
               (container_boat1 ...; bb2-launch FLEET --compose), the fleet's recorder alone
  group        '' or NODE,NODE[,...][;NODE,NODE...]: each boat's groups of nodes in container processes of its own
               (e.g. group:=path_following,l1_autopilot,mixer: every boat's control loop in one process), as in
               bb2_graph.launch.py (bb2-launch FLEET --group)
  timeout      '' or wall s: a fleet not ended by then is stopped (every node, the bag finished), the launch fails
  restart      '' or NODE=POLICY[,...]: what the death of a boat's node (or the fleet's recorder) before its run's end
               does, for every boat: stop (default), restart[:N] or ignore, as in bb2_graph.launch.py

The launch ends when every boat's simulator has ended its run, with exit code 1 when any boat's simulator exited
with an error (the other boats fly on to their end); a boat's other nodes stop when its simulator ends; any other
node of a boat, or the fleet's recorder, that dies before its run's end stops every boat and fails the launch (as in
bb2_graph.launch.py).  Every boat's mission, the params file and the names are checked before any node starts.  Not
recorded, a fleet file's missions are written to a temporary folder, removed as the launch ends.  Ctrl-C stops
every node cleanly.
"""
from __future__ import annotations

import importlib.util
import shutil
import tempfile
import time
from pathlib import Path

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, EmitEvent, LogInfo, OpaqueFunction, RegisterEventHandler
from launch.event_handlers import OnProcessExit, OnShutdown
from launch.events import Shutdown
from launch.substitutions import LaunchConfiguration

from bb2_mission.fleet import load_fleet

_spec = importlib.util.spec_from_file_location("bb2_graph_launch", Path(__file__).with_name("bb2_graph.launch.py"))
graph = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(graph)

ARGUMENTS = {
    "fleet": ("", "'' or a fleet file (shipped name or file): its boats and their missions, instead of boats/missions"),
    "boats": ("boat1,boat2", "comma-separated namespaces, one boat each"),
    "missions": ("canyon", "one mission (name or file) for all, or one per boat, comma-separated"),
    "time_mode": ("lockstep", "lockstep | realtime"),
    "record": ("true", "true | false: one bag of every boat, <bag_dir>/fleet_<date>"),
    "bag_dir": ("bags", "where the fleet's bags go"),
    "params_file": (graph.ARGUMENTS["params_file"][0], "the graph's ROS 2 params file"),
    "without": ("", "'' or NODE[,NODE...]: every boat's nodes left out, yours in their place (bb2_graph.launch.py)"),
    "stall_timeout": graph.ARGUMENTS["stall_timeout"],
    "compose": ("false", "true | false: each boat's planner, controllers and simulator in one container process"),
    "group": graph.ARGUMENTS["group"],
    "restart": graph.ARGUMENTS["restart"],
    "timeout": graph.ARGUMENTS["timeout"],
}


def _fleet(context):
    a = {k: LaunchConfiguration(k).perform(context) for k in ARGUMENTS}
    record = graph.flag(a["record"], "record")
    fleet = load_fleet(fleet_file(a["fleet"])) if a["fleet"].strip() else None
    name = fleet.name if fleet is not None else "fleet"
    if fleet is None:
        boats = [graph.check_namespace(b, "launch argument boats: a boat") for b in a["boats"].split(",") if b.strip()]
        if not boats or len(set(boats)) != len(boats):
            raise RuntimeError(f"launch argument boats must name distinct namespaces, got {a['boats']!r}")
        missions = [m.strip() for m in a["missions"].split(",") if m.strip()]
        if len(missions) == 1:
            missions *= len(boats)
        if len(missions) != len(boats):
            raise RuntimeError(f"launch argument missions: {len(missions)} missions for {len(boats)} boats (give one "
                               "mission for all the boats, or one per boat)")
    graph.check_time_mode(a["time_mode"])
    params_file = graph.checked_params_file(a["params_file"])
    without = graph.check_without(a["without"], "launch argument without")
    stall = graph.check_stall_timeout(a["stall_timeout"], "launch argument stall_timeout")
    groups = graph.checked_groups(a["group"], graph.flag(a["compose"], "compose"), without)
    # the process of each boat that holds its simulator (its exit is the boat's end)
    holder = graph.process_of("simulator", groups)
    restart = graph.checked_restart(a["restart"], groups, record, without)
    timer = graph.wall_timeout(a["timeout"])
    overridden = graph.overridden_by_arguments(params_file, a, stall)
    # the bag directory, claimed as bb2-launch claims its run directory (fleet_<date>, _2 ... when taken)
    root = graph.claim_bag("", a["bag_dir"], f"{name}_{time.strftime('%Y%m%d_%H%M%S')}") if record else None
    # not recorded, a fleet file's missions go to a folder of their own, removed as the launch ends
    scratch = Path(tempfile.mkdtemp(prefix=f"{name}_")) if root is None and fleet is not None else None
    with graph.released_on_error(root or scratch):
        if fleet is not None:  # every boat's mission as a file of its own, kept with the bag (the nodes read it)
            files = fleet.write_missions(root / "missions" if root is not None else scratch)
            boats, missions = list(files), [str(f) for f in files.values()]
        checked = [(ns, graph.mission_file(m)) for ns, m in zip(boats, missions)]
        warnings = [(ns, graph.check_mission(mission)) for ns, mission in checked]  # every boat's, before any starts
        actions, sims = overridden, []
        ended: set[int] = set()
        if record:
            recorder = graph.fleet_recorder(root, boats)
            actions += [LogInfo(msg=f"[bb2_bringup] fleet bag {root}"), recorder,
                        graph.watch(recorder, "the fleet's recorder", lambda: len(ended) == len(sims),
                                    policy=restart.get("recorder"))]
        for (ns, mission), (_ns, warning) in zip(checked, warnings):
            acts = graph.boat(mission, time_mode=a["time_mode"], record=record, bag=None, namespace=ns,
                              params_file=params_file, stop_launch=False, own_recorder=False, without=without,
                              stall_timeout_s=stall, groups=groups, restart=restart)
            sims.append(acts[-1])
            actions += [LogInfo(msg=f"[bb2_bringup] boat /{ns}: mission {mission}"
                                + (f" | composed: {', '.join(map(graph.process_name, groups))}" if groups else "")),
                        *([LogInfo(msg=f"[bb2_bringup] warning: /{ns}: {warning}")] if warning else []), *acts]
    failed: list[str] = []
    names = {id(sim): ns for sim, ns in zip(sims, boats)}

    def on_exit(event, context):
        ended.add(id(event.action))
        ns = names.get(id(event.action), "?")
        if event.returncode != 0 and not context.is_shutdown:
            failed.append(f"/{ns} (code {event.returncode})")
        out = [LogInfo(msg=f"[bb2_bringup] /{ns}/{holder} exited "
                           f"(code {event.returncode}); {len(ended)} of {len(sims)} boats done")]
        if len(ended) == len(sims):
            if failed:  # the other boats flew on; an exception is how ``ros2 launch`` exits non-zero
                out.append(graph.fail(f"{len(failed)} of {len(sims)} boats' runs failed: the {holder} of "
                                      f"{', '.join(failed)} exited with an error (its log above says why)"))
            else:
                out.append(EmitEvent(event=Shutdown(reason="every boat ended its run")))
        return out

    for sim in sims:
        actions.append(RegisterEventHandler(OnProcessExit(target_action=sim, on_exit=on_exit)))
    if scratch is not None:  # (the nodes read their missions as they start)
        actions.append(RegisterEventHandler(OnShutdown(on_shutdown=lambda _event, _context: shutil.rmtree(
            scratch, ignore_errors=True))))
    return actions + timer


def fleet_file(value: str) -> Path:
    """A shipped fleet's name (share/bb2_bringup/missions/fleets/NAME.yaml) or a fleet file."""
    return graph.installed_or_file(value, graph.SHARE / "missions" / "fleets", "fleet")


def generate_launch_description():
    return LaunchDescription([*(DeclareLaunchArgument(k, default_value=d, description=h)
                                for k, (d, h) in ARGUMENTS.items()),
                              OpaqueFunction(function=_fleet)])
