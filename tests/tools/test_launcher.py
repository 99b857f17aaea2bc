"""bb2-launch: process supervision with real processes and real DDS on an isolated domain.

The supervised nodes are small throwaway rclpy scripts written into tmp_path (so these tests do
not depend on the BB2 nodes); a driver script runs :func:`bb2_tools.launcher.run_graph` exactly
as ``bb2-launch`` does, in its own process, so signals reach it as they would from a terminal.
"""
from __future__ import annotations

import importlib.util
import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

from bb2_tools import graph_monitor as M
from bb2_tools import launcher as L
from bb2_tools import supervisor as S

from rosenv import claimed_domain, ros_env  # noqa: E402  (tests/rosenv.py)

REPO = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.slow(seconds=230)  # started first (tests/conftest.py)

FAKE_NODE = r'''
"""Throwaway rclpy node: ticks at 50 Hz, optionally publishes /clock and mission progress,
optionally crashes; writes <name>.pid / .attempts / .clean into --dir."""
import argparse, os, time
from pathlib import Path
import rclpy
from rclpy.executors import ExternalShutdownException

p = argparse.ArgumentParser()
p.add_argument("--name", required=True)
p.add_argument("--dir", type=Path, required=True)
p.add_argument("--clock", action="store_true")
p.add_argument("--clock-for", type=float, default=None)  # the clock stands still after this many wall seconds
p.add_argument("--progress-s", type=float, default=0.0)
p.add_argument("--crash-after", type=float, default=0.0)
p.add_argument("--crash-on-file", type=Path, default=None)  # crash once this file exists
p.add_argument("--crash-attempts", type=int, default=1)
p.add_argument("--exit-code", type=int, default=3)
a, _ = p.parse_known_args()
attempts = a.dir / f"{a.name}.attempts"
attempt = int(attempts.read_text()) if attempts.exists() else 0
attempts.write_text(str(attempt + 1))
rclpy.init()
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64
from bb2_msgs_py.contract import qos_profile
node = rclpy.create_node(f"fake_{a.name}")
clock = node.create_publisher(Clock, "/clock", qos_profile("/clock")) if a.clock else None
prog = (node.create_publisher(Float64, "/bb2/mission/progress", qos_profile("/bb2/mission/progress"))
        if a.progress_s else None)
t0 = time.monotonic()
ticks = 0
def tick():
    global ticks
    ticks += 1
    el = time.monotonic() - t0
    if a.clock_for is not None:
        el = min(el, a.clock_for)
    if ticks % 10 == 0:
        print(f"fake {a.name}: tick {ticks} attempt {attempt}"
              + (f" clock readers {clock.get_subscription_count()}" if clock else ""), flush=True)
    if clock:
        m = Clock(); m.clock.sec = int(el * 10); m.clock.nanosec = int((el * 10 % 1) * 1e9)
        clock.publish(m)
    if prog:
        prog.publish(Float64(data=min(1.0, el / a.progress_s)))
    due = a.crash_after and el > a.crash_after or a.crash_on_file is not None and a.crash_on_file.exists()
    if due and attempt < a.crash_attempts:
        print(f"fake {a.name}: crashing with {a.exit_code}", flush=True)
        os._exit(a.exit_code)
node.create_timer(0.02, tick)
(a.dir / f"{a.name}.pid.tmp").write_text(str(os.getpid()))
os.replace(a.dir / f"{a.name}.pid.tmp", a.dir / f"{a.name}.pid")   # whole when it appears: the test reads it then
print(f"fake {a.name}: up", flush=True)
try:
    rclpy.spin(node)
except (KeyboardInterrupt, ExternalShutdownException):
    pass
(a.dir / f"{a.name}.clean").write_text("clean")
print(f"fake {a.name}: clean shutdown", flush=True)
'''

DRIVER = r'''
"""Runs bb2_tools.launcher.run_graph on the graph described by a JSON file (as bb2-launch does)."""
import json, sys
from pathlib import Path
from bb2_tools.graph_monitor import GraphMonitor
from bb2_tools.launcher import run_graph
from bb2_tools.supervisor import ProcessSpec, RestartPolicy, Supervisor

cfg = json.loads(Path(sys.argv[1]).read_text())
mon = GraphMonitor(cfg["domain"])
if cfg.get("stepping_file"):  # said once the launcher's monitor has seen the graph step (a test's node may crash)
    import threading, time

    def say_stepping():
        while not mon.stepping_started:
            time.sleep(0.05)
        Path(cfg["stepping_file"]).write_text("stepping")
    threading.Thread(target=say_stepping, daemon=True).start()
specs = []
for s in cfg["nodes"]:
    ready = None
    if s.get("ready_node"):
        ready = (lambda n=s["ready_node"], t=s["ready_topics"]: mon.subscribed(n, t))
    specs.append(ProcessSpec(s["name"], s["cmd"], RestartPolicy(*s.get("policy", ["stop"])),
                             stop_stage=s.get("stage", 0), ready=ready, sigint_grace_s=s.get("grace", 10.0)))
sup = Supervisor(specs, cfg["logs"], restart_delay_s=0.2)
try:
    res = run_graph(sup, mon, first=cfg.get("first", []), timeout_s=cfg.get("timeout"), status_period_s=1.0,
                    stall_timeout_s=cfg.get("stall"), ready_timeout_s=cfg.get("ready", 30.0))
finally:
    sup.stop(hurry=True)
    mon.close()
print("RESULT " + json.dumps({"code": res.exit_code, "reason": res.reason,
      "exits": [[e.name, e.returncode, e.action, e.attempt] for e in res.exits],
      "sim_time": res.sim_time_s, "progress": res.progress}), flush=True)
sys.exit(res.exit_code)
'''


# ------------------------------------------------------------------------ fast unit tests (no DDS)
def test_restart_policies_parse_and_reject_bad_input():
    nodes = ["simulator", "recorder", "mixer"]
    pol = S.parse_restart_policies(["simulator=stop,recorder=restart:5", "mixer=ignore"], nodes)
    assert pol["recorder"] == S.RestartPolicy("restart", 5)
    assert pol["simulator"].action == "stop" and pol["mixer"].action == "ignore"
    assert S.parse_restart_policies(["all=restart"], nodes, default_max=2)["mixer"] == S.RestartPolicy("restart", 2)
    for bad in ("simulator", "bogus=stop", "mixer=explode", "mixer=ignore:3", "mixer=restart:x", "mixer=restart:-1"):
        with pytest.raises(S.LaunchError):
            S.parse_restart_policies([bad], nodes)
    with pytest.raises(S.LaunchError, match="--max-restarts must be >= 0"):
        S.parse_restart_policies([], nodes, default_max=-1)
    # each says which item, and the likely name of a misspelt node or policy (as --without and --group do)
    for bad, said in (("mixr=stop", "--restart: unknown node 'mixr' (did you mean 'mixer'?); nodes: simulator, "
                                    "recorder, mixer (or all)"),
                      ("mixer=resart", "--restart mixer=resart: unknown policy 'resart' (did you mean 'restart'?); "
                                       "policies: stop, restart, ignore"),
                      ("mixer=restart:-1", "--restart mixer=restart:-1: the restart count must be >= 0, got -1")):
        with pytest.raises(S.LaunchError) as exc:
            S.parse_restart_policies([bad], nodes)
        assert str(exc.value) == said
    with pytest.raises(L.LaunchError) as exc:
        L.compose_groups(["path_following,mixr"])
    assert str(exc.value).startswith("--group: unknown node 'mixr' (did you mean 'mixer'?); composable: ")
    assert S.uses_default_max(["simulator=stop, mixer=restart"]) and not S.uses_default_max(["mixer=restart:2"])
    assert not S.uses_default_max([]) and not S.uses_default_max(["all=ignore"])


def test_python_runner_builds_entry_point_commands():
    for node in L.GRAPH_NODES:
        cmd = L.node_command(node, "python")
        assert cmd[0] == sys.executable and cmd[1] == "-c"
        assert f"from bb2_ros.entry import run; sys.exit(run({node.entry_point!r}))" in cmd[2]
    with pytest.raises(S.LaunchError):
        L.node_command(L.GRAPH_NODES[0], "nonsense")


def test_graph_specs_pass_mission_mode_params_and_sim_time(tmp_path):
    mission, params, run = tmp_path / "m.yaml", tmp_path / "p.yaml", tmp_path / "bags" / "run"
    specs = L.graph_specs(mission, run, mode="realtime", params=params, runner="python",
                          policies={"recorder": S.RestartPolicy("restart", 2)})
    names = [s.name for s in specs]
    assert names[0] == "recorder" and names[-1] == "simulator"
    assert set(names) == {n.name for n in L.GRAPH_NODES}
    by = {s.name: s for s in specs}
    sim = by["simulator"].argv(0)
    # the params file first: for '/**' keys the last source wins, so the launcher's -p values must follow it
    assert sim[sim.index("--ros-args") + 1:] == ["--params-file", str(params), "-p", f"mission_file:={mission}",
                                                 "-p", "time_mode:=realtime", "-p", "wait_for_readers:=true",
                                                 "-p", "wait_for_commands:=true",
                                                 "-p", f"callback_priority:={L.CALLBACK_PRIORITY_REALTIME}"]
    # lockstep with a recorder: the simulator also waits for the recorder's acknowledgement (issue 10)
    lock = {s.name: s for s in L.graph_specs(mission, run, mode="lockstep", runner="python")}["simulator"].argv(0)
    assert f"recorder_ack_window:={L.RECORDER_ACK_WINDOW}" in lock and L.RECORDER_ACK_WINDOW > 0
    assert not [a for a in lock if "wait_for_commands" in a or "callback_priority" in a]  # lockstep: none of these
    bare = {s.name: s for s in L.graph_specs(mission, run, mode="lockstep", runner="python", record=False)}
    assert not [a for a in bare["simulator"].argv(0) if "recorder_ack_window" in a or "wait_for_readers" in a]
    assert not [a for a in lock if "stall_timeout_s" in a]   # not given: a params file's, else never
    # bb2-launch's --stall-timeout is the simulator's own (0 too: never, over a params file's)
    for stall, said in ((60.0, "stall_timeout_s:=60.0"), (0.0, "stall_timeout_s:=0.0")):
        sim = {s.name: s for s in L.graph_specs(mission, run, runner="python", stall_timeout_s=stall)}["simulator"]
        assert said in sim.argv(0), sim.argv(0)
    # a restarted path_following rejoins the run where it stands (issue 10, point 3); the first attempt does not
    pf = by["path_following"]
    assert "rejoin_run:=true" not in pf.argv(0) and pf.argv(1)[-2:] == ["-p", "rejoin_run:=true"]
    assert not [a for a in by["l1_autopilot"].argv(1) if "rejoin" in a]
    assert by["simulator"].finishes_graph
    for n in ("planner", "path_following", "l1_autopilot", "mixer"):
        assert "use_sim_time:=true" in by[n].argv(0) and f"mission_file:={mission}" in by[n].argv(0)
    rec = by["recorder"]
    assert rec.stop_stage > max(s.stop_stage for s in specs if s.name != "recorder")
    assert rec.argv(0)[rec.argv(0).index("--out") + 1] == str(run)
    assert rec.argv(1)[rec.argv(1).index("--out") + 1] == str(run.with_name("run_r1"))  # never overwrite
    assert rec.policy == S.RestartPolicy("restart", 2)
    assert "recorder" not in [s.name for s in L.graph_specs(mission, run, record=False, runner="python")]


def test_a_namespaced_boat_runs_every_node_in_its_namespace_with_its_own_clock(tmp_path, capsys):
    """``--namespace NAME`` (issue 13, point 4): every node -- the recorder and the Foxglove server too -- gets
    ``-r __ns:=/NAME -r /clock:=/NAME/clock`` (the nodes name their other topics relative to the namespace); the
    recorder's readiness is read on the boat's resolved topics, /diagnostics (every boat's) left out; a name that
    is not a ROS 2 namespace is refused before anything starts."""
    asked = []

    class FakeMonitor:
        def subscribed(self, node, topics):
            asked.append((node, list(topics)))
            return True

    ns_args = ["-r", "__ns:=/boat1", "-r", "/clock:=/boat1/clock"]
    specs = L.graph_specs(tmp_path / "m.yaml", tmp_path / "run", mode="lockstep", runner="python",
                          monitor=FakeMonitor(), groups=[("path_following", "l1_autopilot")], foxglove_port=8765,
                          namespace="/boat1/")
    for spec in specs:
        argv = spec.argv(0)
        per_node = argv.count("--node") or 1  # a composed process: each node's own ROS arguments
        assert sum(argv[i:i + 4] == ns_args for i in range(len(argv))) == per_node, (spec.name, argv)
    by = {s.name: s for s in specs}
    assert by["recorder"].ready()
    ((node, topics),) = asked
    assert node == "recorder" and "/boat1/bb2/odom" in topics and "/boat1/clock" in topics
    assert "/diagnostics" not in topics and not [t for t in topics if t.startswith("/bb2/")]
    alone = {s.name: s.argv(0) for s in L.graph_specs(tmp_path / "m.yaml", tmp_path / "run", runner="python")}
    assert not [a for argv in alone.values() for a in argv if "__ns" in a or "/clock:=" in a]
    assert L.check_namespace("fleet/boat_2") == "fleet/boat_2"
    good = tmp_path / "m.yaml"
    good.write_text("name: x\n")
    for bad in ("1boat", "boat 1", "boat-1", "a//b"):
        with pytest.raises(S.LaunchError, match="--namespace must be a ROS 2 namespace"):
            L.check_namespace(bad)
        assert L.main([str(good), "--namespace", bad]) == 2
        assert "--namespace must be a ROS 2 namespace" in capsys.readouterr().err


def test_lockstep_start_everything_at_once_the_simulator_waits_for_the_recorder(tmp_path):
    class FakeMonitor:
        def subscribed(self, node, topics):
            return node == "recorder"

    specs = L.graph_specs(tmp_path / "m.yaml", tmp_path / "run", mode="lockstep", runner="python",
                          monitor=FakeMonitor())
    by = {s.name: s for s in specs}
    assert [s.name for s in specs][0] == "recorder" and by["recorder"].ready is not None and by["recorder"].ready()
    # every other node starts at once (run_graph: early); the simulator publishes its first state only once
    # every topic it publishes has a reader (the recorder)
    assert [s.name for s in specs if s.early] == ["planner", "path_following", "l1_autopilot", "mixer", "simulator"]
    assert all(s.ready is None for s in specs[1:])
    assert "wait_for_readers:=true" in by["simulator"].argv(0)
    # no recorder: nothing to wait for
    specs = L.graph_specs(tmp_path / "m.yaml", tmp_path / "run", mode="lockstep", runner="python", record=False)
    assert "wait_for_readers:=true" not in {s.name: s for s in specs}["simulator"].argv(0)
    # real time: the simulator starts last, after the recorder is ready (it steps from its first tick)
    specs = L.graph_specs(tmp_path / "m.yaml", tmp_path / "run", mode="realtime", runner="python",
                          monitor=FakeMonitor())
    assert [s.name for s in specs if not s.early] == ["recorder", "simulator"]
    assert [s.name for s in specs][-1] == "simulator"


def test_run_graph_starts_early_nodes_before_the_gated_ones_are_ready(tmp_path):
    """An early spec runs while the first gated spec waits for readiness: here the gate is only ready once
    the early process has written its file (without 'early' it would never start: start-up timeout)."""
    flag = tmp_path / "early_ran"
    py = sys.executable
    early = S.ProcessSpec("early", [py, "-c", f"import pathlib, time; pathlib.Path({str(flag)!r}).touch(); "
                                              "time.sleep(30)"], early=True)
    gated = S.ProcessSpec("gated", [py, "-c", "import time; time.sleep(30)"], ready=flag.exists)
    last = S.ProcessSpec("last", [py, "-c", "import sys; sys.exit(0)"], finishes_graph=True)
    sup = S.Supervisor([gated, early, last], tmp_path / "logs")
    try:
        t0 = time.monotonic()
        res = L.run_graph(sup, None, first=["gated"], ready_timeout_s=15.0, timeout_s=30.0, handle_signals=False)
    finally:
        sup.stop(hurry=True)
    assert flag.exists() and res.exit_code == 0, res
    assert res.reason == "node 'last' finished (exit code 0)"
    assert time.monotonic() - t0 < 15.0


@pytest.mark.parametrize("text, said", [
    ("/**:\n  ros__parameters:\n    rate_hzz: 5.0\n",
     "/**: parameter 'rate_hzz' is declared by no node of the graph (did you mean 'rate_hz'?); ROS would ignore it"),
    ("simulatr:\n  ros__parameters:\n    rate_hz: 5.0\n", "'simulatr' is no node of the graph (did you mean "
                                                          "'simulator'?); nodes: planner, path_following"),
    ("recorder:\n  ros__parameters:\n    chunk_sise: 5\n",
     "recorder: parameter 'chunk_sise' is declared by no recorder (did you mean 'chunk_size'?)"),
])
def test_a_params_file_naming_what_no_node_declares_is_refused(tmp_path, text, said):
    """ROS ignores a parameter no node declares: a typo in a params file flew the mission on the defaults."""
    params = tmp_path / "p.yaml"
    params.write_text(text)
    with pytest.raises(L.LaunchError) as e:
        L.check_params_file(params)
    assert said in str(e.value), str(e.value)


def test_the_graphs_own_params_files_and_ros_own_parameters_pass(tmp_path):
    for f in (REPO / "config" / "bb2_graph.yaml", REPO / "examples" / "hil" / "simulator_hil.yaml"):
        L.check_params_file(f)
    ok = tmp_path / "ok.yaml"
    ok.write_text("/**:\n  ros__parameters:\n    use_sim_time: true\n    qos_overrides:\n      /bb2/odom:\n"
                  "        publisher: {depth: 5}\n/boat1/simulator:\n  ros__parameters:\n    rate_hz: 5.0\n"
                  "/**/mixer:\n  ros__parameters:\n    callback_priority: 0\nrecorder:\n  ros__parameters:\n"
                  "    chunk_size: 1000\n    batch_period_s: 0.0\n")
    L.check_params_file(ok)


def test_a_params_file_value_the_launcher_sets_otherwise_is_named_or_refused(tmp_path, monkeypatch):
    """ROS takes the launcher's ``-p time_mode:=lockstep`` over a params file's ``/**`` ``time_mode: realtime``
    without a word: a warning names the option that wins.  A node's own entry wins over the launcher's ``-p`` (rcl
    applies it after every ``/**`` value: a simulator in real time beside controllers in lockstep): refused.  A
    value equal to the graph's default (a copy of the shipped file) or to the launcher's is neither."""
    monkeypatch.chdir(tmp_path)
    canyon = REPO / "missions" / "canyon.yaml"
    given = L.launcher_parameters(canyon, "lockstep")
    assert L.params_overridden(REPO / "config" / "bb2_graph.yaml", given) == []
    mine = tmp_path / "mine.yaml"
    mine.write_text("/**:\n  ros__parameters:\n    time_mode: realtime\n    stall_timeout_s: 5.0\n"
                    "    mission_file: missions/circle.yaml\n    rate_hz: 10.0\n")
    assert L.params_overridden(mine, given) == [
        f"params file {mine}: /**: time_mode 'realtime' is overridden by --mode lockstep",
        f"params file {mine}: /**: mission_file 'missions/circle.yaml' is overridden by the mission bb2-launch flies "
        f"({canyon})"]
    launch_given = L.launcher_parameters(canyon, "lockstep", {"mission": "canyon", "time_mode": "lockstep",
                                                              "stall_timeout": "60"}, 60.0)
    assert L.params_overridden(mine, launch_given)[1] == (f"params file {mine}: /**: stall_timeout_s 5.0 is "
                                                          "overridden by launch argument stall_timeout:=60")
    for stall in (60.0, 0.0):   # bb2-launch's --stall-timeout, 0 (never) included
        assert L.params_overridden(mine, L.launcher_parameters(canyon, "lockstep", stall_timeout_s=stall))[1] == (
            f"params file {mine}: /**: stall_timeout_s 5.0 is overridden by --stall-timeout {stall:g}")
    (tmp_path / "missions").symlink_to(REPO / "missions")
    for entry, why in (("/boat1/simulator:\n  ros__parameters:\n    time_mode: realtime\n",
                        "/boat1/simulator: time_mode 'realtime' conflicts with --mode lockstep, which sets it to "
                        "'lockstep' for the graph (a node's own entry would win over it for that node alone): choose "
                        "it with --mode and remove it from the file"),
                       ("simulator:\n  ros__parameters:\n    mission_file: missions/circle.yaml\n",
                        "simulator: mission_file 'missions/circle.yaml' conflicts with the mission bb2-launch flies"),
                       ("/**/mixer:\n  ros__parameters:\n    use_sim_time: false\n",
                        "/**/mixer: use_sim_time False conflicts with bb2-launch (the graph runs on the simulator's "
                        "clock), which sets it to True for the graph (a node's own entry would win over it for that "
                        "node alone): leave it out and remove it from the file")):
        mine.write_text(entry)
        with pytest.raises(L.LaunchError) as e:
            L.params_overridden(mine, given)
        assert str(e.value).startswith(f"params file {mine}: {why}"), str(e.value)
    # a node's own entry with the launcher's value (the same mission file named otherwise) is no conflict
    mine.write_text("simulator:\n  ros__parameters:\n    mission_file: missions/canyon.yaml\n"
                    "    time_mode: lockstep\n    use_sim_time: false\nplanner:\n  ros__parameters:\n"
                    "    use_sim_time: true\n")
    assert L.params_overridden(mine, given) == []


def test_bad_input_exits_2_with_one_clear_message(tmp_path, capsys):
    assert L.main([str(tmp_path / "missing.yaml")]) == 2
    assert "does not exist" in capsys.readouterr().err
    bad = tmp_path / "bad.yaml"
    bad.write_text("a: [1, 2\n")
    assert L.main([str(bad)]) == 2
    assert "not valid YAML" in capsys.readouterr().err
    good = tmp_path / "m.yaml"
    good.write_text("name: x\n")
    params = tmp_path / "p.yaml"
    params.write_text("simulator:\n  rate_hz: 100\n")
    assert L.main([str(good), "--params", str(params)]) == 2
    assert "ros__parameters" in capsys.readouterr().err
    assert L.main([str(good), "--restart", "nosuchnode=stop"]) == 2
    assert "unknown node" in capsys.readouterr().err
    assert L.main([str(good), "--domain-id", "999"]) == 2
    assert "--domain-id" in capsys.readouterr().err
    assert L.main([str(good)]) == 2  # a mission without a path: the mission loader's own message
    assert str(good) in capsys.readouterr().err


def test_check_mission_warns_of_a_sea_steeper_than_any_wave(tmp_path):
    m = tmp_path / "steep.yaml"
    m.write_text(f"extends: {REPO / 'missions' / 'straight.yaml'}\nsea: {{spectrum: jonswap, hs: 30, tp: 9}}\n")
    assert "Hs / Lp = 30 / 126 m = 0.237, steeper than any deep-water wave" in L.check_mission(m)
    m.write_text(f"extends: {REPO / 'missions' / 'straight.yaml'}\nsea: {{spectrum: jonswap, hs: 3, tp: 9}}\n")
    assert L.check_mission(m) == ""


def test_format_status_and_exit_causes():
    line = M.format_status(12.5, 0.25, 31.0, 5, 6, 3.0)
    assert "12.50 s" in line and "25.0 %" in line and "31.0x" in line and "5/6" in line
    assert "--" in M.format_status(None, None, None, 0, 6, 0.0)
    assert S.exit_cause(-9) == "killed by SIGKILL" and S.exit_cause(3) == "exit code 3"


def test_caught_up_takes_an_ack_at_zero_as_an_ack_and_says_a_recorder_that_never_acks():
    """The end-of-run wait for the recorder: an ack at the last step (even t = 0) ends it at once; no ack at all
    waits the limit, says how far the recorder got, and returns False."""
    class Monitor:
        sim_time_s, recorder_ack_s = 0.0, 0.0

    said: list[str] = []
    assert L.caught_up(Monitor(), said.append, limit_s=5.0) and said == []
    Monitor.sim_time_s, Monitor.recorder_ack_s = 12.0, 12.0
    assert L.caught_up(Monitor(), said.append, limit_s=5.0) and said == []
    Monitor.recorder_ack_s = None
    assert not L.caught_up(Monitor(), said.append, limit_s=0.6)
    assert "(-- s of 12.00 s)" in said[0] and "only to -- s of the last 12.00 s" in said[-1], said


def test_supervisor_without_dds_reports_restarts_and_failure(tmp_path):
    """Plain processes: a crashing one is restarted up to N times, then stops the rest."""
    crash = [sys.executable, "-c", "import sys; print('boom line'); sys.exit(4)"]
    sleeper = [sys.executable, "-c", "import time; print('sleeping', flush=True); time.sleep(60)"]
    specs = [S.ProcessSpec("sleeper", sleeper),
             S.ProcessSpec("crash", crash, S.RestartPolicy("restart", 2))]
    t0 = time.monotonic()
    with S.Supervisor(specs, tmp_path / "logs", restart_delay_s=0.05) as sup:
        sup.start()
        sleeper_pid = sup.pid("sleeper")
        while not sup.done and time.monotonic() - t0 < 20:
            sup.poll()
            time.sleep(0.02)
        assert [e.action for e in sup.exits if e.name == "crash"] == ["restart", "restart", "stop"]
        assert sup.failure.name == "crash" and sup.failure.returncode == 4 and sup.failure.attempt == 2
        assert "boom line" in sup.failure.last_lines and "exit code 4" in sup.failure.report()
    assert time.monotonic() - t0 < 20
    assert not _alive(sleeper_pid)
    assert (tmp_path / "logs" / "crash.log").read_text().splitlines().count("boom line") == 3


def test_stop_escalates_sigint_sigterm_sigkill_stage_by_stage(tmp_path):
    def proc(ignore: str, on_int: str = "") -> list[str]:
        code = ("import signal, sys, time\n"
                + "".join(f"signal.signal(signal.{sig}, signal.SIG_IGN)\n" for sig in ignore.split())
                + on_int + "print('up', flush=True)\ntime.sleep(60)\n")
        return [sys.executable, "-c", code]

    polite = "signal.signal(signal.SIGINT, lambda *a: sys.exit(0))\n"
    specs = [S.ProcessSpec("stubborn", proc("SIGINT SIGTERM"), sigint_grace_s=0.3, sigterm_grace_s=0.3),
             S.ProcessSpec("deaf", proc("SIGINT"), sigint_grace_s=0.3),
             S.ProcessSpec("last", proc("", polite), stop_stage=1)]
    sup = S.Supervisor(specs, tmp_path / "logs")
    sup.start()
    t0 = time.monotonic()
    while not all("up" in sup.last_lines(n) for n in ("stubborn", "deaf", "last")):
        assert time.monotonic() - t0 < 20
        time.sleep(0.02)
    exits = sup.stop()
    assert [(e.name, e.returncode, e.action) for e in exits][-1] == ("last", 0, "shutdown")
    assert {e.name: e.cause for e in exits} == {"stubborn": "killed by SIGKILL", "deaf": "killed by SIGTERM",
                                                "last": "exit code 0"}
    assert "sending SIGKILL" in (tmp_path / "logs" / "stubborn.log").read_text()
    assert time.monotonic() - t0 < 15


# ------------------------------------------------------------------------ real DDS


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:  # a zombie waiting for its parent is not alive
        return Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0] != "Z"
    except OSError:
        return False


@pytest.fixture
def graph(tmp_path):
    pytest.importorskip("rclpy", reason="rclpy (ROS 2 Jazzy wheels) not installed")
    (tmp_path / "fake_node.py").write_text(FAKE_NODE)
    (tmp_path / "drive.py").write_text(DRIVER)
    domain = claimed_domain()
    env = dict(os.environ)
    env["ROS_DOMAIN_ID"] = str(domain)
    env["AMENT_PREFIX_PATH"] = env.get("AMENT_PREFIX_PATH") or sys.prefix
    env.setdefault("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")
    env["PYTHONPATH"] = str(REPO) + os.pathsep + env.get("PYTHONPATH", "")
    env["PYTHONUNBUFFERED"] = "1"

    def node(name: str, *extra: str, **kw) -> dict:
        return {"name": name, "cmd": [sys.executable, str(tmp_path / "fake_node.py"), "--name", name,
                                      "--dir", str(tmp_path), *extra], **kw}

    def start(nodes: list[dict], **cfg) -> subprocess.Popen:
        c = {"domain": domain, "logs": str(tmp_path / "logs"), "nodes": nodes, **cfg}
        (tmp_path / "cfg.json").write_text(json.dumps(c))
        return subprocess.Popen([sys.executable, str(tmp_path / "drive.py"), str(tmp_path / "cfg.json")],
                                cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                text=True)

    def wait_for(path: Path, timeout: float = 30.0) -> None:
        t0 = time.monotonic()
        while not path.exists():
            assert time.monotonic() - t0 < timeout, f"{path} never appeared"
            time.sleep(0.05)

    procs: list[subprocess.Popen] = []

    class G:
        dir = tmp_path

        @staticmethod
        def run(nodes, **cfg):
            p = start(nodes, **cfg)
            procs.append(p)
            return p

    G.node, G.wait_for, G.domain = staticmethod(node), staticmethod(wait_for), domain
    yield G
    for p in procs:  # never leave a driver behind, even when a test fails
        if p.poll() is None:
            p.kill()
            p.wait()


def _result(stdout: str) -> dict:
    line = [x for x in stdout.splitlines() if x.startswith("RESULT ")]
    assert line, f"driver printed no result: {stdout!r}"
    return json.loads(line[-1][len("RESULT "):])


def _wait_until_discovered(domain: int, topic: str, *, reader: str, writer: str, timeout: float = 60.0) -> None:
    """Poll a probe participant on ``domain`` until it sees node ``reader`` subscribed to and node ``writer``
    publishing ``topic``."""
    import rclpy
    from rclpy.context import Context

    ctx = Context()
    rclpy.init(context=ctx, domain_id=domain)
    probe = rclpy.create_node("discovery_probe", context=ctx)
    try:
        t0 = time.monotonic()
        while time.monotonic() - t0 < timeout:
            subs = {i.node_name for i in probe.get_subscriptions_info_by_topic(topic)}
            pubs = {i.node_name for i in probe.get_publishers_info_by_topic(topic)}
            if reader in subs and writer in pubs:
                return
            time.sleep(0.1)
        raise AssertionError(f"{reader} reading / {writer} writing {topic} not discovered in {timeout:g} s")
    finally:
        probe.destroy_node()
        rclpy.shutdown(context=ctx)


def _wait_for_line(p: subprocess.Popen, pred, timeout: float = 30.0) -> str:
    """Read the driver's stderr until a line satisfies ``pred``; return what was read."""
    seen, t0 = [], time.monotonic()
    while time.monotonic() - t0 < timeout:
        line = p.stderr.readline()
        if not line:
            break
        seen.append(line)
        if pred(line):
            return "".join(seen)
    raise AssertionError("expected launcher output never came: " + "".join(seen))


def _pids(g, names) -> dict[str, int]:
    for n in names:
        g.wait_for(g.dir / f"{n}.pid")
    return {n: int((g.dir / f"{n}.pid").read_text()) for n in names}


@pytest.mark.ros
def test_killed_node_is_reported_and_graph_stops_nonzero_without_hanging(graph):
    p = graph.run([graph.node("a", "--clock"), graph.node("b"), graph.node("c")])
    pids = _pids(graph, "abc")
    time.sleep(1.5)  # a few log lines from b
    os.kill(pids["b"], signal.SIGKILL)
    t_kill = time.monotonic()
    out, err = p.communicate(timeout=40)
    assert time.monotonic() - t_kill < 25, "the launcher took too long to stop the graph"
    assert p.returncode == 1
    res = _result(out)
    assert res["reason"] == "node 'b' failed (killed by SIGKILL)"
    assert "node 'b' ended (killed by SIGKILL)" in err
    assert "fake b: tick" in err.split("node 'b' ended")[1]  # its last log lines
    assert str(graph.dir / "logs" / "b.log") in err
    assert {e[0]: e[2] for e in res["exits"]} == {"b": "stop", "a": "shutdown", "c": "shutdown"}
    assert (graph.dir / "a.clean").exists() and (graph.dir / "c.clean").exists()
    assert not any(_alive(pids[n]) for n in "abc")
    assert "fake b: up" in (graph.dir / "logs" / "b.log").read_text()


@pytest.mark.ros
@pytest.mark.parametrize("stepping", [False, True])
def test_a_node_exiting_2_before_the_first_step_is_bad_input_after_it_a_failure(graph, stepping):
    """A node that exits 2 (it refused a parameter, its mission or its ROS domain) before the sim time moved makes
    the launch exit 2, as the launcher's own input checks do; once the graph steps, a node's exit is a failure
    (exit 1), whatever its code."""
    a = graph.node("a", "--clock") if stepping else graph.node("a")
    # stepping: b crashes once the launcher's monitor has seen the graph step (3 s after b's start, or 1.5 s after
    # the clock reached b, were too early on a machine loaded with two CPU hogs: the monitor had not seen it yet)
    flag = graph.dir / "stepping"
    crash = ("--crash-on-file", str(flag)) if stepping else ("--crash-after", "0.3")
    p = graph.run([a, graph.node("b", *crash, "--exit-code", "2")], stepping_file=str(flag) if stepping else None)
    out, err = p.communicate(timeout=60)
    res = _result(out)
    assert res["reason"] == "node 'b' failed (exit code 2)", err
    assert p.returncode == res["code"] == (1 if stepping else 2), err
    assert (res["sim_time"] is not None and res["sim_time"] > 0) == stepping, res


@pytest.mark.ros
def test_bb2_launch_with_a_parameter_a_node_refuses_exits_2_with_the_nodes_line(tmp_path, bb2_graph_available):
    params = tmp_path / "params.yaml"
    params.write_text("/**:\n  ros__parameters:\n    rate_hz: fast\n    time_mode: realtime\n")
    p = subprocess.run([sys.executable, "-m", "bb2_tools.launcher", str(_short_mission(tmp_path, 20.0)),
                        "--params", str(params), "--out", str(tmp_path / "run"), "--timeout", "100"],
                       cwd=tmp_path, env=ros_env(), capture_output=True, text=True, timeout=160)
    assert p.returncode == 2, p.stderr
    # (and the mode it sets, which --mode overrides, is said before the graph starts)
    assert (f"[bb2-launch] warning: params file {params}: /**: time_mode 'realtime' is overridden by --mode "
            "lockstep\n") in p.stderr.split("node 'simulator' ended")[0], p.stderr
    assert "simulator: error: parameter 'rate_hz'" in p.stderr.split("node 'simulator' ended (exit code 2)")[1]
    assert re.search(r"node 'simulator' failed \(exit code 2\): sim time --, .*exit code 2$", p.stderr, re.M), \
        p.stderr


@pytest.mark.ros
@pytest.mark.parametrize("clock", ["stops", "never", "handshake"])
def test_a_graph_whose_sim_time_stops_or_never_starts_is_stopped_as_stalled(graph, clock):
    """Issue 10, point 3: never left at 0x, whether the sim time stands still mid-run or never starts at all
    (a lockstep simulator waiting for a recorder that is gone; or its clock at the start time, the start-up
    handshake, which is not a stall until the nodes have had their time to come up: seen beside CPU hogs, a
    path follower building its mission for tens of seconds)."""
    a = {"stops": graph.node("a", "--clock", "--clock-for", "1.5"), "never": graph.node("a"),
         "handshake": graph.node("a", "--clock", "--clock-for", "0")}[clock]
    t0 = time.monotonic()
    p = graph.run([a, graph.node("b")], stall=3.0, ready=4.0, timeout=120)
    out, err = p.communicate(timeout=120)
    res = _result(out)
    assert p.returncode == 1 and res["code"] == 1, err
    if clock == "stops":
        assert res["reason"].startswith("stalled: sim time stuck at 15.00 s for "), res
        assert res["sim_time"] == pytest.approx(15.0)
    else:
        assert res["reason"].startswith("stalled: the sim time has not started "), res
        assert res["sim_time"] == (None if clock == "never" else 0.0), res
    assert "(--stall-timeout 3)" in res["reason"] and "timeout after" not in res["reason"]
    assert time.monotonic() - t0 < 100  # stopped by the stall check, long before the 120 s timeout
    assert all(e[2] == "shutdown" for e in res["exits"]), res["exits"]  # both stopped cleanly


@pytest.mark.ros
def test_sigint_stops_everything_cleanly_recorder_last(graph):
    from bb2_tools.bagfile import BagReader

    bag = graph.dir / "bag"
    rec = {"name": "recorder", "cmd": [sys.executable, "-m", "bb2_tools.recorder", "--out", str(bag),
                                       "--topics", "/clock", "--use-sim-time"],
           "stage": 1, "ready_node": "recorder", "ready_topics": ["/clock"], "grace": 20.0}
    p = graph.run([rec, graph.node("a", "--clock"), graph.node("b")], first=["recorder"])
    pids = _pids(graph, "ab")
    seen = _wait_for_line(p, lambda line: "| progress" in line and "sim --" not in line)
    # the recorder discovers the publishers on its own (the monitor is another participant): wait until a third
    # participant sees the recorder reading /clock and the fake node writing it (slow on a loaded machine)
    _wait_until_discovered(graph.domain, "/clock", reader="recorder", writer="fake_a")
    # ... and until the writer has matched the recorder's reader itself (the launcher's monitor is the other one):
    # seen under xdist beside another graph test, discovered both ways yet not matched a second later: an empty bag
    log, t0 = graph.dir / "logs" / "a.log", time.monotonic()
    while not re.search(r"clock readers ([2-9]|\d\d)", log.read_text() if log.exists() else ""):
        assert time.monotonic() - t0 < 60, "fake_a's /clock never matched two readers:\n" + log.read_text()[-2000:]
        time.sleep(0.1)
    time.sleep(1.0)
    p.send_signal(signal.SIGINT)
    out, err = p.communicate(timeout=40)
    err = seen + err
    assert p.returncode == 130, err
    res = _result(out)
    assert res["reason"] == "interrupted (SIGINT)"
    assert {e[0]: (e[1], e[2]) for e in res["exits"]} == {
        "a": (0, "shutdown"), "b": (0, "shutdown"), "recorder": (0, "shutdown")}
    assert [e[0] for e in res["exits"]][-1] == "recorder"  # stopped last
    assert (graph.dir / "a.clean").exists() and (graph.dir / "b.clean").exists()
    assert not any(_alive(pid) for pid in pids.values())
    assert res["sim_time"] is not None and res["sim_time"] > 0, err  # the monitor saw /clock
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())  # the recorder finished its bag
    counts = BagReader(bag).message_counts
    assert counts.get("/clock", 0) > 0, counts
    assert meta["rosbag2_bagfile_information"]["message_count"] == sum(counts.values())


@pytest.mark.ros
def test_restart_policy_restarts_a_crashed_node_and_mission_completes(graph):
    p = graph.run([graph.node("a", "--clock"),
                   graph.node("b", "--crash-after", "1.0", "--exit-code", "7", policy=["restart", 2]),
                   graph.node("c", "--progress-s", "6")], timeout=60)
    out, err = p.communicate(timeout=70)
    res = _result(out)
    assert p.returncode == 0, err
    assert res["reason"] == "mission complete" and res["progress"] >= 1.0
    b_exits = [e for e in res["exits"] if e[0] == "b"]
    assert b_exits[0][1:] == [7, "restart", 0]
    assert b_exits[-1][2] == "shutdown" and b_exits[-1][3] == 1  # the restarted one ran to the end
    assert (graph.dir / "b.attempts").read_text() == "2"
    assert "policy 'restart' for 'b'" in err and "exit code 7" in err
    log = (graph.dir / "logs" / "b.log").read_text()
    assert "attempt 0:" in log and "attempt 1:" in log and "fake b: crashing with 7" in log


# ------------------------------------------------------------------------ the real BB2 graph
def _short_mission(tmp_path: Path, duration_s: float) -> Path:
    f = tmp_path / f"straight_{duration_s:g}s.yaml"
    f.write_text(f"extends: {REPO / 'missions' / 'straight.yaml'}\nname: straight_short\nduration_s: {duration_s}\n")
    return f


def _children(pid: int) -> dict[int, str]:
    """Direct children of ``pid``: {pid: command line}."""
    out = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
            if int(fields[1]) == pid:
                out[int(stat.parent.name)] = (stat.parent / "cmdline").read_bytes().replace(b"\0", b" ").decode()
        except (OSError, IndexError, ValueError):
            continue
    return out


@pytest.fixture
def bb2_graph_available():
    pytest.importorskip("rclpy", reason="rclpy (ROS 2 Jazzy wheels) not installed")
    for node in L.GRAPH_NODES:
        if importlib.util.find_spec(node.entry_point.split(":")[0]) is None:
            pytest.skip(f"node {node.entry_point} not in this checkout")


@pytest.mark.ros
def test_bb2_launch_flies_a_short_mission_and_records_the_bag(tmp_path, bb2_graph_available):
    from bb2_msgs_py.contract import select_topics
    from bb2_tools.bagfile import BagReader

    mission = _short_mission(tmp_path, 10.0)
    out = tmp_path / "bags" / "run"
    p = subprocess.run([sys.executable, "-m", "bb2_tools.launcher", str(mission), "--out", str(out),
                        "--params", str(REPO / "config" / "bb2_graph.yaml"),  # the shipped params file applies
                        "--end-at", "simulator", "--timeout", "100"], cwd=tmp_path, env=ros_env(),
                       capture_output=True, text=True, timeout=130)
    assert p.returncode == 0, p.stderr
    assert "mission complete" in p.stderr and f"bag:   {out}" in p.stderr and f"logs:  {out / 'logs'}" in p.stderr
    meta = yaml.safe_load((out / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    counts = BagReader(out).message_counts
    assert meta["message_count"] == sum(counts.values())
    steps = round(10.0 / 0.05)
    # every step's state (t = 0 .. 10 s) is in the bag (the lockstep simulator re-sends an unanswered
    # state, so a stamp may appear more than once: the t = 0 state while the controllers come up)
    from bb2_msgs_py.conversions import stamp_to_ns
    from bb2_msgs_py.contract import message_class
    from rclpy.serialization import deserialize_message

    odom = message_class("nav_msgs/msg/Odometry")
    stamps = [stamp_to_ns(deserialize_message(m.data, odom).header.stamp)
              for m in BagReader(out).raw_messages("/bb2/odom")]
    want = {round(k * 0.05e9) for k in range(steps + 1)}
    assert set(stamps) == want, sorted(set(stamps) ^ want)[:10]
    assert stamps == sorted(stamps)
    assert counts["/bb2/planes/cmd"] >= steps + 1 and counts["/bb2/state_native"] >= steps + 1
    published = {t.name for t in select_topics() if not t.name.startswith("/bb2/sensors/")} - {
        "/bb2/altitude", "/bb2/nav/state_native", "/bb2/scene/sea_surface"}  # no terrain, no sensors: block (no
    # /bb2/sensors/*, no navigation), a calm sea (no moving sea surface)
    assert published <= set(counts), sorted(published - set(counts))
    for node in L.GRAPH_NODES:  # each node's log was captured, and each stopped cleanly
        log = (out / "logs" / f"{node.name}.log").read_text()
        assert "---- exited: exit code 0" in log, (node.name, log[-2000:])


@pytest.mark.parametrize("args, said", [
    (["--without", "mixr"], "--without: unknown node 'mixr' (did you mean 'mixer'?); nodes that may be left out: "
                            "planner, path_following, l1_autopilot, mixer"),
    (["--without", "simulator"], "--without: the simulator is the boat itself"),
    (["--without", "recorder"], "--without: leave the recorder out with --no-record"),
    (["--without", "mixer,mixer"], "--without: node 'mixer' is named twice"),
    (["--without", "mixer", "--group", "l1_autopilot,mixer"], "a node left out cannot be composed"),
    (["--without", "mixer", "--restart", "mixer=restart"], "unknown node"),   # no process of its own to restart
    # --compose puts every composable node but those left out into one process
    (["--compose", "--without", "mixer", "--restart", "container=stop"],
     "--restart: unknown node 'container'; nodes: recorder, planner+path_following+l1_autopilot+simulator"),
])
def test_without_refuses_what_cannot_be_left_out(tmp_path, capsys, args, said):
    assert L.main([str(REPO / "missions" / "straight.yaml"), *args]) == 2
    err = capsys.readouterr().err
    assert said in err and err.count("\n") == 1, err


def test_a_shipped_mission_or_fleet_is_flown_by_its_name_and_a_misspelt_one_is_named(tmp_path, capsys, monkeypatch):
    """``bb2-sim mission canyon`` and ``ros2 launch ... mission:=canyon`` take a shipped name; ``bb2-launch canyon``
    said 'mission file ./canyon does not exist'.  It now flies the shipped mission (or fleet: canyon_pair), a file
    of that name here first, and a misspelt name is refused with the likely one."""
    from bb2_mission.schema import MISSIONS_DIR

    monkeypatch.chdir(tmp_path)
    assert L.parse_args(["canyon"]).mission == MISSIONS_DIR / "canyon.yaml"
    assert L.parse_args(["canyon_pair"]).mission == MISSIONS_DIR / "fleets" / "canyon_pair.yaml"
    (tmp_path / "canyon").write_text("extends: canyon\n")
    assert L.parse_args(["canyon"]).mission == Path("canyon")  # a file here is what it names
    assert L.main(["canyn"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"bb2-launch: error: mission file {tmp_path / 'canyn'} does not exist (did you mean "
                          "'canyon'?); shipped missions and fleets: canyon, ") and "canyon_pair" in err, err


def test_a_fleet_with_a_boat_that_cannot_start_is_refused_before_any_boat_flies(tmp_path, capsys):
    """A boat above the surface: bb2-launch started the fleet, the other boats flew, and this boat's own launcher
    refused it (the fleet exited 1, 'b2 failed'); it is bad input, refused up front (exit 2), no run directory."""
    fleet = tmp_path / "f.yaml"
    fleet.write_text("boats: {b1: straight, b2: {mission: straight, initial: {offset_m: [0.0, 0.0, 1.0e4]}}}\n")
    from bb2_tools.fleet_launcher import run_fleet

    assert run_fleet(L.parse_args([str(fleet), "--bag-dir", str(tmp_path / "bags")])) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"bb2-launch: error: {fleet}: boat 'b2': its mission (straight.yaml with the boat's "
                          "changes): the initial CG z = 9985.00 m") and err.count("\n") == 1, err
    assert not (tmp_path / "bags").exists()


def test_a_fleet_params_file_that_gives_a_node_its_own_mission_is_refused_before_any_boat_flies(tmp_path, capsys):
    """Each boat flies its own mission; a params file's ``simulator:`` ``mission_file`` would win over it for every
    boat's simulator.  Each boat's launcher refused it (exit 2), after the other boats had started and the fleet's
    run directory was claimed (the fleet exited 1): it is refused with the fleet, up front."""
    from bb2_tools.fleet_launcher import run_fleet

    fleet = tmp_path / "f.yaml"
    fleet.write_text("boats: {b1: straight, b2: straight}\n")
    params = tmp_path / "p.yaml"
    params.write_text(f"simulator:\n  ros__parameters:\n    mission_file: {REPO / 'missions' / 'straight.yaml'}\n")
    assert run_fleet(L.parse_args([str(fleet), "--params", str(params), "--bag-dir", str(tmp_path / "bags")])) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"bb2-launch: error: params file {params}: simulator: mission_file ") and (
        f"conflicts with the fleet file {fleet}" in err and "leave it out and remove it from the file" in err
        and err.count("\n") == 1), err
    assert not (tmp_path / "bags").exists()


def test_without_leaves_the_nodes_out_of_the_graph_and_of_a_composed_process(tmp_path):
    mission = REPO / "missions" / "straight.yaml"
    names = [s.name for s in L.graph_specs(mission, tmp_path / "run", without=("l1_autopilot", "mixer"))]
    assert sorted(names) == ["path_following", "planner", "recorder", "simulator"], names
    assert L.check_without("mixer, l1_autopilot") == ("l1_autopilot", "mixer")  # in the graph's order
    args = L.parse_args([str(mission), "--without", "mixer"])
    from bb2_tools.fleet_launcher import boat_command

    assert boat_command(args, mission, "boat1", 7, tmp_path)[-2:] == ["--without", "mixer"]  # every boat's


@pytest.mark.ros
def test_bb2_launch_without_the_mixer_flies_with_a_users_own_in_its_place(tmp_path, bb2_graph_available):
    """``--without mixer``: a mixer started by the user on the run's ``--domain-id`` (ours, here, in a process of
    its own started first) answers every step in its place, and the run equals the library runner's."""
    import numpy as np

    from bb2_tools.bag_run import read_bag
    from rosenv import library_trajectory

    domain = claimed_domain()
    mission = _short_mission(tmp_path, 3.0)
    env = dict(ros_env(), ROS_DOMAIN_ID=str(domain))
    own = subprocess.Popen([sys.executable, "-m", "bb2_ros.mixer", "--ros-args", "-p", f"mission_file:={mission}",
                            "-p", "use_sim_time:=true"], cwd=tmp_path, env=env, stdout=subprocess.DEVNULL,
                           stderr=subprocess.DEVNULL)
    try:
        p = subprocess.run([sys.executable, "-m", "bb2_tools.launcher", str(mission), "--without", "mixer",
                            "--domain-id", str(domain), "--out", str(tmp_path / "run"), "--end-at", "simulator",
                            "--timeout", "150"], cwd=tmp_path, env=ros_env(), capture_output=True, text=True,
                           timeout=200)
    finally:
        own.send_signal(signal.SIGINT)
        own.wait(30)
    assert p.returncode == 0, p.stderr[-3000:]
    assert f"without: mixer (not started: your nodes answer in their place on ROS_DOMAIN_ID={domain}" in p.stderr
    assert "| FAILSAFE:" not in p.stderr  # the user's mixer answered from the first step
    # what the user's node must publish and may read, from the contract (checked against the graph above)
    assert ("in place of the mixer: publish /bb2/planes/cmd (sensor_msgs/msg/JointState); it reads /clock, "
            "/bb2/autopilot/vh_cmd") in p.stderr, p.stderr[-3000:]
    assert not (tmp_path / "run" / "logs" / "mixer.log").exists()  # ours was never started
    log = (tmp_path / "run" / "logs" / "simulator.log").read_text()
    assert "no answer to step" not in log, log[-2000:]  # the user's mixer answered every step
    ref = library_trajectory(mission)
    run = read_bag(tmp_path / "run")
    assert run.x.shape == (len(ref), 12) and not run.warnings, (run.x.shape, len(ref), run.warnings)
    assert np.max(np.abs(run.x - ref[:, 1:])) <= 1e-9


@pytest.mark.ros
def test_the_status_line_says_when_the_simulator_steps_on_its_failsafe(tmp_path, bb2_graph_available):
    """``--without mixer`` and no node of the user's: nothing answers, the lockstep simulator steps on its failsafe
    (here after 0.2 s a step, its first after 2 s), and the status line says so, with the simulator's reason."""
    mission = _short_mission(tmp_path, 1.0)
    params = tmp_path / "fast_failsafe.yaml"
    params.write_text("simulator:\n  ros__parameters:\n    startup_timeout_s: 2.0\n    lockstep_timeout_s: 0.2\n")
    p = subprocess.run([sys.executable, "-m", "bb2_tools.launcher", str(mission), "--without", "mixer", "--params",
                        str(params), "--status-period", "0.5", "--no-record", "--timeout", "100"], cwd=tmp_path,
                       env=ros_env(), capture_output=True, text=True, timeout=150)
    assert p.returncode == 0 and "mission complete" in p.stderr, p.stderr[-3000:]
    lines = [ln for ln in p.stderr.splitlines() if ln.startswith("[bb2-launch] sim ")]
    # (its planes neutral: none ever came; its propeller this step's, or held when the autopilot was late too)
    assert any("| FAILSAFE: lockstep timeout: neutral planes, " in ln for ln in lines), p.stderr[-3000:]
    # on a mission of 400 s the crawl went on for hours (one step per lockstep_timeout_s): --stall-timeout ends it,
    # with what to do; the simulator stops the run itself (its status says why: the bag ends 'stalled', where
    # bb2-launch's own stop left it 'stopped')
    from bb2_tools.analysis import analyze
    from bb2_tools.bag_run import read_bag

    long = _short_mission(tmp_path, 400.0)
    t0 = time.monotonic()
    p = subprocess.run([sys.executable, "-m", "bb2_tools.launcher", str(long), "--without", "mixer", "--params",
                        str(params), "--stall-timeout", "3", "--timeout", "100", "--out",
                        str(tmp_path / "crawl")], cwd=tmp_path, env=ros_env(), capture_output=True, text=True,
                       timeout=150)
    assert p.returncode == 1, p.stderr[-3000:]
    said = re.search(r"stopping: the simulator stopped: stalled: stepped on the failsafe for (\d+) s of wall time at "
                     r"t = [0-9.]+ s \(lockstep timeout: neutral planes, [^;]*; stall_timeout_s 3\): is every "
                     r"controller running", p.stderr)
    assert said and 3 <= int(said.group(1)) <= 10, p.stderr[-3000:]
    assert "nothing answered in place of the mixer (--without): start your nodes on ROS_DOMAIN_ID=" in p.stderr
    assert time.monotonic() - t0 < 90, p.stderr[-3000:]  # not the --timeout
    end = analyze(read_bag(tmp_path / "crawl")).figures.end
    assert end.reason == "stalled" and "stall_timeout_s 3" in end.message, end


ROS_OWN_TOPICS = {"/rosout", "/parameter_events"}


@pytest.mark.ros
def test_every_node_publishes_and_reads_what_the_contract_says(tmp_path, bb2_graph_available):
    """The contract's publisher and subscribers of every topic (what ``--without`` tells a user their node must
    publish and read) against the running graph's own endpoints, found by ROS graph introspection: each topic a node
    publishes has that node as the contract's publisher, each topic it reads lists it among the subscribers, and no
    node has a topic the contract lacks."""
    import rclpy

    from bb2_msgs_py.contract import EVERY_NODE, select_topics
    from rosenv import wait_for_clock

    domain = claimed_domain()
    mission = _short_mission(tmp_path, 60.0)
    params = tmp_path / "end_at_progress.yaml"   # as the launch files run it: the simulator reads the progress
    params.write_text("simulator:\n  ros__parameters:\n    end_at_progress: true\n")
    p = subprocess.Popen([sys.executable, "-m", "bb2_tools.launcher", str(mission), "--mode", "realtime",
                          "--params", str(params), "--domain-id", str(domain), "--out", str(tmp_path / "run"),
                          "--timeout", "150"],
                         cwd=tmp_path, env=ros_env(), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    nodes = [n.name for n in L.GRAPH_NODES]
    found: dict[str, tuple[set[str], set[str]]] = {}
    ctx = rclpy.Context()
    try:
        wait_for_clock(domain, 1.0)
        rclpy.init(context=ctx, domain_id=domain)
        probe = rclpy.create_node("contract_probe", context=ctx)
        t0 = time.monotonic()
        while time.monotonic() - t0 < 60:
            names = {n for n, _ns in probe.get_node_names_and_namespaces()}
            if set(nodes) <= names:
                found = {n: ({t for t, _ in probe.get_publisher_names_and_types_by_node(n, "/")},
                             {t for t, _ in probe.get_subscriber_names_and_types_by_node(n, "/")}) for n in nodes}
                if all(pubs for pubs, _subs in found.values()):
                    break
            time.sleep(0.5)
        probe.destroy_node()
    finally:
        rclpy.try_shutdown(context=ctx)
        p.send_signal(signal.SIGINT)
        _out, err = p.communicate(timeout=120)
    assert set(found) == set(nodes), (sorted(found), err[-2000:])
    contract = {t.name: t for t in select_topics(include_bag_only=True)}
    wrong = []
    for node, (pubs, subs) in found.items():
        for t in sorted(pubs - ROS_OWN_TOPICS):
            if t not in contract or contract[t].publisher not in (node, EVERY_NODE):
                wrong.append(f"{node} publishes {t} (contract: {contract[t].publisher if t in contract else 'none'})")
        for t in sorted(subs - ROS_OWN_TOPICS):
            if t not in contract or node not in contract[t].subscribers:
                wrong.append(f"{node} reads {t} (contract: {contract[t].subscribers if t in contract else 'none'})")
    assert not wrong, "\n".join(wrong)
    assert "/bb2/planes/cmd" in found["mixer"][0] and "/bb2/autopilot/vh_cmd" in found["mixer"][1]
    assert "/bb2/mission/progress" in found["simulator"][1]


@pytest.mark.ros
def test_bb2_launch_boats_in_namespaces_share_a_domain_without_crosstalk(tmp_path, bb2_graph_available):
    """Issue 13, point 4: two ``bb2-launch --namespace`` of different missions on one ``--domain-id`` make one graph
    of two boats, each in lockstep with its own controllers and clock: each boat's bag equals its mission's library
    run (1e-9 m, so no command of the other boat was taken), its frames carry its namespace, its topics are recorded
    under the contract's names, every published message is accounted for (the publication counts, resolved names
    mapped back), and the other boat's topics are not in it."""
    import numpy as np

    from bb2_tools.bag_run import read_bag
    from bb2_tools.bagfile import BagReader, read_publication_counts
    from rosenv import library_trajectory

    domain = claimed_domain()
    straight = _short_mission(tmp_path, 5.0)
    circle = tmp_path / "circle_5s.yaml"
    circle.write_text(f"extends: {REPO / 'missions' / 'circle.yaml'}\nname: circle_short\nduration_s: 5.0\n")
    env = ros_env()
    boats = {"boat1": straight, "boat2": circle}
    procs = {ns: subprocess.Popen([sys.executable, "-m", "bb2_tools.launcher", str(m), "--namespace", ns,
                                   "--domain-id", str(domain), "--out", str(tmp_path / ns), "--end-at", "simulator",
                                   "--timeout", "150"], cwd=tmp_path, env=env, stdout=subprocess.PIPE,
                                  stderr=subprocess.PIPE, text=True)
             for ns, m in boats.items()}
    errs = {ns: p.communicate(timeout=200)[1] for ns, p in procs.items()}
    for ns, p in procs.items():
        assert p.returncode == 0, (ns, errs[ns][-3000:])
        assert f"namespace /{ns}" in errs[ns] and "mission complete" in errs[ns], errs[ns][-3000:]
        assert "another bb2-launch runs" not in errs[ns]  # boats in namespaces share a domain on purpose
        # the boat's first step waited for its recorder, not for a reader of /diagnostics (which a boat's recorder
        # leaves out): before, every namespaced boat started 30 s late, at the start-up timeout
        log = (tmp_path / ns / "logs" / "simulator.log").read_text()
        assert "starting after" not in log and "no reader of" not in log, log[-2000:]
    for ns, mission in boats.items():
        bag = tmp_path / ns
        ref = library_trajectory(mission)
        run = read_bag(bag)
        assert run.x.shape == (len(ref), 12) and not run.warnings, (ns, run.x.shape, len(ref), run.warnings)
        assert np.max(np.abs(run.x - ref[:, 1:])) <= 1e-9, ns
        reader = BagReader(bag)
        assert reader.vehicle_base_link() == f"{ns}/base_link"
        assert "/bb2/odom" in reader.topics and "/diagnostics" not in reader.topics
        assert not [t for t in reader.topics if t.startswith("/boat")], sorted(reader.topics)
        published = read_publication_counts(bag)
        assert published["/bb2/state_native"] == reader.message_counts["/bb2/state_native"] >= len(ref), ns
        assert published["/clock"] >= len(ref), ns
    assert np.ptp(read_bag(tmp_path / "boat2").x[:, 5]) > 0.01  # the circle turns: two different boats flew


@pytest.mark.ros
def test_realtime_end_waits_for_a_recorder_behind_and_the_bag_holds_the_last_step(tmp_path, bb2_graph_available):
    """In real time nothing holds the graph back for a recorder starved of CPU: at the end of the mission it may be
    seconds behind, and stopping the nodes then loses what their writers still hold for it.  Here the recorder is
    frozen (SIGSTOP) from the first step to the end: the launcher says it waits for the recorder, the recorder
    (continued) takes the writers' histories, and the bag ends on the mission's last step."""
    import threading

    from bb2_tools.bag_run import read_bag

    mission = _short_mission(tmp_path, 8.0)
    out = tmp_path / "bags" / "run"
    p = subprocess.Popen([sys.executable, "-m", "bb2_tools.launcher", str(mission), "--out", str(out),
                          "--mode", "realtime", "--end-at", "simulator", "--timeout", "150"], cwd=tmp_path,
                         env=ros_env(), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                         start_new_session=True)
    lines: list[str] = []
    reader = threading.Thread(target=lambda: lines.extend(p.stderr), daemon=True)
    reader.start()
    recorder = None
    try:
        t0 = time.monotonic()
        sim_log = out / "logs" / "simulator.log"
        while not (sim_log.is_file() and "the controllers answered the first state" in sim_log.read_text()):
            assert p.poll() is None and time.monotonic() - t0 < 120, "".join(lines)[-3000:]
            time.sleep(0.05)
        (recorder,) = [pid for pid, cmd in _children(p.pid).items() if "recorder" in cmd]
        os.kill(recorder, signal.SIGSTOP)
        while not any("waiting for the recorder" in line for line in lines):
            assert not any("stopping:" in line for line in lines), "".join(lines)[-3000:]
            assert p.poll() is None and time.monotonic() - t0 < 150, "".join(lines)[-3000:]
            time.sleep(0.05)
        os.kill(recorder, signal.SIGCONT)
        recorder = None
        p.wait(timeout=120)
    finally:
        if recorder is not None:
            os.kill(recorder, signal.SIGCONT)
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGINT)
            p.wait(timeout=60)
    reader.join(10)
    err = "".join(lines)
    assert p.returncode == 0 and "mission complete" in err, err[-3000:]
    assert "the recorder holds every step after" in err and "stopping anyway" not in err, err[-3000:]
    run = read_bag(out)
    assert run.t[-1] == pytest.approx(8.0), (run.t[-1], err[-3000:])  # the last step is in the bag


@pytest.mark.ros
def test_bb2_launch_reports_a_killed_simulator_and_exits_nonzero(tmp_path, bb2_graph_available):
    mission = _short_mission(tmp_path, 400.0)
    out = tmp_path / "bags" / "run"
    p = subprocess.Popen([sys.executable, "-m", "bb2_tools.launcher", str(mission), "--out", str(out),
                          "--timeout", "100"], cwd=tmp_path, env=ros_env(), stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    try:
        seen = _wait_for_line(p, lambda line: re.search(r"sim +[1-9][0-9.]* s", line) is not None, timeout=90)
        sims = [pid for pid, cmd in _children(p.pid).items() if "simulator" in cmd]
        assert len(sims) == 1, _children(p.pid)
        # the Fast DDS shared-memory segments it maps (its own, which a killed process leaves, and its peers')
        with open(f"/proc/{sims[0]}/maps") as f:
            segments = {Path(m) for m in re.findall(r"(/dev/shm/fastrtps_[0-9a-f]{16})$", f.read(), re.M)}
        assert segments and all(s.exists() for s in segments), segments
        os.kill(sims[0], signal.SIGKILL)
        t_kill = time.monotonic()
        _, err = p.communicate(timeout=60)
        assert time.monotonic() - t_kill < 45
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
    err = seen + err
    assert p.returncode == 1, err
    assert "node 'simulator' failed (killed by SIGKILL)" in err
    assert "simulator up" in err.split("node 'simulator' ended")[1]  # its last log lines
    assert not _children(p.pid)
    assert (out / "metadata.yaml").is_file()  # the recorder, stopped last, finished the bag
    # bb2-launch removed what the killed simulator left in /dev/shm (fastdds shm clean) and said so: "simulator ended
    # by a signal: 1 stale Fast DDS shared-memory segment and 2 ports removed from /dev/shm (fastdds shm clean)" --
    # unless a clean of a test beside this one (another xdist worker) took them in the seconds before; gone either way
    assert not [s for s in segments if s.exists() or Path(f"{s}_el").exists()], segments
    said = re.findall(r"\[bb2-launch\] (.*) ended by a signal: (.*)", err)
    assert all(who == "simulator" and re.fullmatch(r"\d+ stale Fast DDS shared-memory segments? and \d+ ports? "
                                                   r"removed from /dev/shm \(fastdds shm clean\)", what)
               for who, what in said), said


@pytest.mark.ros
def test_a_simulation_diverging_at_speed_ends_the_graph_with_exit_1_and_the_substeps_advice(
        tmp_path, bb2_graph_available):
    """The sprint mission (16 m/s) with the authors' 0.05 s step diverges about 3 s in.  The simulator node says so
    with the advice ``bb2-sim mission`` gives (the mission's ``substeps`` the shipped file flies with), in its status
    (recorded) and through ``bb2-launch``, which stops the graph with exit 1 and a finished bag."""
    from bb2_mission import MISSIONS_DIR, MissionRunner, load_mission, substeps_warning
    from bb2_tools.analysis import analyze
    from bb2_tools.bag_run import read_bag
    from bb2_tools.bagfile import BagReader

    mission = tmp_path / "fast.yaml"
    mission.write_text(f"extends: {MISSIONS_DIR / 'sprint.yaml'}\nname: fast\nsubsteps: 1\nduration_s: 15.0\n")
    out = tmp_path / "bags" / "run"
    p = subprocess.run([sys.executable, "-m", "bb2_tools.launcher", str(mission), "--out", str(out),
                        "--timeout", "100"], cwd=tmp_path, env=ros_env(), capture_output=True, text=True,
                       timeout=130)
    assert p.returncode == 1, p.stderr
    said = re.search(r"the simulator stopped: (simulation diverged at t = [0-9.]+ s: non-finite .*)$", p.stderr,
                     re.MULTILINE)
    assert said, p.stderr
    k = load_mission(MISSIONS_DIR / "sprint.yaml").substeps
    advice = f"the mission's substeps: {k} integrates it in {k}"
    assert said.group(1).endswith(advice) and "m/s, near or past where the ROM's 0.05 s step in 1 ode3" in said.group(1)
    assert (out / "metadata.yaml").is_file()  # the recorder, stopped last, finished the bag
    warned = substeps_warning(load_mission(mission))
    assert warned.startswith("mission fast (4.00 rps) at about ") and "in 1 ode3 step(s) flies steadily" in warned
    assert f"[bb2-launch] warning: {warned}\n" in p.stderr, p.stderr  # before the flight, by the launcher
    log = (out / "logs" / "simulator.log").read_text()  # and by the simulator as it started
    assert "is faster than the ROM's 0.05 s step in 1 ode3 step(s) flies steadily" in log, log[-3000:]
    assert f"will likely diverge; the mission's substeps: {k} flies to about" in log, log[-3000:]
    status = BagReader(out).last_statuses()["bb2/simulator"]
    assert status["state"] == "diverged" and status["error"] == said.group(1), status
    end = analyze(read_bag(out), mission=str(mission)).figures.end  # bb2-analyze's (and a --graph campaign's)
    alone = MissionRunner(load_mission(mission)).run().summary
    assert (end.reason, end.message) == ("diverged", f"diverged: {said.group(1)}"), end
    assert str(alone.end_reason) == "diverged" and end.t_s == pytest.approx(alone.event.t, abs=1e-9), (end, alone)


@pytest.mark.ros
def test_bb2_launch_each_node_killed_in_turn_is_reported_and_restarted(tmp_path, bb2_graph_available):
    """Issue 5: every node of the real graph killed in turn (SIGKILL) is reported with its cause and handled by
    its policy (here restart for all but the simulator, whose restart is refused up front: issue 10); the graph
    keeps running and a final Ctrl-C still finishes the bags."""
    mission = _short_mission(tmp_path, 400.0)
    out = tmp_path / "bags" / "run"
    p = subprocess.Popen([sys.executable, "-m", "bb2_tools.launcher", str(mission), "--out", str(out),
                          "--restart", "all=restart:2,simulator=stop", "--timeout", "200"], cwd=tmp_path,
                         env=ros_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    victims = ["planner", "path_following", "l1_autopilot", "mixer", "recorder"]
    seen = ""
    try:
        seen += _wait_for_line(p, lambda line: re.search(r"sim +[1-9][0-9.]* s", line) is not None, timeout=90)
        for name in victims:
            pids = [pid for pid, cmd in _children(p.pid).items()
                    if re.search(rf"\b{name}\b", cmd) and "launcher" not in cmd]
            assert len(pids) == 1, (name, _children(p.pid))
            os.kill(pids[0], signal.SIGKILL)
            seen += _wait_for_line(p, lambda line, n=name: f"policy 'restart' for '{n}'" in line, timeout=60)
            # the restarted node is running again before the next one is killed
            t0 = time.monotonic()
            while time.monotonic() - t0 < 30:
                alive = [pid for pid, cmd in _children(p.pid).items() if re.search(rf"\b{name}\b", cmd)]
                if alive and alive != pids:
                    break
                time.sleep(0.2)
            else:
                raise AssertionError(f"{name} was not restarted: {_children(p.pid)}")
        time.sleep(2.0)
        p.send_signal(signal.SIGINT)
        _, err = p.communicate(timeout=90)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
    err = seen + err
    assert p.returncode == 130, err[-3000:]
    for name in victims:
        assert f"node '{name}' ended (killed by SIGKILL)" in err, name
        assert f"policy 'restart' for '{name}'" in err, name
    assert not _children(p.pid)
    assert (out / "metadata.yaml").is_file()                      # the first recorder's bag was repaired
    assert (out.with_name("run_r1") / "metadata.yaml").is_file()  # the restarted recorder finished its own


def test_domain_claims_keep_two_launches_off_one_domain(tmp_path):
    """Issue 10, point 2 (DDS): a launch claims its ROS_DOMAIN_ID with a lock file; a claimed id is never handed to
    a second launch on the same machine, however close together they start, and the claim goes with the monitor
    (or the process)."""
    pytest.importorskip("rclpy")
    from bb2_tools import graph_monitor as G

    locks = tmp_path / "locks"
    held = [G.claim_domain(d, locks) for d in G.SAFE_DOMAIN_IDS if d != 37]
    assert all(fd is not None for fd in held)
    assert G.claim_domain(5, locks) is None            # held: refused, in this process too (flock per open file)
    mon = G.free_domain_id(lock_dir=locks, listen_s=0.1)
    try:
        assert mon.domain_id == 37 and mon.domain_lock_fd is not None
        with pytest.raises(S.LaunchError, match="no free ROS_DOMAIN_ID"):
            G.free_domain_id(lock_dir=locks, listen_s=0.1)
    finally:
        mon.close()
    fd = G.claim_domain(37, locks)                     # released with the monitor
    assert fd is not None
    for f in held + [fd]:
        os.close(f)


def _plainly_held_port(ids) -> tuple[int, object]:
    """A domain of ``ids`` whose discovery port this test can hold unshared (as an ephemeral socket would), and the
    socket holding it."""
    import random
    import socket

    from bb2_ros.discovery_port import discovery_multicast_port

    for d in random.sample(list(ids), len(ids)):
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            s.bind(("0.0.0.0", discovery_multicast_port(d)))
            return d, s
        except OSError:
            s.close()
    raise AssertionError(f"every discovery port of domains {ids} is in use")


def test_a_domain_whose_discovery_port_is_taken_is_passed_over_or_refused(tmp_path, capsys):
    """No node on a domain whose discovery multicast port another socket holds unshared would discover another
    (bb2_ros.discovery_port): bb2-launch passes such a domain over when it picks one, and refuses it, with the
    port and its holder, when it is given; before any node starts."""
    pytest.importorskip("rclpy")
    locks = tmp_path / "locks"
    blocked, plain = _plainly_held_port(M.SAFE_DOMAIN_IDS)
    try:
        # the other candidate: claimed on this machine too, so no launch of another test runs there meanwhile
        free, free_claim = next((d, fd) for d in M.SAFE_DOMAIN_IDS if d != blocked
                                and M.discovery_blocked({}, d) is None and (fd := M.claim_domain(d)) is not None)
        held = [M.claim_domain(d, locks) for d in M.SAFE_DOMAIN_IDS if d not in (blocked, free)]

        class BlockedFirst:  # free_domain_id's random order, with the blocked domain first
            @staticmethod
            def sample(ids, _k):
                return sorted(ids, key=lambda d: d != blocked)

        try:
            mon = M.free_domain_id(lock_dir=locks, listen_s=0.1, rng=BlockedFirst())
            try:
                assert mon.domain_id == free, (mon.domain_id, blocked, free)
            finally:
                mon.close()
        finally:
            for f in held + [free_claim]:
                os.close(f)
        mission = _short_mission(tmp_path, 5.0)
        assert L.main([str(mission), "--domain-id", str(blocked), "--out", str(tmp_path / "run")]) == 2
        err = capsys.readouterr().err
        assert err.startswith(f"bb2-launch: error: ROS domain {blocked}'s discovery port: UDP port "
                              f"{7400 + 250 * blocked} is held by pid {os.getpid()} "), err
        assert len(err.strip().splitlines()) == 1 and "ROS_DOMAIN_ID in 0..101" in err, err
    finally:
        plain.close()


def test_publication_counts_are_merged_over_the_recorded_topics_and_a_killed_process_is_named(tmp_path):
    """``merge_publication_counts``: the node processes' count files are summed per recorded topic into the bag's
    publication_counts.json (the Foxglove viewer's own file set aside); a process killed by a signal left no file,
    and the summary line names it; an unreadable (half-written) file counts as missing."""
    from bb2_tools.bagfile import PUBLICATION_COUNTS_FILE

    counts = tmp_path / "published"
    counts.mkdir()
    for name, pid, pub in (("simulator", 1, {"/bb2/state_native": 10, "/bb2/status": 2, "/not_recorded": 4}),
                           ("mixer", 2, {"/bb2/planes/cmd": 9, "/bb2/status": 3}),
                           ("mixer", 3, {"/bb2/planes/cmd": 1}),           # its restart
                           ("foxglove_bridge", 4, {})):
        (counts / f"{name}-{pid}.json").write_text(json.dumps({"process": name, "pid": pid, "published": pub}))

    def exit_(name, rc, attempt=0):
        return S.NodeExit(name, rc, attempt, "shutdown", [], tmp_path / f"{name}.log", 1.0)

    exits = [exit_("simulator", 0), exit_("mixer", -9), exit_("mixer", 0, 1), exit_("recorder", 0),
             exit_("foxglove_bridge", 0)]
    bag = tmp_path / "bag"
    bag.mkdir()
    topics = ["/bb2/state_native", "/bb2/status", "/bb2/planes/cmd"]
    assert L.merge_publication_counts(bag, counts, exits, topics) == ""   # every node process left its counts
    doc = json.loads((bag / PUBLICATION_COUNTS_FILE).read_text())
    assert doc["published"] == {"/bb2/planes/cmd": 10, "/bb2/state_native": 10, "/bb2/status": 5}, doc
    assert [r["process"] for r in doc["processes"]] == ["mixer", "mixer", "simulator"] and doc["uncounted"] == []
    assert doc["uncounted_sources"] == ["bb2/recorder"]  # no recorder file: its statuses in the bag count for nobody
    # a boat in /boat1: its processes count resolved names, the file names the bag's (the contract's)
    boat = tmp_path / "boat_bag"
    boat.mkdir()
    boat_counts = tmp_path / "boat_published"
    boat_counts.mkdir()
    (boat_counts / "simulator-5.json").write_text(json.dumps({"process": "simulator", "pid": 5, "published": {
        "/boat1/bb2/state_native": 7, "/boat1/clock": 8, "/diagnostics": 2, "/bb2/status": 99}}))
    assert L.merge_publication_counts(boat, boat_counts, [exit_("simulator", 0)],
                                      ["/bb2/state_native", "/clock", "/bb2/status"], "boat1") == ""
    boat_doc = json.loads((boat / PUBLICATION_COUNTS_FILE).read_text())
    assert boat_doc["published"] == {
        "/bb2/state_native": 7, "/clock": 8}  # another boat's (root) /bb2/status is not this boat's
    assert boat_doc["uncounted_sources"] == ["boat1/bb2/recorder"]  # the boat's recorder is /boat1/recorder
    (counts / "mixer-2.json").write_text('{"process": "mix')              # killed while writing: half a file
    note = L.merge_publication_counts(bag, counts, exits, topics)
    assert "publication counts missing from mixer (attempt 0: killed by SIGKILL)" in note, note
    doc = json.loads((bag / PUBLICATION_COUNTS_FILE).read_text())
    assert doc["published"]["/bb2/planes/cmd"] == 1 and doc["uncounted"] == ["mixer (attempt 0: killed by SIGKILL)"]
    # the recorder counts its own statuses (they are in its bag): summed in, but its file stands for no node's
    (counts / "recorder-6.json").write_text(json.dumps({"process": "recorder", "pid": 6,
                                                        "published": {"/bb2/status": 4, "/diagnostics": 4}}))
    note = L.merge_publication_counts(bag, counts, exits, topics)
    assert "publication counts missing from mixer (attempt 0: killed by SIGKILL)" in note, note
    doc = json.loads((bag / PUBLICATION_COUNTS_FILE).read_text())
    assert doc["published"]["/bb2/status"] == 2 + 4 and doc["uncounted"] == ["mixer (attempt 0: killed by SIGKILL)"]
    assert "uncounted_sources" not in doc  # the recorder counted its own
    assert not list(bag.glob("*.tmp"))
