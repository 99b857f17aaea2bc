"""Speed of the BB2 ROS 2 graph, measured in one run (issue 4 "Done when").

1. Lockstep: the 500 s canyon mission (``missions/canyon.yaml`` with the simulator's ``duration_s``
   set to 500) with every node and the recorder, started by the launcher's own code
   (:mod:`bb2_tools.launcher`).  Prints the real-time factor (sim seconds per wall second while
   stepping -- from the first step on, the start-up handshake at t = 0 excluded -- and including
   start-up) -- goal >= 20x -- and the message counts: what the simulator published (its step count
   from ``trajectory_csv`` and its re-send counter from the last ``/bb2/status``) against what is in
   the bag, per topic -- goal: zero lost.  And each node process's CPU per step while stepping (process and main
   thread, from the ``cpu_process_s`` / ``cpu_main_thread_s`` of its nodes' statuses): where the step goes.
2. Real time at 100 Hz (``rate_hz: 100``, 100 s of sim time = 20 s wall): a probe node takes the
   DDS source timestamps (the writer's wall clock) of ``/bb2/state_native`` and ``/bb2/planes/cmd``;
   the step period's p50/p99 of ``|period - 10 ms|`` -- goal p99 <= 1 ms -- and the sensor ->
   plane-command loop latency, source time of the mixer's command minus that of the simulator's
   state with the same stamp -- goal p99 <= 3 ms.

3. Ratios (issue 15): absolute figures do not carry from one machine to the next, so the same invocation also runs
   the library mission runner (:class:`bb2_mission.MissionRunner`, no ROS) on the same lockstep mission and prints
   graph RTF / runner RTF -- goals >= 0.5 with one process per node, >= 0.8 composed -- for each layout
   (``--layout``: ``alone`` one process per node, ``composed`` the container of ``bb2-launch --compose``,
   ``controllers`` the planner and controllers composed with the simulator alone), each
   repetition paired with its own runner run; ``--repeat N`` prints min/median/max over N.

Usage: ``python benchmarks/graph_speed.py [--out DIR] [--rt-sim-s 100] [--lockstep-sim-s 500] [--only MODE]
[--layout alone|composed|both] [--repeat N] [--normal-scheduling] [--lockstep-priority P]``
(``bash run.sh bench`` runs it with the defaults; about 3-6 minutes of wall time on 2 cores).
"""
from __future__ import annotations

import argparse
import csv
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from bb2_tools import launcher as L  # noqa: E402
from bb2_tools.graph_monitor import free_domain_id  # noqa: E402
from bb2_tools.supervisor import Supervisor  # noqa: E402
from bb2_ros.node_common import REALTIME_CONTROLLERS, take_all  # noqa: E402

TS = 0.05  # the ROM's major step (s); one simulator step per Ts of sim time


def own_node(domain_id: int, name: str):
    """(context, node): an rclpy node in a context of its own on ``domain_id`` (no rosout, no parameter services)."""
    import rclpy
    from rclpy.context import Context
    from rclpy.signals import SignalHandlerOptions

    context = Context()
    rclpy.init(context=context, domain_id=domain_id, signal_handler_options=SignalHandlerOptions.NO)
    return context, rclpy.create_node(name, context=context, enable_rosout=False, start_parameter_services=False)


class Probe:
    """An rclpy node (own context) taking the DDS source timestamps (writer's wall clock at publication) of
    the simulator's states and the mixer's plane commands, per sim-time stamp.

    It polls (a thread takes whatever is queued every 20 ms, raw, with the message info) rather than
    spinning an executor, so it does not wake a Python callback per message at the very moment the
    controllers must answer: the measurement takes as little CPU from the measured loop as it can.
    (The bag cannot give these times: the recorder's publish times are its receive times on the sim clock.)
    """

    POLL_S = 0.02

    def __init__(self, domain_id: int):
        import threading

        from rclpy.qos import HistoryPolicy
        from rclpy.serialization import deserialize_message

        from bb2_msgs_py import conversions as cv
        from bb2_msgs_py.contract import message_class, qos_profile

        self.cv, self._deserialize = cv, deserialize_message
        self.state_sends: dict[int, list[int]] = {}  # stamp -> source times of its publications (t = 0 is re-sent
        #                                               until the clock starts)
        self.cmd_src: dict[int, int] = {}
        self.hop_src: dict[str, dict[int, int]] = {"/bb2/guidance/rate_cmd": {}, "/bb2/autopilot/vh_cmd": {}}
        self.context, self.node = own_node(domain_id, "bb2_bench_probe")

        def qos(name):
            q = qos_profile(name)
            q.history, q.depth = HistoryPolicy.KEEP_LAST, 1000
            return q

        def sub(type_name, name):
            return self.node.create_subscription(message_class(type_name), name, lambda _m: None, qos(name), raw=True)

        self._subs = [(sub("std_msgs/msg/Float64MultiArray", "/bb2/state_native"), self._on_state),
                      (sub("sensor_msgs/msg/JointState", "/bb2/planes/cmd"), self._on_cmd),
                      (sub("geometry_msgs/msg/Vector3Stamped", "/bb2/guidance/rate_cmd"),
                       lambda m, i: self._on_hop("/bb2/guidance/rate_cmd", m, i)),
                      (sub("sensor_msgs/msg/JointState", "/bb2/autopilot/vh_cmd"),
                       lambda m, i: self._on_hop("/bb2/autopilot/vh_cmd", m, i))]
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._poll, daemon=True)
        self._thread.start()

    def _poll(self) -> None:
        while not self._stop.wait(self.POLL_S):
            for sub, handler in self._subs:
                for data, info in take_all(sub):
                    handler(self._deserialize(data, sub.msg_type), info)

    def _on_state(self, msg, info) -> None:
        t_ns = self.cv.seconds_to_ns(self.cv.state_native_from_message(msg).t)
        self.state_sends.setdefault(t_ns, []).append(int(info["source_timestamp"]))

    def _on_cmd(self, msg, info) -> None:
        self.cmd_src.setdefault(self.cv.stamp_to_ns(msg.header.stamp), int(info["source_timestamp"]))

    def _on_hop(self, name: str, msg, info) -> None:
        self.hop_src[name].setdefault(self.cv.stamp_to_ns(msg.header.stamp), int(info["source_timestamp"]))

    def close(self) -> None:
        import rclpy

        self._stop.set()
        self._thread.join(timeout=2.0)
        self.node.destroy_node()
        rclpy.shutdown(context=self.context)


LAYOUTS = {"alone": [], "composed": [L.COMPOSABLE],
           "controllers": [("planner", "path_following", "l1_autopilot", "mixer")]}
"""The process layouts measured: one process per node, every composable node in the container, or the planner and
the controllers composed with the simulator alone (its real-time thread keeps its interpreter to itself)."""


def run_graph_once(mission: Path, out: Path, mode: str, sim_params: dict, timeout_s: float,
                   probe=False, groups=(), node_params: dict | None = None
                   ) -> tuple[L.RunResult, float, Probe | None]:
    """Fly ``mission`` through the whole graph (recorder included); return the run result, the
    wall time from the first /clock to the end, and the probe (if asked for, closed).  ``probe``: True for a
    :class:`Probe`, or a factory of the graph's domain id giving any object with ``close()``.  ``node_params``:
    other nodes' parameters, ``{node: {name: value}}``."""
    os.environ.setdefault("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")
    os.environ.setdefault("AMENT_PREFIX_PATH", sys.prefix)
    out.mkdir(parents=True, exist_ok=True)
    params = out.parent / f"{out.name}_params.yaml"
    params.write_text(yaml.safe_dump({"simulator": {"ros__parameters": sim_params},
                                      **{n: {"ros__parameters": p} for n, p in (node_params or {}).items()}}))
    monitor = free_domain_id(end_at="simulator")
    env = dict(os.environ, ROS_DOMAIN_ID=str(monitor.domain_id), ROS_LOG_DIR=str(out / "logs" / "ros"),
               PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    specs = L.graph_specs(mission, out, mode=mode, params=params, monitor=monitor, groups=groups)
    sup = Supervisor(specs, out / "logs", env=env)
    pr = (probe if callable(probe) else Probe)(monitor.domain_id) if probe else None
    try:
        res = L.run_graph(sup, monitor, first=[s.name for s in specs if s.ready is not None],
                          timeout_s=timeout_s, status_period_s=10.0)
    finally:
        sup.stop(hurry=True)
        monitor.close()
        if pr is not None:
            pr.close()
    return res, (res.stepping_wall_s or float("nan")), pr


def last_simulator_status(reader) -> dict[str, str]:
    """The simulator's last status in the bag (its statuses come in step order: one writer, one reader)."""
    return next((vals for name, vals in reader.last_statuses().items() if "simulator" in name), {})


def stamps_and_pub_times(reader, topic: str) -> list[tuple[int, int]]:
    """(header stamp ns, publish time ns) of every message on ``topic``."""
    from rclpy.serialization import deserialize_message

    from bb2_msgs_py import conversions as cv
    from bb2_msgs_py.contract import message_class

    cls = message_class(reader.topics[topic])
    out = []
    for m in reader.raw_messages(topic):
        msg = deserialize_message(m.data, cls)
        if hasattr(msg, "header"):
            ns = cv.stamp_to_ns(msg.header.stamp)
        elif hasattr(msg, "clock"):
            ns = cv.stamp_to_ns(msg.clock)
        else:  # /bb2/state_native (Float64MultiArray): the time is in the state
            ns = cv.seconds_to_ns(cv.state_native_from_message(msg).t)
        out.append((ns, m.publish_time_ns))
    return out


def runner_summary(sim_s: float, tmp: Path):
    """The library mission runner's summary on the canyon cut at ``sim_s`` (same process, no ROS)."""
    from bb2_mission import MissionRunner, load_mission

    mission = tmp / "canyon_runner.yaml"
    mission.write_text(f"extends: {REPO / 'missions' / 'canyon.yaml'}\nduration_s: {float(sim_s)}\n")
    return MissionRunner(load_mission(mission)).run().summary


def runner_rtf(args, tmp: Path) -> float:
    """The library mission runner's real-time factor on the lockstep benchmark's mission (same process, no ROS)."""
    s = runner_summary(args.lockstep_sim_s, tmp)
    rtf = s.mission_time_s / s.wall_time_s
    print(f"library runner, same mission: {s.mission_time_s:.1f} s simulated in {s.wall_time_s:.2f} s wall: "
          f"{rtf:.1f}x")
    return rtf


def lockstep(args, tmp: Path, layout: str = "alone") -> dict:
    from bb2_tools.bagfile import BagReader

    out = tmp / f"lockstep_{layout}"
    csv_path = tmp / f"lockstep_{layout}_states.csv"
    t0 = time.monotonic()
    sim = {"duration_s": float(args.lockstep_sim_s), "trajectory_csv": str(csv_path)}
    if args.lockstep_priority:
        sim["lockstep_priority"] = args.lockstep_priority
    res, stepping_wall, _ = run_graph_once(REPO / "missions" / "canyon.yaml", out, "lockstep", sim,
                                           timeout_s=args.timeout, groups=LAYOUTS[layout])
    total_wall = time.monotonic() - t0
    print(f"lockstep canyon ({layout}): {res.reason} (exit {res.exit_code}); sim time {res.sim_time_s} s"
          + (f" (simulator at SCHED_FIFO {args.lockstep_priority})" if args.lockstep_priority else ""))
    if res.exit_code != 0:
        for e in res.exits:
            print("  " + e.report(5))
        return {}
    with open(csv_path) as fh:
        states = sum(1 for _ in csv.reader(fh)) - 1  # header
    steps = states - 1
    sim_s = steps * TS
    print(f"  real-time factor: {res.rtf_overall:.1f}x while stepping ({stepping_wall:.1f} s wall from the first "
          f"step to the end; the start-up handshake at t = 0 excluded), {sim_s / total_wall:.1f}x including "
          f"start-up and shutdown ({total_wall:.1f} s)   [goal >= 20x]")
    reader = BagReader(out)
    counts = reader.message_counts
    status = last_simulator_status(reader)
    resends = int(status.get("lockstep_resends", "0"))
    print(f"  simulator: {steps} steps, {states} states published, {resends} re-sends "
          f"(last /bb2/status step = {status.get('step')})")
    uniq = {t: len({s for s, _ in stamps_and_pub_times(reader, t)})
            for t in ("/bb2/odom", "/bb2/state_native", "/bb2/planes/cmd", "/bb2/propeller/cmd")}
    expected = {  # topic: (published by count, in the bag)
        "/clock": (states, counts.get("/clock", 0)),
        "/bb2/odom (distinct stamps)": (states, uniq["/bb2/odom"]),
        "/bb2/state_native (with re-sends)": (states + resends, counts.get("/bb2/state_native", 0)),
        "/bb2/depth": (states, counts.get("/bb2/depth", 0)),
        "/bb2/altitude": (states, counts.get("/bb2/altitude", 0)),
        "/bb2/imu": (steps, counts.get("/bb2/imu", 0)),
        "/bb2/planes/state": (steps, counts.get("/bb2/planes/state", 0)),
        "/bb2/propeller/state": (steps, counts.get("/bb2/propeller/state", 0)),
        "/bb2/planes/cmd (distinct stamps)": (states, uniq["/bb2/planes/cmd"]),
        "/bb2/propeller/cmd (distinct stamps)": (states, uniq["/bb2/propeller/cmd"]),
    }
    lost_total = 0
    for name, (pub, bag) in expected.items():
        lost = pub - bag
        lost_total += max(lost, 0)
        print(f"    {name:40s} published {pub:6d}  in bag {bag:6d}  lost {lost:5d}")
    print(f"  lost messages: {lost_total}   [goal 0]")
    print_cpu_per_step(reader)
    return {"rtf": res.rtf_overall, "lost": lost_total}


def cpu_per_step(reader, after_s: float = 1.0) -> list[tuple[str, float, float | None]]:
    """Each node process's CPU per step while the graph stepped, from its nodes' statuses (``cpu_process_s``,
    ``cpu_main_thread_s``: :func:`bb2_ros.node_common.cpu_times`) between the first one sent after ``after_s`` of
    sim time and the last one whose sim time moved on: ``(its nodes, process us per step, main thread us per step or
    None)``.  A node's steps are the simulator's ``step`` or its sim time over the step (nodes on sim time, and the
    recorder: its status is stamped on the boat's /clock)."""
    series: dict[str, list[tuple[float, float, float | None, str]]] = {}
    for _topic, _t, msg in reader.messages("/bb2/status"):
        for st in msg.status:
            v = {kv.key: kv.value for kv in st.values}
            if "cpu_process_s" not in v:
                continue
            if "step" in v:
                step = float(v["step"])
            elif v.get("use_sim_time") == "true":
                step = float(v["node_time_s"]) / TS
            else:
                continue
            main = float(v["cpu_main_thread_s"]) if "cpu_main_thread_s" in v else None
            series.setdefault(st.name, []).append((step, float(v["cpu_process_s"]), main, v["process_id"]))
    by_pid: dict[str, list[str]] = {}
    figures: dict[str, tuple[float, float | None]] = {}
    for name, rows in series.items():
        rows = [r for r in rows if r[0] * TS >= after_s]
        while len(rows) >= 2 and rows[-1][0] <= rows[-2][0]:  # sent after the end (the shutdown's CPU): left out
            rows.pop()
        if len(rows) < 2 or rows[-1][0] <= rows[0][0]:
            continue
        (s0, p0, m0, pid), (s1, p1, m1, _) = rows[0], rows[-1]
        by_pid.setdefault(pid, []).append(name.removeprefix("bb2/"))
        per = (p1 - p0) / (s1 - s0) * 1e6, (None if m0 is None or m1 is None else (m1 - m0) / (s1 - s0) * 1e6)
        if pid not in figures or "simulator" in name:  # a composed process: the simulator's account, if it holds it
            figures[pid] = per
    return [(", ".join(sorted(names)), *figures[pid]) for pid, names in by_pid.items()]


def print_cpu_per_step(reader) -> None:
    rows = cpu_per_step(reader)
    if not rows:
        return
    print("  CPU per step while stepping, per process (the nodes' from their statuses):")
    for names, proc, main in sorted(rows, key=lambda r: -r[1]):
        print(f"    {names:50s} {proc:7.0f} us" + ("" if main is None else f"  (main thread {main:5.0f} us, the "
                                                       f"middleware's threads {proc - main:5.0f} us)"))
    print(f"    {'all of them':50s} {sum(r[1] for r in rows):7.0f} us")


def realtime(args, tmp: Path, layout: str = "alone") -> dict:
    from bb2_tools.bagfile import BagReader

    out = tmp / f"realtime_{layout}"
    rate = 100.0
    params = {"duration_s": float(args.rt_sim_s), "rate_hz": rate, "realtime_loop": args.realtime_loop}
    if args.answer_first_s is not None:
        params["answer_first_s"] = args.answer_first_s
    controllers = {}
    if args.normal_scheduling:  # what a user without root gets
        params.update(realtime_priority=0, hold_cpu_dma_latency=False)
        controllers = {n: {"callback_priority": 0} for n in REALTIME_CONTROLLERS}
    if args.cpus:  # the stepping thread apart from everything else of the loop
        stepping, others = args.cpus.split(":")
        params.update(stepping_cpus=stepping, cpus=others)
        controllers = {n: {**controllers.get(n, {}), "cpus": others} for n in REALTIME_CONTROLLERS}
    res, _, probe = run_graph_once(REPO / "missions" / "canyon.yaml", out, "realtime", params, timeout_s=args.timeout,
                                   probe=True, groups=LAYOUTS[layout], node_params=controllers)
    print(f"real time at {rate:g} Hz ({layout}): {res.reason} (exit {res.exit_code}); sim time {res.sim_time_s} s"
          + (" (normal scheduling, cpu_dma_latency not held)" if args.normal_scheduling else ""))
    if res.exit_code != 0:
        return {}
    figures = {}
    stamps = sorted(probe.state_sends)
    # the stepping's periods, not the one from the state of t = 0: the simulator waits with it for the controllers'
    # first answer (wait_for_commands; re-sending it), and its clock starts when that comes, not a period later
    pubs = np.array([max(probe.state_sends[s]) for s in stamps], dtype=np.int64)
    steady = np.array([s != 0 for s in stamps[:-1]], dtype=bool)
    period_ms = np.diff(pubs)[steady] * 1e-6
    dev_ms = np.abs(period_ms - 1e3 / rate)
    print(f"  step period (DDS source timestamps of /bb2/state_native): {len(period_ms)} periods"
          f"{'' if steady.all() else ' (the start-up wait with the state of t = 0 left out)'}, mean "
          f"{period_ms.mean():.3f} ms; |period - {1e3 / rate:g} ms| p50 {np.percentile(dev_ms, 50):.3f} ms, "
          f"p99 {np.percentile(dev_ms, 99):.3f} ms, max {dev_ms.max():.3f} ms   [goal p99 <= 1 ms]")
    figures["jitter_p99_ms"] = float(np.percentile(dev_ms, 99))
    # each state's publication that its answer followed (the last before the answer, for the re-sent state of t = 0)
    state_src = {s: max([p for p in probe.state_sends[s] if p <= probe.cmd_src[s]] or probe.state_sends[s][:1])
                 if s in probe.cmd_src else probe.state_sends[s][0] for s in stamps}
    lat_ms = np.array([(probe.cmd_src[s] - state_src[s]) * 1e-6 for s in stamps if s in probe.cmd_src])
    answered = [s for s in stamps if s in probe.cmd_src]
    if answered:
        before = sum(1 for s in stamps if s < answered[0])
        after = sum(1 for s in stamps if s > answered[0] and s not in probe.cmd_src)
        print(f"  states seen by the probe from t = {stamps[0] * 1e-9:.2f} s (it matches the simulator after its "
              f"start): unanswered {before} before the first answer (t = {answered[0] * 1e-9:.2f} s; controllers still "
              f"discovering, the simulator on the failsafe), {after} after it")
    if len(lat_ms):
        print(f"  loop latency /bb2/state_native -> /bb2/planes/cmd (same stamp, source timestamps): "
              f"{len(lat_ms)}/{len(stamps)} steps answered, p50 {np.percentile(lat_ms, 50):.3f} ms, "
              f"p99 {np.percentile(lat_ms, 99):.3f} ms, max {lat_ms.max():.3f} ms   "
              f"[goal p99 <= {1 if layout == 'composed' else 3} ms]")
        figures["latency_p99_ms"] = float(np.percentile(lat_ms, 99))
        # where the loop's time goes: each node's answer, from its input's source time to its output's
        chain = [("/bb2/state_native", state_src),
                 *((name, probe.hop_src[name]) for name in ("/bb2/guidance/rate_cmd", "/bb2/autopilot/vh_cmd")),
                 ("/bb2/planes/cmd", probe.cmd_src)]
        for (a, src_a), (b, src_b) in zip(chain, chain[1:]):
            hop = np.array([(src_b[s] - src_a[s]) * 1e-6 for s in answered if s in src_a and s in src_b])
            if len(hop):
                print(f"    {a} -> {b}: p50 {np.percentile(hop, 50):.3f} ms, p99 {np.percentile(hop, 99):.3f} ms "
                      f"({len(hop)} steps)")
    reader = BagReader(out)
    status = last_simulator_status(reader)
    print(f"  simulator status: overruns {status.get('overruns')}, failsafe steps {status.get('failsafe_steps')}, "
          f"measured step rate {status.get('step_rate_hz')} Hz, stepping thread {status.get('scheduling')}, "
          f"cpu_dma_latency {status.get('cpu_dma_latency')}, CPUs: process {status.get('cpus')}, stepping thread "
          f"{status.get('stepping_cpus')}; loop {args.realtime_loop}, samples after the answer "
          f"{status.get('samples_after_answer')}, after the wait {status.get('samples_after_wait')}")
    figures["overruns"] = float(status.get("overruns", "nan"))
    figures["jitter_max_ms"] = float(dev_ms.max())
    # the garbage collector's pauses stop every thread of a process (bb2_ros.heap): each process's, from its
    # nodes' last statuses (composed nodes share one collector: the same figures under each name)
    gcs = {name.removeprefix("bb2/"): st for name, st in reader.last_statuses().items() if "gc_collections" in st}
    print("  garbage collections since spinning (count, longest pause; heap frozen at start): " + "; ".join(
        f"{n} {st['gc_collections']}, {st['gc_pause_max_ms']} ms ({st['gc_frozen_objects']} objects)"
        for n, st in sorted(gcs.items())))
    pauses = [float(st["gc_pause_max_ms"]) for st in gcs.values() if st.get("gc_pause_max_ms")]
    figures["gc_pause_max_ms"] = max(pauses) if pauses else None
    return figures


def spread(values: list[float]) -> str:
    """min / median / max of ``values`` (those measured), or what is missing."""
    v = [x for x in values if x is not None and np.isfinite(x)]
    if not v:
        return "not measured"
    return f"min {min(v):.3g} / median {float(np.median(v)):.3g} / max {max(v):.3g} (n = {len(v)})"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=None, help="keep the bags here (default: a temporary directory)")
    ap.add_argument("--lockstep-sim-s", type=float, default=500.0)
    ap.add_argument("--rt-sim-s", type=float, default=100.0)
    ap.add_argument("--timeout", type=float, default=900.0, help="wall limit per run (s)")
    ap.add_argument("--only", choices=("lockstep", "realtime"), default=None)
    ap.add_argument("--layout", choices=(*LAYOUTS, "both"), default="both",
                    help="one process per node, the nodes composed, the controllers composed (simulator alone), "
                         "or both of the first two (default)")
    ap.add_argument("--repeat", type=int, default=1, help="repetitions (min/median/max printed at the end)")
    ap.add_argument("--lockstep-priority", type=int, default=0,
                    help="lockstep with the simulator's process at this SCHED_FIFO priority (its lockstep_priority; "
                         "default 0, normal scheduling)")
    ap.add_argument("--normal-scheduling", action="store_true",
                    help="real time without the controllers' SCHED_FIFO callbacks (callback_priority 0, as in "
                         "lockstep), the simulator's SCHED_FIFO thread and its cpu_dma_latency request "
                         "(realtime_priority 0, hold_cpu_dma_latency false): what a user without root gets")
    ap.add_argument("--cpus", default=None, metavar="STEPPING:OTHERS",
                    help="real time: the simulator's stepping thread on CPU(s) STEPPING, its other threads and the "
                         "controllers' processes on OTHERS (its stepping_cpus and every loop node's cpus), e.g. 0:1")
    ap.add_argument("--realtime-loop", choices=("executor", "thread"), default="executor",
                    help="real time: the simulator steps on its executor's thread (default) or a thread of its own "
                         "(its realtime_loop)")
    ap.add_argument("--answer-first-s", type=float, default=None, metavar="S",
                    help="real time: the simulator's answer_first_s (default: the node's, 0.005; 0 = a step's other "
                         "samples go out with its state)")
    args = ap.parse_args()
    if args.cpus is not None and args.cpus.count(":") != 1:
        ap.error("--cpus takes STEPPING:OTHERS, e.g. 0:1")
    if args.repeat < 1:
        ap.error("--repeat must be >= 1")
    layouts = ["alone", "composed"] if args.layout == "both" else [args.layout]
    rows: dict[str, dict[str, list]] = {k: {} for k in layouts}
    with tempfile.TemporaryDirectory(prefix="bb2_graph_speed_") as t:
        root = args.out or Path(t)
        for rep in range(args.repeat):
            tmp = root / f"run{rep + 1}"
            tmp.mkdir(parents=True, exist_ok=True)
            print(f"=== repetition {rep + 1}/{args.repeat}")
            runner = runner_rtf(args, tmp) if args.only in (None, "lockstep") else None
            for layout in layouts:
                fig = {}
                if args.only in (None, "lockstep"):
                    lk = lockstep(args, tmp, layout)
                    fig["graph RTF (lockstep, while stepping)"] = lk.get("rtf")
                    fig["runner RTF (same mission)"] = runner
                    fig["graph / runner"] = lk["rtf"] / runner if lk.get("rtf") and runner else None
                    fig["lost messages"] = lk.get("lost")
                if args.only in (None, "realtime"):
                    rt = realtime(args, tmp, layout)
                    fig["real time 100 Hz: latency p99 (ms)"] = rt.get("latency_p99_ms")
                    fig["real time 100 Hz: jitter p99 (ms)"] = rt.get("jitter_p99_ms")
                    fig["real time 100 Hz: jitter max (ms)"] = rt.get("jitter_max_ms")
                    fig["real time 100 Hz: overruns"] = rt.get("overruns")
                    fig["real time: longest GC pause (ms)"] = rt.get("gc_pause_max_ms")
                for k, v in fig.items():
                    rows[layout].setdefault(k, []).append(v)
    goals = {"controllers": {"lost messages": "0"},
             "alone": {"graph / runner": ">= 0.5", "real time 100 Hz: latency p99 (ms)": "<= 3",
                       "real time 100 Hz: jitter p99 (ms)": "<= 1", "lost messages": "0"},
             "composed": {"graph / runner": ">= 0.8", "real time 100 Hz: latency p99 (ms)": "<= 1",
                          "real time 100 Hz: jitter p99 (ms)": "<= 1", "lost messages": "0"}}
    print(f"\n=== summary over {args.repeat} repetition(s) (each graph run paired with that repetition's runner)")
    for layout in layouts:
        print(f"{layout}:")
        for k, vals in rows[layout].items():
            goal = goals[layout].get(k)
            print(f"  {k:40s} {spread(vals)}" + (f"   [goal {goal}]" if goal else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
