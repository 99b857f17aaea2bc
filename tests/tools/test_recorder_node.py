"""Issue 13 (3): the recorder is a proper node: named ``recorder``, configured by ROS parameters (bag directory,
topics, batch period, storage options), with parameter services that answer ``ros2 param`` at once (they are
served from the recorder's own wait set); its command-line options remain as a convenience."""
from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

pytestmark = pytest.mark.ros
pytest.importorskip("rclpy", reason="rclpy (ROS 2 Jazzy wheels) not installed")

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from ros2_tooling import tooling_env, tooling_venv  # noqa: E402  (tests/ros2_tooling.py)
from rosenv import SpinningNode, claimed_domain, ros_env  # noqa: E402

REPO = Path(__file__).resolve().parents[2]


def _ros2_found(cmd, env, timeout_s: float = 60.0):
    """Run a ros2 CLI call again while it says "Node not found" (each call discovers the graph anew)."""
    deadline = time.monotonic() + timeout_s
    while True:
        r = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=60)
        if "Node not found" not in r.stdout + r.stderr or time.monotonic() > deadline:
            return r
        time.sleep(0.5)


def test_recorder_parameters_and_parameter_services(tmp_path):
    domain = claimed_domain()
    env = tooling_env(tooling_venv(), ROS_DOMAIN_ID=str(domain))
    bag = tmp_path / "bag"
    params = tmp_path / "rec.yaml"
    params.write_text(yaml.safe_dump({"recorder": {"ros__parameters": {
        "bag_directory": str(bag), "topics": ["/clock", "/bb2/mission/progress"], "batch_period_s": 0.01,
        "chunk_size": 4096, "compression": "lz4", "use_sim_time": True}}}))
    proc = subprocess.Popen([sys.executable, "-m", "bb2_tools.recorder", "--ros-args", "--params-file", str(params)],
                            cwd=tmp_path, env=ros_env(domain), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        t0 = time.monotonic()
        while not bag.is_dir():
            assert proc.poll() is None and time.monotonic() - t0 < 60, proc.stderr.read() if proc.poll() else ""
            time.sleep(0.1)
        # discovery first (slow on a loaded machine): a `ros2 param list` that does not find the node yet says
        # "Node not found" at once; once found, the parameter services answer at once (before: an 8 s time-out)
        deadline = time.monotonic() + 90
        while True:
            t0 = time.monotonic()
            r = subprocess.run(["ros2", "param", "list", "/recorder"], env=env, capture_output=True, text=True,
                               timeout=60)
            took = time.monotonic() - t0
            if r.returncode == 0 or "Node not found" not in r.stderr or time.monotonic() > deadline:
                break
            time.sleep(0.5)
        assert r.returncode == 0 and "bag_directory" in r.stdout and "batch_period_s" in r.stdout, r.stdout + r.stderr
        assert took < 7.5, "ros2 param list waited for a time-out"  # it took 8 s without services
        r = _ros2_found(["ros2", "param", "get", "/recorder", "compression"], env)
        assert "String value is: lz4" in r.stdout, r.stdout + r.stderr
        r = _ros2_found(["ros2", "param", "set", "/recorder", "chunk_size", "5"], env)
        assert "Setting parameter failed" in r.stdout + r.stderr and "read-only" in r.stdout + r.stderr
        r = _ros2_found(["ros2", "param", "describe", "/recorder", "topics"], env)
        assert "Type: string array" in r.stdout and "Read only: true" in r.stdout, r.stdout
    finally:
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=30)
    assert proc.returncode == 0, err
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert meta["custom_data"]["topics"] == "/clock /bb2/mission/progress"


def test_recorder_refuses_bad_storage_parameters_with_one_line(tmp_path):
    for args, why in ((["-p", "storage_id:=sqlite3"], "storage_id"), (["-p", "compression:=gzip"], "compression"),
                      (["-p", "batch_period_s:=5.0"], "--batch-period (parameter batch_period_s) must be in [0, 1] s, "
                                                        "got 5.0"),
                      (["-p", "topics:=[/bb2/nothing]"], "matches no contract topic"),
                      (["-p", "boats:=[boat1,1boat]"], "a boat's namespace must be a ROS 2 namespace"),
                      (["-p", "boats:=[boat1,boat1]"], "the boats must be distinct"),
                      # each value is named with its option and parameter (one message named them all, and
                      # "got" the status period whichever was wrong)
                      (["-p", "status_period_s:=-1.0"], "parameter status_period_s must be >= 0 s, got -1.0"),
                      (["-p", "chunk_size:=0"], "--chunk-size (parameter chunk_size) must be > 0 bytes, got 0"),
                      (["-p", "queue_depth:=-3"], "--depth (parameter queue_depth) must be > 0, got -3"),
                      (["-p", "flush_period_s:=-1.0"], "--flush-period (parameter flush_period_s) must be >= 0 s, "
                                                       "got -1.0")):
        r = subprocess.run([sys.executable, "-m", "bb2_tools.recorder", "--ros-args",
                            "-p", f"bag_directory:={tmp_path / 'b'}", *args], cwd=tmp_path, env=ros_env(claimed_domain()),
                           capture_output=True, text=True, timeout=60)
        assert r.returncode == 2 and why in r.stderr and "Traceback" not in r.stderr, (args, r.stderr)
        assert not (tmp_path / "b").exists()
    r = subprocess.run([sys.executable, "-m", "bb2_tools.recorder", "--out", str(tmp_path / "b"), "--flush-period",
                        "inf"], cwd=tmp_path, env=ros_env(claimed_domain()), capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and r.stderr.strip() == \
        "bb2-record: error: --flush-period (parameter flush_period_s) must be >= 0 s, got inf", r.stderr
    assert not (tmp_path / "b").exists()


def test_the_recorder_says_its_own_status_on_the_boats_sim_time_and_records_it(tmp_path):
    """The recorder publishes its status as every node does (``bb2/recorder`` on /bb2/status and /diagnostics, from
    its own wait set: no executor runs a timer there): what it wrote so far, the messages lost, its process's CPU; with
    --use-sim-time stamped on the boat's /clock.  Its statuses are in its bag too, the bag's counts growing."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import HistoryPolicy

    from bb2_msgs_py import conversions as cv
    from bb2_msgs_py.contract import message_class, qos_profile
    from bb2_tools.bagfile import BagReader

    domain = claimed_domain()
    bag = tmp_path / "bag"
    proc = subprocess.Popen([sys.executable, "-m", "bb2_tools.recorder", "--out", str(bag), "--use-sim-time",
                             "--topics", "/clock", "/bb2/status", "--ros-args", "-p", "status_period_s:=0.2"],
                            cwd=tmp_path, env=dict(ros_env(domain), BB2_PUBLISHED_DIR=str(tmp_path / "published")),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=domain)
    node = rclpy.create_node("status_probe", context=ctx)
    seen: dict[str, list[tuple[float, dict[str, str], int, str]]] = {"/bb2/status": [], "/diagnostics": []}
    for name in seen:
        q = qos_profile(name, reader=True)
        q.history, q.depth = HistoryPolicy.KEEP_LAST, 100

        def cb(msg, box=seen[name]):
            for st in msg.status:
                if st.name == "bb2/recorder":
                    box.append((cv.stamp_to_ns(msg.header.stamp) * 1e-9, {kv.key: kv.value for kv in st.values},
                                st.level[0] if isinstance(st.level, bytes) else int(st.level), st.message))
        node.create_subscription(message_class("diagnostic_msgs/msg/DiagnosticArray"), name, cb, q)
    clock = node.create_publisher(message_class("rosgraph_msgs/msg/Clock"), "/clock", qos_profile("/clock"))
    ex = SingleThreadedExecutor(context=ctx)
    ex.add_node(node)
    try:
        deadline = time.monotonic() + 90
        while clock.get_subscription_count() == 0:  # a /clock before the recorder matched would be a head gap
            assert proc.poll() is None and time.monotonic() < deadline, proc.communicate() if proc.poll() else ""
            ex.spin_once(timeout_sec=0.05)
        sim_s = 42.5
        while sum(float(v["node_time_s"]) >= 42.5 and int(v["messages_written"]) > 0
                  for _t, v, _l, _m in seen["/bb2/status"]) < 3:
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline, seen
            clock.publish(cv.clock_message(sim_s))
            sim_s += 0.05
            ex.spin_once(timeout_sec=0.05)
        stamp, v, level, message = next(x for x in seen["/bb2/status"] if float(x[1]["node_time_s"]) >= 42.5)
        assert stamp == pytest.approx(float(v["node_time_s"]), abs=1e-6) and v["use_sim_time"] == "true", v  # sim time
        assert v["process_id"] == str(proc.pid) and float(v["cpu_process_s"]) > 0.0, v
        assert v["bag"] == str(bag) and v["state"] == "recording", v
        assert (level, message) == (0, "recording"), (level, message, v)  # nothing lost: OK level
        assert v["gaps"] == "0" and v["messages_lost"] == "0", v
        t_end = time.monotonic() + 30
        while not seen["/diagnostics"]:  # and on the standard diagnostics topic
            assert time.monotonic() < t_end
            ex.spin_once(timeout_sec=0.05)
    finally:
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=30)
        ex.shutdown()
        node.destroy_node()
        rclpy.shutdown(context=ctx)
    assert proc.returncode == 0, err
    # its statuses are in its bag, each saying what the bag held when it was sent: counts that only grow
    rows = [(st.values, msg) for _t, _lt, msg in BagReader(bag).messages("/bb2/status") for st in msg.status
            if st.name == "bb2/recorder"]
    written = [int({kv.key: kv.value for kv in vals}["messages_written"]) for vals, _m in rows]
    assert len(written) >= 3 and written == sorted(written) and written[-1] > written[0], written
    # every one it published (its count, beside the nodes' for the launcher's check), the last ones too
    counts = json.loads((tmp_path / "published" / f"recorder-{proc.pid}.json").read_text())
    assert counts["published"]["/bb2/status"] == len(rows), (counts, len(rows))


def _fastdds_shared_memory(pid: int) -> list[str]:
    """The Fast DDS shared-memory segments and ports process ``pid`` has mapped (``/dev/shm/fastrtps_*``)."""
    lines = Path(f"/proc/{pid}/maps").read_text().splitlines()
    return sorted({ln.split()[-1] for ln in lines if "/dev/shm/fastrtps_" in ln})


def _net_core(name: str) -> int:
    """A kernel socket limit, ``/proc/sys/net/core/<name>`` (bytes)."""
    return int(Path(f"/proc/sys/net/core/{name}").read_text())


def _recorder_receive_buffer() -> int:
    """What the recorder's sockets get for RECORDER_SOCKETS_SIZE: the kernel caps the request at rmem_max and
    doubles it."""
    from bb2_tools.recorder import RECORDER_SOCKETS_SIZE

    return 2 * min(RECORDER_SOCKETS_SIZE, _net_core("rmem_max"))


def _udp_receive_buffers(pid: int) -> list[int] | None:
    """The receive buffer sizes (bytes) of process ``pid``'s UDP sockets, from ``ss -uanmp`` (None without ``ss``)."""
    if shutil.which("ss") is None:
        return None
    out = subprocess.run(["ss", "-uanmp"], capture_output=True, text=True, timeout=30).stdout.splitlines()
    sizes = []
    for line, nxt in zip(out, out[1:] + [""]):
        if f"pid={pid}," in line and (m := re.search(r"\brb(\d+)", line + nxt)):
            sizes.append(int(m.group(1)))
    return sizes


def test_the_recorders_transports_come_from_its_option_then_its_environment_then_udp():
    from bb2_tools.recorder import RECORDER_TRANSPORTS, TRANSPORTS_ENV, recorder_transports

    assert RECORDER_TRANSPORTS == "UDPv4?sockets_size=4194304"
    assert recorder_transports(None, {}) == recorder_transports(" ", {TRANSPORTS_ENV: ""}) == RECORDER_TRANSPORTS
    assert recorder_transports(None, {TRANSPORTS_ENV: "SHM"}) == "SHM"
    assert recorder_transports("DEFAULT", {TRANSPORTS_ENV: "SHM"}) == "DEFAULT"
    assert recorder_transports("LARGE_DATA?max_msg_size=1MB", {}) == "LARGE_DATA?max_msg_size=1MB"
    for option, env, named in (("FOO", {}, "--transports 'FOO'"), (None, {TRANSPORTS_ENV: "NONE"}, TRANSPORTS_ENV)):
        with pytest.raises(ValueError, match=named):
            recorder_transports(option, env)


def test_the_recorder_refuses_transports_fast_dds_does_not_know_with_one_line(tmp_path):
    """Fast DDS itself would fall back to its default transports with a log line: the recorder says it and stops."""
    p = subprocess.run([sys.executable, "-m", "bb2_tools.recorder", "--out", str(tmp_path / "bag"), "--transports",
                        "UDP4"], cwd=tmp_path, env=ros_env(claimed_domain()), capture_output=True, text=True,
                       timeout=120)
    assert p.returncode == 2 and p.stderr.startswith("bb2-record: error: --transports 'UDP4': not a Fast DDS"), \
        p.stderr
    assert len(p.stderr.strip().splitlines()) == 1 and not (tmp_path / "bag").exists(), p.stderr


@pytest.mark.parametrize("transports", [None, "DEFAULT"])
def test_the_recorder_hears_the_graph_over_udp_only_unless_told_otherwise(tmp_path, transports):
    """By default the recorder's process maps no Fast DDS shared memory (UDP only: a starved reader there cannot be
    left on a replaced port) while the publisher beside it keeps its own, and it records every message and says its
    transports; ``--transports DEFAULT`` gives it shared memory again."""
    from rclpy.duration import Duration

    from bb2_msgs_py import conversions as cv
    from bb2_msgs_py.contract import message_class, qos_profile
    from bb2_tools.bagfile import BagReader
    from bb2_tools.recorder import RECORDER_TRANSPORTS

    domain = claimed_domain()
    bag = tmp_path / "bag"
    env = ros_env(domain)
    env.pop("FASTDDS_BUILTIN_TRANSPORTS", None)
    proc = subprocess.Popen([sys.executable, "-m", "bb2_tools.recorder", "--out", str(bag), "--topics", "/clock",
                             *(["--transports", transports] if transports else []),
                             "--ros-args", "-p", "status_period_s:=0.0"],
                            cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    n = 300
    pub = SpinningNode("transport_probe", domain).start()
    try:
        clock = pub.node.create_publisher(message_class("rosgraph_msgs/msg/Clock"), "/clock", qos_profile("/clock"))
        deadline = time.monotonic() + 90
        while clock.get_subscription_count() == 0:  # the writer has matched the recorder's reader
            assert proc.poll() is None and time.monotonic() < deadline, proc.communicate() if proc.poll() else ""
            time.sleep(0.05)
        mine, its = _fastdds_shared_memory(os.getpid()), _fastdds_shared_memory(proc.pid)
        buffers = _udp_receive_buffers(proc.pid)
        # the writer matches the recorder's reader before the reader matches it (a message then would be a head
        # gap): warm-up messages at t < 100 s until one is acknowledged, then the n counted ones at t >= 100 s
        warm = 0
        while True:
            clock.publish(cv.clock_message(0.05 * warm))
            warm += 1
            if clock.wait_for_all_acked(Duration(seconds=0.5)):
                break
            assert proc.poll() is None and time.monotonic() < deadline, "the recorder never acknowledged"
        for k in range(n):
            clock.publish(cv.clock_message(100.0 + 0.05 * k))
            if k % 50 == 49:
                time.sleep(0.05)
        # every message acknowledged by the recorder before the writer goes (a UDP datagram a loaded machine dropped
        # comes back at the writer's next heartbeat, up to 3 s later)
        assert clock.wait_for_all_acked(Duration(seconds=60)), "the recorder did not acknowledge every message"
    finally:
        pub.close()
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=30)
    assert proc.returncode == 0, err
    assert mine, "the test's own participant maps Fast DDS shared memory (the default transports)"
    expected = transports or RECORDER_TRANSPORTS
    assert f"(Fast DDS transports {expected})" in out, out
    if transports is None:
        assert its == [], its
        # its sockets asked for RECORDER_SOCKETS_SIZE
        if buffers is not None and _recorder_receive_buffer() > _net_core("rmem_default"):
            assert max(buffers) == _recorder_receive_buffer(), buffers
    else:
        assert its, "--transports DEFAULT: the recorder maps shared memory as the nodes do"
    recorded = [m.clock.sec + m.clock.nanosec * 1e-9 for _t, _log, m in BagReader(bag).messages("/clock")]
    assert sorted(round(t, 3) for t in recorded if t >= 100.0) == [round(100.0 + 0.05 * k, 3) for k in range(n)], out


BURST = 300  # messages sent at once to a stopped recorder (the start-up burst that overflowed it was 330)
BURST_SETTLE_S = 1.5  # the whole burst is in the bag this soon after SIGCONT (a bound for a loaded machine)


def _udp_drops(pid: int) -> int:
    """Datagrams the kernel dropped on process ``pid``'s UDP sockets, their receive buffers full (``/proc/net/udp``'s
    ``drops``)."""
    inodes = set()
    for fd in Path(f"/proc/{pid}/fd").iterdir():
        try:
            link = os.readlink(fd)
        except OSError:
            continue
        if link.startswith("socket:["):
            inodes.add(link[8:-1])
    drops = 0
    for table in ("udp", "udp6"):
        for line in Path(f"/proc/{pid}/net/{table}").read_text().splitlines()[1:]:
            f = line.split()
            if f[9] in inodes:
                drops += int(f[12])
    return drops


def _burst_into_a_stopped_recorder(tmp_path, transports: str) -> tuple[list[float], int]:
    """A recorder is SIGSTOPped (a starved process), ``BURST`` reliable messages go out at once, it runs again: wall
    seconds from SIGCONT to each burst message's arrival in the bag, and the datagrams its sockets dropped."""
    from rclpy.duration import Duration
    from rclpy.qos import HistoryPolicy

    from bb2_msgs_py import conversions as cv
    from bb2_msgs_py.contract import message_class, qos_profile
    from bb2_tools.bagfile import BagReader

    domain = claimed_domain()
    env = ros_env(domain)
    env.pop("FASTDDS_BUILTIN_TRANSPORTS", None)
    bag = tmp_path / f"bag_{len(list(tmp_path.glob('bag_*')))}"
    proc = subprocess.Popen([sys.executable, "-m", "bb2_tools.recorder", "--out", str(bag), "--topics",
                             "/bb2/planes/cmd", "--transports", transports, "--ros-args", "-p", "status_period_s:=0.0"],
                            cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    node = SpinningNode("burst_probe", domain).start()
    try:
        q = qos_profile("/bb2/planes/cmd")
        q.history, q.depth = HistoryPolicy.KEEP_LAST, BURST + 50  # the writer keeps the whole burst for repairs
        w = node.node.create_publisher(message_class("sensor_msgs/msg/JointState"), "/bb2/planes/cmd", q)
        deadline = time.monotonic() + 90
        warm = 0
        while not (w.get_subscription_count() and w.wait_for_all_acked(Duration(seconds=0.5))):
            if w.get_subscription_count():
                w.publish(cv.planes_message(-1.0 - warm, [0.0] * 5))  # warm-up, stamped t < 0
                warm += 1
            assert proc.poll() is None and time.monotonic() < deadline, "the recorder never matched"
            time.sleep(0.05)
        os.kill(proc.pid, signal.SIGSTOP)
        time.sleep(0.2)
        for k in range(BURST):
            w.publish(cv.planes_message(0.05 * k, [0.0] * 5))
        time.sleep(0.3)
        cont = time.time()
        os.kill(proc.pid, signal.SIGCONT)
        assert w.wait_for_all_acked(Duration(seconds=30)), "the burst was never acknowledged"
        drops = _udp_drops(proc.pid)
    finally:
        node.close()
        try:
            os.kill(proc.pid, signal.SIGCONT)
        except ProcessLookupError:
            pass
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=30)
    assert proc.returncode == 0, err
    decoded = BagReader(bag).messages("/bb2/planes/cmd")
    arrivals = [m.log_time_ns * 1e-9 - cont for m, (_t, _log, msg) in zip(BagReader(bag).raw_messages("/bb2/planes/cmd"),
                                                                          decoded) if msg.header.stamp.sec >= 0]
    assert len(arrivals) == BURST, (len(arrivals), out)
    return arrivals, drops


def test_a_burst_to_a_starved_recorder_waits_in_its_socket_not_for_a_repair(tmp_path):
    """The recorder's sockets hold a burst of small messages while it is stopped (its 4 MiB buffers), so it has them
    all as soon as it runs again; with the default buffers the kernel drops part of it and the reliable reader waits
    for the writer to repair it at a heartbeat (the control, where the defaults are that small)."""
    from bb2_tools.recorder import RECORDER_TRANSPORTS

    if _recorder_receive_buffer() < 2 * 1024 * 1024:
        pytest.skip(f"net.core.rmem_max is {_net_core('rmem_max')} bytes: the recorder's sockets get "
                    f"{_recorder_receive_buffer()} bytes, too few to hold {BURST} messages for sure")
    arrivals, drops = _burst_into_a_stopped_recorder(tmp_path, RECORDER_TRANSPORTS)
    assert drops == 0 and max(arrivals) < BURST_SETTLE_S, (drops, max(arrivals))
    if _net_core("rmem_default") <= 212992:  # the control: the defaults drop some
        arrivals, drops = _burst_into_a_stopped_recorder(tmp_path, "UDPv4")
        assert drops > 0, "with the default socket buffers no datagram of the burst was dropped: the test shows nothing"
