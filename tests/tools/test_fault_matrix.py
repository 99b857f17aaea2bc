"""Issue 10, point 7: the fault matrix of the README, one test per cell, on the real graph over real DDS.

Each node of the control side of the launched graph (simulator, planner, path_following, l1_autopilot, mixer) is
killed (SIGKILL) or frozen for 5 s (SIGSTOP, then SIGCONT) in the middle of a short ``bb2-launch`` run, in
lockstep and in real time (``rate_hz`` 60: three times real time, still stepping on wall deadlines).  The fault
comes once the loop is closed (a probe on the run's domain has seen ``/bb2/planes/cmd`` answer 20 steps).  Each test
asserts what the README's "Fault matrix" says: the launcher's exit code and the line naming the node, what the
simulator's ``/bb2/status`` said (as recorded), and what the bag holds (readable, states complete up to where,
the holes in the commands).  The recorder's four cells are in ``test_recording_gaps.py``.

The cells are independent runs; the module's fixture runs two at a time (each waits on DDS, on its 5 s stop or on
the wall clock most of the time): 215-260 s measured for the file on this 2-core machine at a load average of 5-8
(other graph tests beside it); 158-190 s in the idle suite once the nodes' start-up imports went (2026-12-07), about
300 s of CPU (183 s alone).
"""
from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import threading
import time
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from rosenv import descendants, ros_env  # noqa: E402  (tests/rosenv.py)

from bb2_msgs_py.contract import QOS

REPO = Path(__file__).resolve().parents[2]
PY = sys.executable
TS = 0.05  # the ROM's step, s

pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=300)]  # slow: started first (tests/conftest.py)

NODES = ("simulator", "planner", "path_following", "l1_autopilot", "mixer")
CONTROLLERS = ("path_following", "l1_autopilot", "mixer")
FAULTS = ("SIGKILL", "SIGSTOP")
MODES = ("lockstep", "realtime")
OUTPUT = {"path_following": "/bb2/guidance/rate_cmd", "l1_autopilot": "/bb2/autopilot/vh_cmd",
          "mixer": "/bb2/planes/cmd"}  # what each controller publishes, one message per state it answers
STOP_S = 5.0  # the SIGSTOP, wall s
# what a process publishes after the signal was sent: the signal lands at its next return from the kernel and
# a loaded machine may first run what it was doing (two states published 60-77 ms after a SIGSTOP were seen
# while the suite ran); the stream must still stand still for the rest of the STOP_S
FAULT_GRACE_S = 0.25
RT_RATE_HZ = 60.0  # real time: 3 sim s per wall s
LOCKSTEP_TIMEOUT_S = 1.0  # config/bb2_graph.yaml's default
INJECT_AFTER = 20  # the fault comes once plane commands answered this many steps (1 s of sim time)
LAUNCH_TIMEOUT_S = 180.0  # bb2-launch --timeout: never reached by a cell (each ends long before)
PARALLEL = 2  # cells run at once by the fixture


def duration_s(node: str, fault: str, mode: str) -> float:
    """Sim seconds of the mission: the run still steps well after the fault (a 5 s stop of a controller in real
    time is 15 s of sim time, and the real-time loop closes a few seconds into the run)."""
    if mode == "lockstep":  # long enough that the probe sees the loop close before the end, even at 20x
        return 60.0
    return 15.0 if (node, fault) == ("simulator", "SIGSTOP") else 32.0  # a frozen simulator's time stands still


# ================================================================================ processes
def node_pid(launcher_pid: int, node: str) -> int | None:
    """The pid of ``node``'s process among the launcher's descendants (entry point, lib executable or ros2 run;
    the deepest match: under ``ros2 run`` the node's own process)."""
    pat = re.compile(rf"(bb2_(?:ros|tools)\.{node}:main|lib/bb2_(?:ros|tools)/{node}\b|bb2_(?:ros|tools) {node}\b)")
    found = None
    for pid in descendants(launcher_pid):  # parents before children
        try:
            cmd = Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue
        if pat.search(cmd):
            found = pid
    return found


_RCLPY_SETUP = threading.Lock()
"""The cells run side by side in threads of this process: their probes' rclpy context and node set-up and tear-down
go one at a time (a probe closing while another was being made crashed the test process once: a segfault in rcl)."""


class Probe:
    """A tiny rclpy node on the run's domain: the latest ``/bb2/planes/cmd`` stamp and how many came (the loop answered those steps)."""

    def __init__(self, domain_id: int):
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions

        from bb2_msgs_py.contract import message_class, qos_profile

        self.last_cmd_s: float | None = None
        self.n_cmds = 0
        self.closed_loop = threading.Event()
        with _RCLPY_SETUP:
            self.context = Context()
            rclpy.init(context=self.context, domain_id=domain_id, signal_handler_options=SignalHandlerOptions.NO)
            self.node = rclpy.create_node("fault_matrix_probe", context=self.context, start_parameter_services=False,
                                          enable_rosout=False)
            self.node.create_subscription(message_class("sensor_msgs/msg/JointState"), "/bb2/planes/cmd",
                                          self._on_cmd, qos_profile("/bb2/planes/cmd"))
            self.executor = SingleThreadedExecutor(context=self.context)
            self.executor.add_node(self.node)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def _on_cmd(self, msg) -> None:
        t = round(msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9, 6)
        if self.last_cmd_s is None or t > self.last_cmd_s:  # a new step answered (not a re-sent state)
            self.last_cmd_s = t
            self.n_cmds += 1
        if self.n_cmds >= INJECT_AFTER:
            self.closed_loop.set()

    def _spin(self) -> None:
        while not self._stop.is_set():
            try:
                self.executor.spin_once(timeout_sec=0.05)
            except Exception:
                if self._stop.is_set():
                    break
                raise

    def close(self) -> None:
        import rclpy

        self._stop.set()
        self._thread.join(timeout=2.0)
        with _RCLPY_SETUP:
            self.executor.shutdown(timeout_sec=1.0)
            self.node.destroy_node()
            if self.context.ok():
                rclpy.shutdown(context=self.context)


# ================================================================================ one cell
@dataclass
class Cell:
    """What one faulted run did."""

    node: str
    fault: str
    mode: str
    duration_s: float
    returncode: int
    stderr: str
    run: Path
    fault_at_s: float  # the latest answered step when the fault came (sim s)
    fault_wall: float  # wall time (time.time()) just after the SIGKILL / SIGSTOP
    resume_wall: float | None  # just before the SIGCONT
    logs: dict[str, str] = field(default_factory=dict)
    truncated: bool = True
    counts: dict[str, int] = field(default_factory=dict)
    stamps: dict[str, list[float]] = field(default_factory=dict)  # header stamps (data[0] for the state), s
    walls: dict[str, list[float]] = field(default_factory=dict)  # publish (DDS source) wall times, s
    statuses: list[dict[str, str]] = field(default_factory=list)  # the simulator's /bb2/status values, in order
    wall_s: float = 0.0  # how long the cell took
    sequences: dict[str, list[tuple[int, float]]] = field(default_factory=dict)  # (publication sequence, stamp)
    gaps: list = field(default_factory=list)  # the recording gaps the bag says (bagfile.bag_gaps)

    @property
    def states(self) -> list[float]:
        """The distinct states the bag holds (re-sends of a state counted once), sim s."""
        return sorted(set(self.stamps.get("/bb2/state_native", [])))

    def holes(self, topic: str, after_s: float = -1.0) -> list[tuple[float, float]]:
        """Stretches of sim time (from, to) in which ``topic`` has no stamp, longer than one step."""
        ts = sorted(set(t for t in self.stamps.get(topic, []) if t > after_s))
        return [(a, b) for a, b in zip(ts, ts[1:]) if b - a > 1.5 * TS]

    def said_lost(self, topic: str) -> list[tuple[float, float]]:
        """Stretches of sim time (from, to), open at both ends, between two recorded messages of ``topic`` whose
        publication sequence numbers jump: messages lost before the recorder (under CPU contention a reliable
        command topic can lose one), each of them said in the bag's gaps, which this asserts."""
        seq = self.sequences.get(topic, [])  # in the bag's order (one writer: the killed cells restart nothing)
        out = []
        for (s1, t1), (s2, t2) in zip(seq, seq[1:]):
            if s2 - s1 > 1:
                assert any(g.topic == topic and g.after_sequence == s1 and g.before_sequence == s2
                           for g in self.gaps), (topic, s1, s2, self.gaps)   # a loss is said, never silent
                out.append((t1, t2))
        return out


_start_lock = threading.Lock()
_last_start = [0.0]


def _staggered() -> None:
    """Launches at least 2 s apart: each launcher's domain check sees the other's monitor node."""
    with _start_lock:
        wait = _last_start[0] + 2.0 - time.monotonic()
        if wait > 0:
            time.sleep(wait)
        _last_start[0] = time.monotonic()


STAMPED = ("/bb2/guidance/rate_cmd", "/bb2/autopilot/vh_cmd", "/bb2/planes/cmd", "/bb2/propeller/cmd")


def read_bag(cell: Cell) -> None:
    from bb2_tools.bagfile import BagReader

    bag = BagReader(cell.run)
    cell.truncated = bag.truncated
    cell.counts = bag.message_counts
    topics = [t for t in (*STAMPED, "/bb2/state_native", "/bb2/status") if t in bag.topics]
    for m in bag.raw_messages(topics):
        cell.walls.setdefault(m.topic, []).append(m.publish_time_ns * 1e-9)
    from bb2_tools.bagfile import bag_gaps

    cell.gaps = bag_gaps(bag) or []
    decoded = bag.messages(["/bb2/planes/cmd"]) if "/bb2/planes/cmd" in bag.topics else []
    raws = bag.raw_messages(["/bb2/planes/cmd"]) if "/bb2/planes/cmd" in bag.topics else []
    for m, (_topic, _log, msg) in zip(raws, decoded):
        stamp = round(msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9, 6)
        cell.sequences.setdefault("/bb2/planes/cmd", []).append((int(m.sequence), stamp))
    for topic, _log, msg in bag.messages(topics):
        if topic == "/bb2/status":
            cell.statuses += [{kv.key: kv.value for kv in st.values} for st in msg.status if "simulator" in st.name]
        elif topic == "/bb2/state_native":
            cell.stamps.setdefault(topic, []).append(round(float(msg.data[0]), 6))
        else:
            cell.stamps.setdefault(topic, []).append(round(msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9, 6))


def run_cell(tmp: Path, node: str, fault: str, mode: str) -> Cell:
    """Launch the graph on a short straight mission, inject ``fault`` into ``node`` once the loop is closed, wait
    for the launcher to end, read the bag."""
    duration = duration_s(node, fault, mode)
    mission = tmp / "mission.yaml"
    mission.write_text(f"extends: {REPO / 'missions' / 'straight.yaml'}\nname: fault_{node}\n"
                       f"duration_s: {duration}\n")
    params = tmp / "params.yaml"
    params.write_text(f"/**:\n  ros__parameters:\n    rate_hz: {RT_RATE_HZ}\n")
    run = tmp / "run"
    _staggered()
    t_launch = time.monotonic()
    p = subprocess.Popen([PY, "-m", "bb2_tools.launcher", str(mission), "--mode", mode, "--params", str(params),
                          "--out", str(run), "--timeout", str(LAUNCH_TIMEOUT_S)],
                         cwd=tmp, env=ros_env(), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    err: list[str] = []
    domain = threading.Event()
    domain_id: list[int] = []

    def read() -> None:
        for line in iter(p.stderr.readline, ""):
            err.append(line)
            if not domain.is_set() and (m := re.search(r"ROS_DOMAIN_ID=(\d+)", line)):
                domain_id.append(int(m.group(1)))
                domain.set()
        domain.set()

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    pid, probe = None, None
    try:
        assert domain.wait(60) and domain_id, "".join(err)
        probe = Probe(domain_id[0])
        t0 = time.monotonic()
        while not probe.closed_loop.wait(0.1):
            assert p.poll() is None and time.monotonic() - t0 < 150, "the loop never closed:\n" + "".join(err)
        pid = node_pid(p.pid, node)
        assert pid is not None, f"no process of {node} under the launcher:\n" + "".join(err)
        os.kill(pid, signal.SIGKILL if fault == "SIGKILL" else signal.SIGSTOP)
        fault_wall, resume_wall = time.time(), None
        fault_at = probe.last_cmd_s
        probe.close()
        probe = None
        if fault == "SIGSTOP":
            time.sleep(STOP_S)
            resume_wall = time.time()
            os.kill(pid, signal.SIGCONT)
        p.wait(timeout=LAUNCH_TIMEOUT_S + 60)
    finally:
        if probe is not None:
            probe.close()
        if pid is not None and fault == "SIGSTOP":
            try:
                os.kill(pid, signal.SIGCONT)
            except ProcessLookupError:
                pass
        if p.poll() is None:
            p.kill()
            p.wait()
        reader.join(timeout=10)
    cell = Cell(node, fault, mode, duration, p.returncode, "".join(err), run, fault_at, fault_wall, resume_wall)
    cell.wall_s = time.monotonic() - t_launch
    cell.logs = {f.stem: f.read_text(errors="replace") for f in (run / "logs").glob("*.log")}
    read_bag(cell)
    return cell



# ================================================================================ the matrix
CELLS = [(n, f, m) for n in NODES for f in FAULTS for m in MODES]


@pytest.fixture(scope="module")
def matrix(request, tmp_path_factory):
    """The runs of the selected cells, ``PARALLEL`` at a time, the longest first: cell -> Future[Cell]."""
    pytest.importorskip("rclpy")
    wanted = [tuple(item.callspec.params["cell"]) for item in request.session.items
              if getattr(item, "originalname", "") == "test_fault_matrix" and hasattr(item, "callspec")]
    wanted.sort(key=lambda c: (c[1] != "SIGSTOP", c[2] != "realtime"))
    pool = ThreadPoolExecutor(PARALLEL, thread_name_prefix="cell")
    futures: dict[tuple, Future] = {c: pool.submit(run_cell, tmp_path_factory.mktemp("_".join(c)), *c)
                                    for c in wanted}
    yield futures
    pool.shutdown(wait=True, cancel_futures=True)


def _published_between(cell: Cell, topic: str, a: float, b: float) -> list[float]:
    return [w for w in cell.walls.get(topic, []) if a < w < b]


def check_common(cell: Cell) -> None:
    """No traceback anywhere, a complete bag (metadata and summary) whose states have no hole from t = 0, a fault
    in the middle of the run."""
    assert "Traceback" not in cell.stderr, cell.stderr
    for name, text in cell.logs.items():
        assert "Traceback" not in text, f"{name}.log:\n{text[-3000:]}"
    assert (cell.run / "metadata.yaml").is_file() and not cell.truncated
    st = cell.states
    assert st and st[0] == 0.0 and not cell.holes("/bb2/state_native"), (st[:3], cell.holes("/bb2/state_native"))
    assert 0.0 < cell.fault_at_s < cell.duration_s - 2.0, cell.fault_at_s


def teardown_hangs(cell: Cell) -> set[str]:
    """Nodes whose rclpy teardown hung after the graph was told to stop, bounded by their ExitWatchdog (its stack
    dump in the node's log, exit 1) and said by the launcher "during shutdown": not the fault's doing.  Seen once per
    few full suites beside two CPU hogs (the main thread in rclpy's ``EventHandler.__exit__``); left open in
    issue 10."""
    out = set()
    for m in re.findall(r"during shutdown: node '(\w+)' ended \(exit code 1\)", cell.stderr):
        log = cell.logs.get(m, "")
        if "Timeout (" in log or "still running" in log:
            out.add(m)
    return out


def summary_line(cell: Cell) -> str:
    lines = [ln for ln in cell.stderr.splitlines() if re.match(r"\[bb2-launch\] .*: sim time .*, exit code \d+$", ln)]
    assert len(lines) == 1, cell.stderr
    return lines[0]


def check_killed(cell: Cell) -> None:
    """The launcher names the node, stops the graph, exits 1; the bag holds everything up to the kill and
    nothing of the node after it; the run never finished."""
    n = cell.node
    assert cell.returncode == 1, cell.stderr
    assert f"[bb2-launch] stopping: node '{n}' failed (killed by SIGKILL)" in cell.stderr, cell.stderr
    # (sim time "--": the launcher's monitor had no /clock sample yet, seen on short runs of a loaded machine)
    assert re.match(rf"\[bb2-launch\] node '{n}' failed \(killed by SIGKILL\): sim time ([0-9.]+ s|--), .*exit code 1$",
                    summary_line(cell)), cell.stderr
    ended = set(re.findall(r"node '(\w+)' ended \(", cell.stderr)) - (teardown_hangs(cell) - {n})
    assert ended == {n}, cell.stderr   # no other node failed
    st = cell.states
    assert cell.fault_at_s <= st[-1] < cell.duration_s - 1.0, (cell.fault_at_s, st[-1])
    # starting until the first step, then running to the kill: the simulator says each at once (before 2026-12-07
    # only every wall second, and a real-time cell killed within its first second had recorded none), and the
    # fault comes after the loop has closed, so both are in the bag
    states = [s.get("state") for s in cell.statuses]
    stepped = next((i for i, x in enumerate(states) if x != "starting"), len(states))
    assert 0 < stepped < len(states) and all(x == "running" for x in states[stepped:]), states
    killed_topic = {"simulator": "/bb2/state_native", **OUTPUT}.get(n)
    if killed_topic and killed_topic not in cell.stamps:
        # killed before the recorder had matched its writer (seen beside two CPU hogs and with three cells at once:
        # path_following killed 3 s into the run, the mixer 1 s in; their commands reached the next node, no sample
        # the recorder, and the transient-local history died with the writer): only early in the run
        assert cell.fault_at_s <= 10.0 and n != "simulator", (killed_topic, cell.fault_at_s)
    elif killed_topic:  # nothing of the killed node after the kill; its last message answers (or is) the last state
        assert not _published_between(cell, killed_topic, cell.fault_wall + FAULT_GRACE_S, float("inf")), killed_topic
        # (its very last sample may die in flight with it: the mixer had it, the recorder not yet)
        assert cell.fault_at_s - 2 * TS <= max(cell.stamps[killed_topic]) <= st[-1]
    # every state from the first recorded answer (real time starts on the failsafe until the controllers answer)
    # up to the fault was answered
    if "/bb2/planes/cmd" not in cell.stamps:  # the mixer (or what feeds it) killed before the recorder matched it
        assert cell.fault_at_s <= 10.0, cell.fault_at_s
        return
    answered = set(cell.stamps["/bb2/planes/cmd"])
    # (a killed controller's last samples may die in flight, as above: the probe saw the mixer answer a state whose
    # answer the recorder never got -- seen with the mixer killed in real time -- or the next stage never got them)
    upto = cell.fault_at_s - (2 * TS if n in CONTROLLERS else 0.0)
    # (an answer lost before the recorder is allowed where the bag says it: seen once, one /bb2/planes/cmd of a
    # real-time cell in a full suite beside two CPU hogs)
    said = cell.said_lost("/bb2/planes/cmd")
    # (real time: the chain's later links may still be matching, or making their first slow answers, for a moment
    # after the first answer -- seen beside two CPU hogs: the state at 0.85 s unanswered after the first answer at
    # 0.80 s; the state at 0 answered, then none up to 1.30 s (0.43 s of wall time) -- so it is checked from where
    # the loop is steadily closed, STEADY_STEPS states answered in a row; lockstep waits for every answer, so it is
    # checked from the first)
    start = min(answered) if cell.mode == "lockstep" else steady_from(st, answered, upto)
    assert start is not None, ("the loop never steadily closed before the fault", sorted(answered)[:40], upto)
    unanswered = [t for t in st if start <= t <= upto + 1e-9 and t not in answered
                  and not any(a < t < b for a, b in said)]
    assert not unanswered, (start, unanswered[:5], said)


STEADY_STEPS = 10  # real time: the loop is closed once this many states in a row were answered (0.5 s of sim time)


def steady_from(states: list[float], answered: set[float], upto: float) -> float | None:
    """The first state from which ``STEADY_STEPS`` states in a row, all before ``upto``, were answered; None if none."""
    for i in range(len(states) - STEADY_STEPS + 1):
        run = states[i:i + STEADY_STEPS]
        if run[-1] <= upto + 1e-9 and all(t in answered for t in run):
            return run[0]
    return None


def check_completed(cell: Cell) -> None:
    assert cell.returncode == 0, cell.stderr
    assert "[bb2-launch] stopping: mission complete" in cell.stderr, cell.stderr
    assert re.match(rf"\[bb2-launch\] mission complete: sim time {cell.duration_s:.2f} s, .*exit code 0$",
                    summary_line(cell)), cell.stderr
    hung = teardown_hangs(cell)
    assert "failed" not in cell.stderr, cell.stderr   # no node reported, but a bounded teardown hang
    assert set(re.findall(r"node '(\w+)' ended \(", cell.stderr)) <= hung, cell.stderr
    assert cell.states[-1] == pytest.approx(cell.duration_s)   # every state 0 .. duration (no hole: check_common)
    assert cell.statuses[-1]["state"] == "finished" and cell.statuses[-1]["failsafe"] == "false", cell.statuses[-1]


def _failsafe_statuses(cell: Cell) -> list[dict[str, str]]:
    return [s for s in cell.statuses if s["failsafe"] == "true" and float(s["sim_time_s"]) >= cell.fault_at_s]


def check_simulator_frozen(cell: Cell) -> None:
    """Sim time stands still for the stop (no state published), then the run goes on to the end with every step."""
    check_completed(cell)
    assert not _published_between(cell, "/bb2/state_native", cell.fault_wall + FAULT_GRACE_S, cell.resume_wall)
    w = cell.walls["/bb2/state_native"]
    assert max(b - a for a, b in zip(w, w[1:])) >= STOP_S - 0.5
    last = cell.statuses[-1]
    if cell.mode == "lockstep":  # the watchdog wakes first: a few steps on the held commands at most (one per
        assert int(last["lockstep_timeouts"]) <= 3, last  # lockstep_timeout_s while the answers come through)
    else:  # the missed deadlines are one overrun; the schedule restarts from the resume
        assert int(last["overruns"]) >= 1, last


def check_planner_frozen(cell: Cell) -> None:
    """Nothing happens: the path is latched and already held by path_following."""
    check_completed(cell)
    assert cell.counts["/bb2/path"] == 1 and cell.counts["/bb2/path/bernstein"] == 1
    if cell.mode == "lockstep":  # every step answered at once
        assert not _failsafe_statuses(cell), _failsafe_statuses(cell)[:1]
        assert cell.statuses[-1]["lockstep_timeouts"] == "0", cell.statuses[-1]
        assert not cell.holes("/bb2/planes/cmd", after_s=cell.fault_at_s - TS), cell.holes("/bb2/planes/cmd")
        return
    # real time: the loop goes on through the stop, the plane commands keep coming on the wall clock.  (A
    # failsafe of the loaded machine's own -- the controllers starved past command_timeout_s, seen in a full suite
    # with a second cell starting beside it -- is allowed when it is brief: a stopped controller would hold it the
    # whole 5 s; here no wall gap in the commands comes near that.)
    w = _published_between(cell, "/bb2/planes/cmd", cell.fault_wall, cell.resume_wall)
    assert len(w) >= 0.5 * STOP_S * RT_RATE_HZ, (len(w), STOP_S * RT_RATE_HZ)
    gaps = [b - a for a, b in zip([cell.fault_wall, *w], [*w, cell.resume_wall])]
    assert max(gaps) < 0.5 * STOP_S, max(gaps)


def check_controller_frozen(cell: Cell) -> None:
    """The simulator steps on the failsafe while the controller stands, releases it when the answers come back,
    and the run completes."""
    check_completed(cell)
    out = OUTPUT[cell.node]
    assert not _published_between(cell, out, cell.fault_wall + FAULT_GRACE_S, cell.resume_wall), out
    fs = _failsafe_statuses(cell)
    assert fs, [(s["sim_time_s"], s["failsafe"]) for s in cell.statuses]
    last = cell.statuses[-1]
    if cell.mode == "lockstep":  # a step per lockstep timeout; the late answers of those steps are in the bag
        assert fs[0]["failsafe_reason"].startswith("lockstep timeout"), fs[0]
        assert 2 <= int(last["lockstep_timeouts"]) <= STOP_S / LOCKSTEP_TIMEOUT_S + 2, last
        assert not cell.holes(out, after_s=cell.fault_at_s - TS), cell.holes(out)
    else:  # the failsafe after command_timeout_s (0.5 s): planes neutral; a hole in the node's output
        # (the plane and the propeller commands go stale within a tick of each other: either may be said first)
        assert fs[0]["failsafe_reason"].startswith("no valid"), fs[0]
        assert any("planes neutral" in s["failsafe_reason"] for s in fs), [s["failsafe_reason"] for s in fs]
        # the hole on the wall clock: nothing from the node for the whole stop
        w = cell.walls[out]
        assert max(b - a for a, b in zip(w, w[1:])) >= STOP_S - 0.5, out
        # the hole in sim time: on SIGCONT the node is repaired the states it missed that the simulator's writer
        # still keeps (its history depth, 100) and answers them late, so the hole is what the simulator stepped
        # during the stop less those (15 s at 60 Hz on an idle machine, less when the real-time loop itself was
        # starved: seen beside two CPU hogs, a full stop's hole under 2 s)
        stepped = len(set(_published_between(cell, "/bb2/state_native", cell.fault_wall, cell.resume_wall)))
        depth = QOS["command"].depth
        holes = cell.holes(out, after_s=cell.fault_at_s - TS)
        if stepped > depth + 20:
            assert holes and max(b - a for a, b in holes) >= (stepped - depth - 20) * TS, (holes, stepped)
        if holes:
            assert max(cell.stamps[out]) >= max(b for _, b in holes)   # it answers again after its hole
        assert max(cell.stamps[out]) > cell.fault_at_s + stepped * TS - TS   # and after the stop


def check_frozen_said(cell: Cell) -> None:
    """bb2-launch says which node is stopped, and when it runs again (once each; a node that does not hold the run
    may still be stopped when the run ends)."""
    n = cell.node
    assert cell.stderr.count(f"[bb2-launch] node '{n}' is stopped (process state T") == 1, cell.stderr
    again = re.findall(rf"\[bb2-launch\] node '{n}' runs again after ([0-9.]+) s stopped", cell.stderr)
    assert len(again) <= 1 and all(STOP_S - 1.0 <= float(a) <= STOP_S + 2.0 for a in again), cell.stderr
    if n == "simulator":  # it holds the run: the run goes on only once it runs again
        assert len(again) == 1, cell.stderr
    assert not re.search(r"node '(?!" + n + r"')\w+' is stopped", cell.stderr), cell.stderr


@pytest.mark.parametrize("cell", CELLS, ids=["-".join(c) for c in CELLS])
def test_fault_matrix(matrix, cell):
    c = matrix[tuple(cell)].result(timeout=1200)
    check_common(c)
    if c.fault == "SIGSTOP":
        check_frozen_said(c)
    if c.fault == "SIGKILL":
        check_killed(c)
    elif c.node == "simulator":
        check_simulator_frozen(c)
    elif c.node == "planner":
        check_planner_frozen(c)
    else:
        check_controller_frozen(c)
