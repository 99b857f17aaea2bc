"""Child-process environment of the ROS tests: real DDS (Fast DDS) on an isolated domain, this checkout first."""
from __future__ import annotations

import os
import subprocess
import sys
import threading
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def ros_env(domain_id: int | None = None) -> dict[str, str]:
    """os.environ plus the ament prefix (the venv), Fast DDS, this checkout on PYTHONPATH, unbuffered output,
    and ROS_DOMAIN_ID = ``domain_id`` (None: unset, the child picks or is told its domain)."""
    env = dict(os.environ)
    env["AMENT_PREFIX_PATH"] = env.get("AMENT_PREFIX_PATH") or sys.prefix
    env["RMW_IMPLEMENTATION"] = "rmw_fastrtps_cpp"
    env["PYTHONPATH"] = str(REPO) + os.pathsep + env.get("PYTHONPATH", "")
    env["PYTHONUNBUFFERED"] = "1"
    if domain_id is None:
        env.pop("ROS_DOMAIN_ID", None)
    else:
        env["ROS_DOMAIN_ID"] = str(domain_id)
    return env


def spawn_node(module: str, domain_id: int, *ros_args: str) -> subprocess.Popen:
    """``python -m module --ros-args ...`` on ``domain_id``, stdout+stderr captured as text."""
    return subprocess.Popen([sys.executable, "-m", module, "--ros-args", *ros_args], cwd=REPO,
                            env=ros_env(domain_id), stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def stop_nodes(procs: dict[str, subprocess.Popen], timeout_s: float = 10.0) -> tuple[dict[str, int], dict[str, str]]:
    """SIGINT each running node of ``procs`` (name -> process), wait for all: their exit codes, and the last lines
    of what each node that did not exit 0 printed (for the assertion's message: why it failed).  A teardown stuck
    in the middleware and ended by the node's ExitWatchdog backstop (its stack dump, ``Timeout (``, then exit 1:
    seen about once in a few hundred stops on a loaded machine; the node's work was over) counts as the clean
    stop (0) it was, as the bring-up tests count it; its output is still returned."""
    import signal

    for p in procs.values():
        if p.poll() is None:
            p.send_signal(signal.SIGINT)
    codes = {m: p.wait(timeout_s) for m, p in procs.items()}
    said = {}
    for m, c in codes.items():
        if c != 0:
            try:
                out = procs[m].communicate(timeout=5)[0] or ""
            except (subprocess.TimeoutExpired, ValueError, OSError) as e:
                out = f"(its output could not be read: {e})"
            said[m] = "\n".join(out.splitlines()[-25:])
            if c == 1 and "Timeout (" in out:
                codes[m] = 0
    return codes, said


def node_pid(node: str, *must_contain: str, timeout_s: float = 60.0) -> int:
    """The pid of a running graph node's process — any runner: the python entry point (``sys.argv[0] = 'node'``),
    ``lib/<pkg>/<node>``, ``ros2 run`` — whose command line holds every ``must_contain`` string (its run's
    mission file or bag folder: never another test's node); the launcher itself is never it."""
    import re
    import time

    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout_s:
        for f in Path("/proc").glob("[0-9]*/cmdline"):
            try:
                cmd = f.read_bytes().replace(b"\0", b" ").decode(errors="replace") + " "
            except OSError:
                continue
            if "launcher" not in cmd and re.search(rf"(\b|/|'){node}(\b|')", cmd) \
                    and all(s in cmd for s in must_contain):
                return int(f.parent.name)
        time.sleep(0.2)
    raise AssertionError(f"no {node} process with {must_contain}")


def status_sim_time(text: str) -> float | None:
    """The sim time of the last bb2-launch status line in ``text`` (``sim 12.35 s``), or None."""
    import re

    found = re.findall(r"sim\s+([0-9.]+) s", text)
    return float(found[-1]) if found else None


def read_until_sim_time(p: subprocess.Popen, min_sim_s: float = 0.0, timeout_s: float = 240.0) -> str:
    """Read a running bb2-launch's stderr until its monitor line shows the sim time past ``min_sim_s`` (> 0: the
    graph steps); returns what it printed."""
    import time

    seen = ""
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout_s:
        line = p.stderr.readline()
        if not line and p.poll() is not None:
            break
        seen += line
        t = status_sim_time(line)
        if t is not None and t > min_sim_s:
            return seen
    raise AssertionError(f"the graph never passed sim time {min_sim_s:g} s:\n{seen[-3000:]}")


def wait_for_clock(domain_id: int, min_sim_s: float, timeout_s: float = 120.0) -> float:
    """Listen to /clock on ``domain_id`` in this process until a graph's sim time passes ``min_sim_s`` (the graph
    steps, however long a loaded machine took to bring its nodes up); returns that time. AssertionError after
    ``timeout_s`` of wall time."""
    import time

    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from rosgraph_msgs.msg import Clock

    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=domain_id)
    latest = [-1.0]
    try:
        node = rclpy.create_node("test_clock_probe", context=ctx)
        node.create_subscription(Clock, "/clock",
                                 lambda m: latest.__setitem__(0, max(latest[0], m.clock.sec + 1e-9 * m.clock.nanosec)),
                                 QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT))
        executor = SingleThreadedExecutor(context=ctx)
        executor.add_node(node)
        t0 = time.monotonic()
        while latest[0] <= min_sim_s:
            assert time.monotonic() - t0 < timeout_s, \
                f"the graph's /clock never passed {min_sim_s:g} s in {timeout_s:g} s (last: {latest[0]:g} s)"
            executor.spin_once(timeout_sec=0.05)
        executor.shutdown()
        node.destroy_node()
    finally:
        rclpy.shutdown(context=ctx)
    return latest[0]


class SpinningNode:
    """A node of this test process on its own rclpy context and ``domain_id``, spun on a daemon thread.

    ``__init__`` makes the context, the node ``name`` (``node_kwargs`` go to ``rclpy.create_node``) and a
    ``SingleThreadedExecutor`` holding it (``ctx``, ``node``, ``executor``), not spinning yet: a subclass creates its
    subscriptions and publishers after ``super().__init__`` and then calls :meth:`start`, which spins the executor
    (``spin_once(timeout_sec=spin_timeout_s)``) until :meth:`close`.  ``close`` stops the spinning (the thread
    joined for at most 2 s), destroys the node and shuts the context down; a second call does nothing."""

    def __init__(self, name: str, domain_id: int, *, spin_timeout_s: float = 0.05, **node_kwargs):
        import rclpy
        from rclpy.executors import SingleThreadedExecutor

        self.ctx = rclpy.Context()
        rclpy.init(context=self.ctx, domain_id=domain_id)
        self.node = rclpy.create_node(name, context=self.ctx, **node_kwargs)
        self.executor = SingleThreadedExecutor(context=self.ctx)
        self.executor.add_node(self.node)
        self.spin_timeout_s = spin_timeout_s
        self._stop = threading.Event()
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self._closed = False

    def start(self) -> SpinningNode:
        """Spin on the daemon thread (until :meth:`close`); returns self."""
        self.thread.start()
        return self

    def _spin(self) -> None:
        while not self._stop.is_set():
            self.executor.spin_once(timeout_sec=self.spin_timeout_s)

    def close(self) -> None:
        import rclpy

        if self._closed:
            return
        self._closed = True
        self._stop.set()
        if self.thread.is_alive():
            self.thread.join(2)
        self.node.destroy_node()
        rclpy.shutdown(context=self.ctx)


def launch_with_fault(mission: Path, out: Path, *args: str, fault, min_sim_s: float = 0.0,
                      timeout_s: float = 600.0, fault_reads_launcher: bool = False) -> tuple[int, str]:
    """``bb2-launch MISSION --out OUT --end-at simulator --timeout 600 --status-period 0.5 ARGS``; once its sim
    time passes ``min_sim_s`` (a status line every 0.5 s: within a few sim seconds of it however fast the machine),
    ``fault()`` (a SIGKILL or SIGSTOP of a node); then the run to its end, at most ``timeout_s``.
    With ``fault_reads_launcher`` the fault is called as ``fault(launcher, seen)`` (the running bb2-launch and what
    it printed so far: it may read on, e.g. :func:`read_until_sim_time`) and returns what it read.
    Returns (exit code, everything it printed on stderr); the launcher is killed if the test fails meanwhile."""
    p = subprocess.Popen([sys.executable, "-m", "bb2_tools.launcher", str(mission), "--out", str(out), "--end-at",
                          "simulator", "--timeout", "600", "--status-period", "0.5", *args], cwd=out.parent,
                         env=ros_env(),
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    seen = ""
    try:
        seen = read_until_sim_time(p, min_sim_s)
        try:
            if fault_reads_launcher:
                seen += fault(p, seen)
            else:
                fault()
        except OSError as exc:  # e.g. the node's process gone before its SIGCONT: say what the launcher saw
            p.kill()
            _, err = p.communicate(timeout=30)
            raise AssertionError(f"the fault failed ({exc!r}); bb2-launch printed:\n{(seen + err)[-4000:]}") from exc
        _, err = p.communicate(timeout=timeout_s)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
    return p.returncode, seen + err


def last_statuses(bag: Path) -> dict[str, dict[str, str]]:
    """Each node's last ``/bb2/status`` in a bag: status name -> its key/values."""
    from bb2_tools.bagfile import BagReader

    return BagReader(bag).last_statuses()


def library_trajectory(mission_file: Path):
    """``[t, x(12)]`` of every step of the library mission runner on ``mission_file`` (what the lockstep graph must
    equal), as an array."""
    import numpy as np

    from bb2_mission import MissionRunner, load_mission

    runner = MissionRunner(load_mission(mission_file))
    xs = [np.r_[runner.sim.t, runner.sim.x]]
    while not runner.done:
        runner.step()
        xs.append(np.r_[runner.sim.t, runner.sim.x])
    return np.array(xs)


_domain_claims: list[int] = []  # the claims' lock descriptors, held until this test process ends
claimed_ids: list[int] = []     # the domains this test process claimed
_port_holds: dict = {}          # their discovery ports' sockets by domain, held with the claims


def claimed_domain() -> int:
    """A ROS domain id in 102..232 that no other test process of this machine holds: claimed with the launcher's
    lock files (``bb2_tools.graph_monitor.claim_domain``; bb2-launch picks its own in 1..101), so tests running in
    parallel (``pytest -n``) or beside another test run never share a domain.  The claim is held until this test
    process ends.  Its discovery multicast port is held too (shared, as Fast DDS binds it:
    ``bb2_ros.discovery_port.hold_discovery_port``): most of these domains' ports lie in Linux's ephemeral range,
    and an unrelated socket given that port would leave every participant there deaf.  A domain whose port is held
    unshared already is passed over."""
    import os
    import random

    from bb2_ros.discovery_port import hold_discovery_port
    from bb2_tools.graph_monitor import claim_domain

    ids = range(102, 233)
    for d in random.sample(ids, len(ids)):
        fd = claim_domain(d)
        if fd is None:
            continue
        port = hold_discovery_port(d)
        if port is None:
            os.close(fd)
            continue
        _domain_claims.append(fd)
        _port_holds[d] = port
        claimed_ids.append(d)
        return d
    raise AssertionError("every ROS domain in 102..232 is claimed by another test process or its discovery port "
                         "is taken")


def block_discovery_port(domain_id: int):
    """Take ``domain_id``'s discovery port (claimed by this process, :func:`claimed_domain`) from Fast DDS as an
    unrelated ephemeral socket would: the claim's shared hold is closed and a socket without ``SO_REUSEADDR`` binds
    the port.  Returns that socket; close it to free the port."""
    import socket

    from bb2_ros.discovery_port import discovery_multicast_port

    if (held := _port_holds.pop(domain_id, None)) is not None:
        held.close()
    plain = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    plain.bind(("0.0.0.0", discovery_multicast_port(domain_id)))
    return plain


def descendants(root: int) -> list[int]:
    """The processes below ``root`` (from /proc), parents before their children."""
    kids: dict[int, list[int]] = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            ppid = int(stat.read_text().rsplit(")", 1)[1].split()[1])
        except (OSError, IndexError, ValueError):
            continue
        kids.setdefault(ppid, []).append(int(stat.parent.name))
    out, todo = [], [root]
    while todo:
        for k in kids.get(todo.pop(0), []):
            out.append(k)
            todo.append(k)
    return out


def own_dds_segment(pid: int, timeout_s: float = 30.0) -> Path:
    """The Fast DDS shared-memory segment a node process owns (``/dev/shm/fastrtps_<id>``): the one whose lock file
    (``_el``) it holds open (it maps its peers' too); a killed process leaves both files."""
    import re
    import time

    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        for fd in os.listdir(f"/proc/{pid}/fd"):
            try:
                target = os.readlink(f"/proc/{pid}/fd/{fd}")
            except OSError:
                continue
            if re.fullmatch(r"/dev/shm/fastrtps_[0-9a-f]{16}_el", target):
                return Path(target[:-3])
        time.sleep(0.1)
    raise AssertionError(f"no Fast DDS segment of its own in process {pid}")


def command_line(pid: int) -> str:
    """The command line of ``pid`` ('' once it is gone)."""
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
    except OSError:
        return ""


def stop_ros2_daemons(domains) -> list[int]:
    """End the ``ros2`` CLI daemons (``ros2cli.daemon.daemonize``, one per domain, started by ``ros2 param`` /
    ``ros2 launch`` and left running by them) of ``domains``: the domains this test process claimed, so no other
    process uses them. Returns the pids signalled."""
    import os
    import re
    import signal

    wanted = {int(d) for d in domains}
    done = []
    for cmd in Path("/proc").glob("[0-9]*/cmdline"):
        line = command_line(int(cmd.parent.name))
        m = re.search(r"--ros-domain-id (\d+)", line)
        if "ros2cli.daemon.daemonize" in line and m and int(m.group(1)) in wanted:
            try:
                os.kill(int(cmd.parent.name), signal.SIGTERM)
                done.append(int(cmd.parent.name))
            except OSError:
                pass
    return done
