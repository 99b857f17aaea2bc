"""bb2-launch FLEET.yaml: a fleet file (:mod:`bb2_mission.fleet`) flown through one ROS graph.

Every boat is the graph ``bb2-launch MISSION --namespace BOAT`` starts (its own process, a launcher of its own that
watches its boat, reports its faults and ends its run), all on one ``ROS_DOMAIN_ID``; beside them one recorder
records every boat into one bag (``bb2-record --boats``: ``/boat1/bb2/odom``, ``/boat1/clock``, one ``/tf``), which
each boat's simulator waits for as for its own (``--external-recorder``: its readers before the first step, in
lockstep its acknowledgements on ``/boat1/bb2/recorder/ack``).  The run directory ``<bag-dir>/<fleet>_<date>/``
(or ``--out``) is the fleet's bag, with ``missions/<boat>.yaml`` (every boat's mission as its nodes read it),
``logs/recorder.log``, ``logs/<boat>.log`` (each boat's launcher) and ``<boat>/logs/`` (its nodes' logs).

A boat that fails does not stop the others (they fly on; the fleet's exit code says it); the recorder failing, the
timeout, Ctrl-C or SIGTERM stop every boat, then the recorder (which finishes the bag).  Each boat's launcher's lines
are shown prefixed ``[boat1]``.  Exit codes: 0 every boat's mission complete; 1 a boat or the recorder failed or the
timeout passed; 2 bad input; 130 interrupted.
"""
from __future__ import annotations

import argparse
import os
import signal
import sys
import threading
import time
from pathlib import Path

from bb2_sim.outputs import OutputError, claim_run_dir

from bb2_tools.graph_monitor import domain_monitor
from bb2_tools.launcher import (GRAPH_NODES, RECORDER_NODE_NAME, check_params_file, check_run_options, check_without,
                                clean_after_killed, gap_lines, launcher_parameters, node_command, params_overridden,
                                recorded_topics)
from bb2_tools.supervisor import LaunchError, ProcessSpec, RestartPolicy, Supervisor, exit_cause

BOAT_STOP_GRACE_S = 60.0  # a boat's launcher stops its graph on SIGINT (its recorder-less end: seconds)
RECORDER_STOP_GRACE_S = 30.0


def _refuse(args: argparse.Namespace) -> None:
    """Options that do not apply to a fleet (one line naming them)."""
    if args.namespace:
        raise LaunchError("--namespace: a fleet file's boats are the namespaces (give the fleet file alone)")
    if args.foxglove is not None:
        raise LaunchError("--foxglove is not available for a fleet file yet (one bb2-launch --namespace per boat "
                          "serves one boat)")
    if args.external_recorder:
        raise LaunchError("--external-recorder: a fleet file's launch starts the fleet's recorder itself")
    check_without(args.without, "--without")   # every boat's nodes left out, said once before any boat starts
    check_run_options(args)


def boat_command(args: argparse.Namespace, mission: Path, boat: str, domain_id: int, run_dir: Path) -> list[str]:
    """The ``bb2-launch`` of one boat of the fleet (the options of the fleet's launch that apply to a boat)."""
    cmd = [sys.executable, "-m", "bb2_tools.launcher", str(mission), "--namespace", boat, "--domain-id",
           str(domain_id), "--out", str(run_dir / boat), "--mode", args.mode, "--end-at", args.end_at,
           "--stall-timeout", str(args.stall_timeout), "--ready-timeout", str(args.ready_timeout),
           "--runner", args.runner, "--max-restarts", str(args.max_restarts)]
    cmd.append("--no-record" if args.no_record else "--external-recorder")
    if args.params is not None:
        cmd += ["--params", str(args.params.resolve())]
    for r in args.restart:
        cmd += ["--restart", r]
    if args.without:
        cmd += ["--without", args.without]
    if args.compose:
        cmd.append("--compose")
    for g in args.group or []:
        cmd += ["--group", g]
    if args.echo:
        cmd.append("--echo")
    return cmd


FLEET_MISSIONS = "each boat's own mission"
"""What a fleet sets as every node's ``mission_file`` (said when a params file's node entry sets it otherwise)."""


def run_fleet(args: argparse.Namespace) -> int:
    """Fly the fleet file ``args.mission`` (the options of ``bb2-launch``); returns the exit code."""
    from bb2_mission.fleet import load_fleet
    from bb2_mission.schema import MissionError
    from bb2_msgs_py.contract import boat_topic

    try:
        _refuse(args)
        fleet = load_fleet(args.mission)
        if args.params is not None:
            check_params_file(args.params.resolve())
            given = launcher_parameters(Path(), args.mode, stall_timeout_s=args.stall_timeout)
            # each boat flies its own mission (written into the run directory): a node's own mission_file, which
            # would win over it for that node of every boat, is refused here, before any boat flies (each boat's
            # launcher says the /** warnings)
            given["*"] = {"mission_file": (FLEET_MISSIONS, f"the fleet file {args.mission}", "")}
            params_overridden(args.params.resolve(), given)  # a node's own entry that would win: refused up front
        recorder = next(n for n in GRAPH_NODES if n.name == RECORDER_NODE_NAME)
        rec_base = node_command(recorder, args.runner)  # one clear error before anything starts
        if args.out is not None:
            run_dir = claim_run_dir(path=args.out.resolve())
        else:
            run_dir = claim_run_dir(args.bag_dir.resolve(), f"{fleet.name}_{time.strftime('%Y%m%d_%H%M%S')}")
        missions = fleet.write_missions(run_dir / "missions")
    except (LaunchError, MissionError, OutputError) as exc:
        print(f"bb2-launch: error: {exc}", file=sys.stderr)
        return 2
    boats = list(missions)
    try:
        monitor = domain_monitor(args.domain_id)
    except LaunchError as exc:
        print(f"bb2-launch: error: {exc}", file=sys.stderr)
        return 2
    domain = monitor.domain_id
    specs = [ProcessSpec(b, boat_command(args, missions[b], b, domain, run_dir), RestartPolicy("ignore"),
                         sigint_grace_s=BOAT_STOP_GRACE_S) for b in boats]
    record = not args.no_record
    if record:
        topics = [boat_topic(t, b) for b in boats for t in recorded_topics(b)]
        rec_cmd = [*rec_base, "--out", str(run_dir), "--overwrite", "--use-sim-time", "--boats", *boats]
        specs.insert(0, ProcessSpec(RECORDER_NODE_NAME, rec_cmd, RestartPolicy("stop"), stop_stage=1,
                                    sigint_grace_s=RECORDER_STOP_GRACE_S, nice=10,
                                    ready=lambda: monitor.subscribed(RECORDER_NODE_NAME, topics)))
    say = _sayer()
    say(f"[bb2-launch] fleet {fleet.name} ({fleet.file}) | {len(boats)} boats: "
        + ", ".join(f"/{b} {missions[b].name}" for b in boats)
        + f" | mode {args.mode} | ROS_DOMAIN_ID={domain} | run {run_dir}")
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), ROS_LOG_DIR=str(run_dir / "logs" / "ros"))

    def echo(name: str, line: str) -> None:
        if name in boats or args.echo:
            say(f"[{name}] {line}")

    stop = {"signal": "", "count": 0}

    def on_signal(signum, _frame) -> None:  # a second one hurries the stop (1 s per stage)
        stop["signal"], stop["count"] = signal.Signals(signum).name, stop["count"] + 1

    previous = {}
    if threading.current_thread() is threading.main_thread():
        previous = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    sup = Supervisor(specs, run_dir / "logs", env=env, echo=echo)
    t0 = time.monotonic()
    ended: dict[str, int] = {}
    reason = ""
    try:
        if record:
            try:
                sup.start([RECORDER_NODE_NAME], ready_timeout_s=args.ready_timeout,
                          interrupted=lambda: bool(stop["signal"]))
            except LaunchError as exc:
                reason = f"the recorder did not come up: {exc}"
        if not reason and not stop["signal"] and not sup.failure:
            sup.start(boats, interrupted=lambda: bool(stop["signal"]))
        while not reason:
            for ev in sup.poll():
                if ev.name in boats:
                    ended[ev.name] = ev.returncode
                    say(f"[bb2-launch] boat /{ev.name} ended ({exit_cause(ev.returncode)}); "
                        f"{len(ended)} of {len(boats)} boats done")
                else:
                    say(f"[bb2-launch] the recorder failed ({exit_cause(ev.returncode)}): stopping every boat; "
                        f"log {ev.log_path}")
            if sup.failure is not None:
                reason = "the recorder failed"
            elif stop["signal"]:
                reason = f"interrupted ({stop['signal']})"
            elif args.timeout is not None and time.monotonic() - t0 > args.timeout:
                reason = f"timeout after {args.timeout:g} s"
            elif len(ended) == len(boats):
                reason = "every boat ended"
            else:
                time.sleep(0.1)
    finally:
        for ev in sup.stop(hurry=lambda: stop["count"] > 1):
            if ev.name in boats and ev.name not in ended:
                ended[ev.name] = ev.returncode
        monitor.close()
        for s, h in previous.items():
            signal.signal(s, h)
    clean_after_killed(sup.exits, say)  # (each boat's launcher cleans after its own nodes)
    failed = [b for b in boats if ended.get(b) != 0]
    if stop["signal"]:
        code = 130
    elif failed or reason != "every boat ended":
        code = 1
    else:
        code = 0
    for b in boats:
        line = _summary_line(run_dir / "logs" / f"{b}.log")
        say(f"[bb2-launch] /{b}: {line or exit_cause(ended.get(b))}")
    said = "stopped before the end" if stop["signal"] or reason.startswith("timeout") else "failed"
    say(f"[bb2-launch] fleet {fleet.name}: {reason}" + (f" ({', '.join(failed)} {said})" if failed else "")
        + f", wall {time.monotonic() - t0:.1f} s, exit code {code}")
    if record and (run_dir / "metadata.yaml").is_file():
        say(f"[bb2-launch] bag:   {run_dir} (every boat; bb2-analyze {run_dir})")
        for line in gap_lines(run_dir):
            say(f"[bb2-launch]        {line}")
    elif record:
        say(f"[bb2-launch] no finished bag in {run_dir} (see {run_dir / 'logs' / 'recorder.log'})")
    say(f"[bb2-launch] logs:  {run_dir / 'logs'}")
    return code


def _summary_line(log: Path) -> str:
    """A boat launcher's closing line (``mission complete: sim time ..., exit code 0``), '' if none."""
    try:
        lines = log.read_text(errors="replace").splitlines()
    except OSError:
        return ""
    done = [ln.split("[bb2-launch] ", 1)[1] for ln in lines if "[bb2-launch] " in ln and ", exit code " in ln]
    return done[-1] if done else ""


def _sayer():
    lock = threading.Lock()

    def say(msg: str) -> None:
        with lock:
            print(msg, file=sys.stderr, flush=True)

    return say
