"""Issue 15: the controllers' callbacks at a real-time priority (``callback_priority``).

The helper (:func:`bb2_ros.node_common.set_callback_priority`) in a child process of its own (scheduling is per
thread and per process: the test process keeps its own): which threads it changes, which it leaves, what it says
when the OS refuses.  Then a real node over real DDS: its threads' policy as the kernel reports it, its status,
priority 0 and an invalid priority."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]

CHILD = textwrap.dedent("""
    import json, os, sys, threading
    sys.path.insert(0, {repo!r})
    from bb2_ros.node_common import set_callback_priority

    def named(name, prio=0):
        ready, stop = threading.Event(), threading.Event()
        box = {{}}

        def run():
            box["tid"] = threading.get_native_id()
            with open(f"/proc/self/task/{{box['tid']}}/comm", "w") as f:
                f.write(name)
            if prio:
                os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(prio))
            ready.set()
            stop.wait()
        threading.Thread(target=run, daemon=True).start()
        ready.wait()
        return box["tid"]

    tids = {{"main": threading.get_native_id(), "dds": named("dds.test"), "worker": named("worker")}}
    if {own_rt}:
        tids["stepping"] = named("stepping", 9)
    if {drop}:
        os.setgid(65534)
        os.setuid(65534)  # nobody: no CAP_SYS_NICE (and the default RLIMIT_RTPRIO 0)
    outcome = set_callback_priority(7)
    pol = {{k: [os.sched_getscheduler(t) & ~getattr(os, "SCHED_RESET_ON_FORK", 0),
               os.sched_getparam(t).sched_priority] for k, t in tids.items()}}
    print(json.dumps({{"outcome": outcome, "policies": pol}}))
""")


def _child(*, own_rt: bool = False, drop: bool = False) -> dict:
    code = CHILD.format(repo=str(REPO), own_rt=own_rt, drop=drop)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


def _threads(pid: int) -> dict[int, tuple[str, int, int]]:
    """Each thread of process ``pid``: (name, scheduling policy, priority), as the kernel reports them."""
    threads = {}
    for t in os.listdir(f"/proc/{pid}/task"):
        try:
            comm = Path(f"/proc/{pid}/task/{t}/comm").read_text().strip()
            threads[int(t)] = (comm, os.sched_getscheduler(int(t)) & ~getattr(os, "SCHED_RESET_ON_FORK", 0),
                               os.sched_getparam(int(t)).sched_priority)
        except (OSError, ProcessLookupError):
            continue
    return threads


def _may_use_fifo() -> bool:
    try:
        import resource

        return os.geteuid() == 0 or resource.getrlimit(resource.RLIMIT_RTPRIO)[0] >= 7
    except (ImportError, OSError):
        return False


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="thread scheduling through /proc: Linux only")
def test_the_executor_and_middleware_threads_get_sched_fifo_the_others_stay_as_they_are():
    got = _child(own_rt=True)
    pol, other, fifo = got["policies"], os.SCHED_OTHER, os.SCHED_FIFO
    if not _may_use_fifo():  # what a user without the privilege gets: said, nothing changed
        assert got["outcome"].startswith("normal (SCHED_FIFO 7 refused: "), got
        assert pol["main"] == pol["dds"] == pol["worker"] == [other, 0], got
        return
    assert got["outcome"] == "SCHED_FIFO 7 (2 threads: the executor's and the middleware's)", got
    assert pol["main"] == [fifo, 7] and pol["dds"] == [fifo, 7], got  # the caller and the dds.* thread
    assert pol["worker"] == [other, 0], got  # a BLAS pool's thread (may spin while it waits) is left alone
    assert pol["stepping"] == [fifo, 9], got  # a thread real-time already keeps its own priority


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="thread scheduling through /proc: Linux only")
@pytest.mark.skipif(os.geteuid() != 0, reason="dropping to an unprivileged user needs root (here the refusal is "
                                               "what the other test sees)")
def test_a_refused_priority_is_said_and_leaves_every_thread_normal():
    got = _child(drop=True)
    assert got["outcome"] == "normal (SCHED_FIFO 7 refused: Operation not permitted)", got
    assert all(p == [os.SCHED_OTHER, 0] for p in got["policies"].values()), got


# ----------------------------------------------------------------------------------------- a real node
@pytest.mark.ros
def test_a_controller_runs_its_callbacks_at_callback_priority_and_says_so(tmp_path):
    pytest.importorskip("rclpy", reason="rclpy (ROS 2 Jazzy wheels) not installed")
    from rosenv import claimed_domain, ros_env, spawn_node  # tests/rosenv.py

    from test_nodes import MISSION, Probe  # the node tests' probe (tests/ros/test_nodes.py)

    mission = tmp_path / "circle.yaml"
    mission.write_text(MISSION)
    domain_id = claimed_domain()
    bad = spawn_node("bb2_ros.mixer", domain_id, "-p", f"mission_file:={mission}", "-p", "callback_priority:=120")
    probe = Probe(domain_id)
    procs = []
    try:
        probe.sub("/bb2/status")
        for name, prio in (("mixer_rt", 33), ("mixer_normal", 0)):
            procs.append(spawn_node("bb2_ros.mixer", domain_id, "-p", f"mission_file:={mission}", "-p",
                                    f"callback_priority:={prio}", "-p", "status_period_s:=0.2", "-r",
                                    f"__node:={name}"))
        # the simulator (lockstep, waiting for answers that do not come): its process at lockstep_priority (its
        # callback_priority, the real-time command reception's, does not apply in lockstep)
        procs.append(spawn_node("bb2_ros.simulator", domain_id, "-p", f"mission_file:={mission}", "-p",
                                "lockstep_priority:=21", "-p", "callback_priority:=23", "-p", "status_period_s:=0.2"))
        # a simulator in real time (on the failsafe: nobody answers) with a stepping thread of its own
        # (realtime_loop thread): its command reception at callback_priority, its stepping thread at realtime_priority
        procs.append(spawn_node("bb2_ros.simulator", domain_id, "-p", f"mission_file:={mission}", "-p",
                                "time_mode:=realtime", "-p", "callback_priority:=23", "-p", "realtime_priority:=27",
                                "-p", "hold_cpu_dma_latency:=false", "-p", "duration_s:=1000.0", "-p",
                                "realtime_loop:=thread", "-p", "status_period_s:=0.2", "-r", "__node:=sim_rt"))
        # the same stepping on the executor's thread (realtime_loop executor, the default): the callbacks run on the
        # stepping thread, at realtime_priority; callback_priority holds for the middleware's threads
        procs.append(spawn_node("bb2_ros.simulator", domain_id, "-p", f"mission_file:={mission}", "-p",
                                "time_mode:=realtime", "-p", "callback_priority:=23", "-p", "realtime_priority:=27",
                                "-p", "hold_cpu_dma_latency:=false", "-p", "duration_s:=1000.0",
                                "-p", "status_period_s:=0.2", "-r", "__node:=sim_rx"))
        # composed with the simulator in lockstep (default lockstep_priority 0), a controller's 40 does not apply:
        # the simulator paces the process, and at a real-time priority it would run ahead of outside readers
        procs.append(subprocess.Popen(
            [sys.executable, "-m", "bb2_ros.container", "--node", "simulator", "--ros-args", "-p",
             f"mission_file:={mission}", "-p", "status_period_s:=0.2", "-r", "__node:=sim_c", "--node", "mixer",
             "--ros-args", "-p", f"mission_file:={mission}", "-p", "status_period_s:=0.2", "-p",
             "callback_priority:=40", "-r", "__node:=mixer_c"],
            cwd=REPO, env=ros_env(domain_id), stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True))

        def statuses():
            with probe.lock:
                arrays = list(probe.msgs.get("/bb2/status", []))
            return {st.hardware_id: {kv.key: kv.value for kv in st.values} for a in arrays for st in a.status
                    if st.name in ("bb2/mixer", "bb2/simulator")}

        probe.wait(lambda: {"/mixer_rt", "/mixer_normal", "/simulator", "/sim_rt", "/sim_rx", "/mixer_c"}
                   <= set(statuses())
                   and all(statuses()[n].get("scheduling", "").startswith(("SCHED_FIFO", "normal"))
                           for n in ("/sim_rt", "/sim_rx"))
                   # (the simulators' first status goes out as they come up, before they spin: "not yet set")
                   and all("not yet" not in statuses()[n]["callback_scheduling"]
                           for n in ("/simulator", "/sim_rt", "/sim_rx")),
                   60, "the mixers' and the simulators' status", procs[0])
        rt, normal = statuses()["/mixer_rt"], statuses()["/mixer_normal"]
        assert normal["callback_scheduling"] == "normal", normal
        sim = statuses()["/simulator"]["callback_scheduling"]
        assert sim.startswith("SCHED_FIFO 21 (" if _may_use_fifo() else "normal (SCHED_FIFO 21 refused: "), sim
        sim_rt = statuses()["/sim_rt"]
        rt_pid = procs[3].pid
        rt_threads = _threads(rt_pid)
        rt_dds = [v for v in rt_threads.values() if v[0].startswith("dds.")]
        if _may_use_fifo():
            assert sim_rt["callback_scheduling"] == \
                f"SCHED_FIFO 23 ({len(rt_dds) + 1} threads: the executor's and the middleware's)", sim_rt
            assert sim_rt["scheduling"] == "SCHED_FIFO 27", sim_rt
            assert rt_threads[rt_pid][1:] == (os.SCHED_FIFO, 23) and rt_dds \
                and all(v[1:] == (os.SCHED_FIFO, 23) for v in rt_dds), rt_threads
            # the stepping thread keeps its own priority (started before, real-time already)
            assert sum(v[1:] == (os.SCHED_FIFO, 27) for v in rt_threads.values()) == 1, rt_threads
        else:
            assert sim_rt["callback_scheduling"].startswith("normal (SCHED_FIFO 23 refused: "), sim_rt
        sim_rx = statuses()["/sim_rx"]
        rx_pid = procs[4].pid
        rx_threads = _threads(rx_pid)
        rx_dds = [v for v in rx_threads.values() if v[0].startswith("dds.")]
        if _may_use_fifo():
            assert sim_rx["scheduling"] == "SCHED_FIFO 27", sim_rx
            assert sim_rx["callback_scheduling"] == (
                f"SCHED_FIFO 27 (on the simulator's stepping thread: realtime_loop executor; the middleware's threads: "
                f"SCHED_FIFO 23 ({len(rx_dds) + 1} threads: the executor's and the middleware's))"), sim_rx
            # the main thread steps and spins, at 27; the middleware's threads at 23
            assert rx_threads[rx_pid][1:] == (os.SCHED_FIFO, 27), rx_threads
            # (a thread the executor starts once spinning, e.g. its timers', inherits the stepping thread's policy)
            assert rx_dds and all(v[1:] == (os.SCHED_FIFO, 23) for v in rx_dds), rx_threads
        else:
            assert sim_rx["callback_scheduling"].startswith("normal (SCHED_FIFO 27 refused: "), sim_rx
        composed = statuses()["/mixer_c"]["callback_scheduling"]
        assert composed == "normal (composed with the simulator in lockstep: its lockstep_priority 0 decides)", composed
        assert os.sched_getscheduler(procs[-1].pid) == os.SCHED_OTHER
        pid = procs[0].pid
        threads = _threads(pid)
        dds = {t: v for t, v in threads.items() if v[0].startswith("dds.")}
        assert dds, threads  # Fast DDS names its threads dds.*
        if _may_use_fifo():
            assert rt["callback_scheduling"] == f"SCHED_FIFO 33 ({len(dds) + 1} threads: the executor's and the middleware's)", \
                rt
            assert threads[pid][1:] == (os.SCHED_FIFO, 33), threads  # the executor: the process's main thread
            assert all(v[1:] == (os.SCHED_FIFO, 33) for v in dds.values()), threads
            # the threads started before the middleware's (the BLAS pools of numpy and scipy) are left alone; one the
            # executor starts later inherits its policy
            pools = [v for t, v in threads.items() if t != pid and t < min(dds)]
            assert pools and all(v[1] == os.SCHED_OTHER for v in pools), repr(sorted(threads.items()))
        else:
            assert rt["callback_scheduling"].startswith("normal (SCHED_FIFO 33 refused: "), rt
        out, _ = bad.communicate(timeout=60)
        assert bad.returncode == 2 and "callback_priority must be in 0..99, got 120" in out, out
    finally:
        for p in procs:
            if p.poll() is None:
                p.send_signal(signal.SIGINT)
        codes = [p.wait(15) for p in procs]
        probe.close()
    assert codes == [0] * len(procs), [p.communicate()[0] for p in procs]


@pytest.mark.ros
def test_the_example_external_autopilot_puts_its_callbacks_and_the_middleware_at_its_realtime_priority(tmp_path):
    """``examples/hil/external_autopilot.py --realtime-priority N`` (a user's autopilot beside the graph): its
    executor thread and Fast DDS's threads at SCHED_FIFO N (they hand it the messages), said on its output; refused,
    said and nothing changed."""
    pytest.importorskip("rclpy", reason="rclpy (ROS 2 Jazzy wheels) not installed")
    import threading

    from rosenv import claimed_domain, ros_env  # tests/rosenv.py

    from test_nodes import MISSION  # tests/ros/test_nodes.py

    mission = tmp_path / "circle.yaml"
    mission.write_text(MISSION)
    p = subprocess.Popen([sys.executable, str(REPO / "examples" / "hil" / "external_autopilot.py"), "--mission",
                          str(mission), "--realtime-priority", "17"], cwd=REPO, env=ros_env(claimed_domain()),
                         stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    killer = threading.Timer(90.0, p.kill)   # a hung start fails the test instead of hanging it
    killer.start()
    lines: list[str] = []
    try:
        for line in p.stdout:
            lines.append(line)
            if "external autopilot ready" in line:
                break
        said = next((ln for ln in lines if "callbacks at" in ln), "")
        threads = _threads(p.pid)
        dds = [v for v in threads.values() if v[0].startswith("dds.")]
        assert dds, threads
        if _may_use_fifo():
            assert f"callbacks at SCHED_FIFO 17 ({len(dds) + 1} threads" in said, lines
            assert threads[p.pid][1:] == (os.SCHED_FIFO, 17), threads
            assert all(v[1:] == (os.SCHED_FIFO, 17) for v in dds), threads
        else:
            assert "callbacks at normal (SCHED_FIFO 17 refused: " in said, lines
            assert all(v[1] == os.SCHED_OTHER for v in threads.values()), threads
        p.send_signal(signal.SIGINT)
        rest, _ = p.communicate(timeout=30)
    finally:
        killer.cancel()
        if p.poll() is None:
            p.kill()
            p.wait()
    assert p.returncode == 0, "".join(lines) + (rest if p.returncode is not None else "")


@pytest.mark.skipif(not sys.platform.startswith("linux") or not {0, 1} <= os.sched_getaffinity(0),
                    reason="thread CPUs: Linux, CPUs 0 and 1")
def test_a_main_thread_pinned_apart_still_says_the_process_cpus():
    """The simulator stepping on the executor's (main) thread takes its stepping_cpus there: every node of the
    process still says the process's CPUs in its status (process_cpus), not the stepping thread's; a stepping thread
    of its own changes nothing the main thread says."""
    child = textwrap.dedent(f"""
        import json, os, sys, threading
        sys.path.insert(0, {str(REPO)!r})
        from bb2_ros.node_common import pin_this_thread, process_cpus, set_process_cpus
        set_process_cpus({{0, 1}})
        out = {{}}
        t = threading.Thread(target=lambda: out.update(thread=pin_this_thread({{1}})))
        t.start(); t.join()
        out["after_thread"] = process_cpus()
        out["main"] = pin_this_thread({{0}})
        out["after_main"] = process_cpus()
        out["main_affinity"] = sorted(os.sched_getaffinity(0))
        print(json.dumps(out))
    """)
    r = subprocess.run([sys.executable, "-c", child], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    got = json.loads(r.stdout)
    assert got == {"thread": "1", "after_thread": "0,1", "main": "0", "after_main": "0,1", "main_affinity": [0]}, got


def test_the_status_cpu_times_are_the_main_threads_and_the_processs_whoever_asks():
    """``cpu_times`` (every node's status): ``cpu_main_thread_s`` is the main thread's CPU (the executor's, which runs
    the callbacks) even when another thread asks (the real-time simulator's stepping thread publishes statuses too),
    and ``cpu_process_s`` adds every other thread's.  A child process: its main thread burns 0.3 s of CPU, then a
    second thread burns 0.3 s and asks."""
    child = textwrap.dedent(f"""
        import json, os, sys, threading, time
        sys.path.insert(0, {str(REPO)!r})
        from bb2_ros.node_common import cpu_times

        def burn(s):
            t0 = time.thread_time()
            while time.thread_time() - t0 < s:
                pass
        before = cpu_times()
        burn(0.3)
        main_done = cpu_times()
        out = {{}}
        t = threading.Thread(target=lambda: (burn(0.3), out.update(cpu_times())))
        t.start(); t.join()
        print(json.dumps({{"before": before, "main_done": main_done, "from_thread": out, "pid": os.getpid()}}))
    """)
    r = subprocess.run([sys.executable, "-c", child], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    got = json.loads(r.stdout)
    b, m, t = ({k: float(v) for k, v in got[w].items() if k != "process_id"} for w in ("before", "main_done",
                                                                                        "from_thread"))
    assert {got[w]["process_id"] for w in ("before", "main_done", "from_thread")} == {str(got["pid"])}, got
    assert m["cpu_main_thread_s"] - b["cpu_main_thread_s"] >= 0.3 and m["cpu_process_s"] - b["cpu_process_s"] >= 0.3
    # asked from the second thread: the main thread's CPU has not moved (the second thread's is not counted in it),
    # the process's has grown by the second thread's 0.3 s
    assert t["cpu_main_thread_s"] - m["cpu_main_thread_s"] < 0.05, got
    assert t["cpu_process_s"] - m["cpu_process_s"] >= 0.3, got
    for x in (b, m, t):
        assert 0.0 < x["cpu_main_thread_s"] <= x["cpu_process_s"], got
