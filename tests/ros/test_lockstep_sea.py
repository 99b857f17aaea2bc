"""Sea state 5 through the ROS graph in lockstep (issue 11): the canyon transit at periscope depth in a short-crested
JONSWAP sea with a current equals the library runner within 1e-9 m, and the simulator publishes the sea (latched
``/bb2/sea``) from which the same sea is rebuilt exactly; the node parameter ``sea_file`` replaces the mission's
sea (here by the bag-format description of another sea) and the graph still equals the runner given that sea.
"""
from __future__ import annotations

import json
import signal
import threading
import time
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.ros
rclpy = pytest.importorskip("rclpy", reason="rclpy (ROS 2 Jazzy wheels) not installed")

from bb2_msgs_py.contract import message_class, qos_profile  # noqa: E402

from rosenv import SpinningNode, claimed_domain, spawn_node, stop_nodes  # noqa: E402  (tests/rosenv.py)

REPO = Path(__file__).resolve().parents[2]
PARAMS = REPO / "config" / "bb2_graph.yaml"
CONTROLLERS = ("bb2_ros.planner", "bb2_ros.path_following", "bb2_ros.l1_autopilot", "bb2_ros.mixer")
DURATION_S = 15.0


class SeaListener(SpinningNode):
    """The latched /bb2/sea, received by a reader that may come late."""

    def __init__(self, domain_id: int):
        super().__init__("sea_test", domain_id)
        self.sea: list[str] = []
        self.finished = threading.Event()  # the simulator said state=finished (it stays up: exit_at_end false)
        self.node.create_subscription(message_class("std_msgs/msg/String"), "/bb2/sea",
                                      lambda m: self.sea.append(m.data), qos_profile("/bb2/sea"))
        self.node.create_subscription(message_class("diagnostic_msgs/msg/DiagnosticArray"), "/bb2/status",
                                      self._on_status, qos_profile("/bb2/status"))
        self.start()

    def _on_status(self, msg) -> None:
        if any(kv.key == "state" and kv.value == "finished" for st in msg.status if st.name == "bb2/simulator"
               for kv in st.values):
            self.finished.set()


def _library_trajectory(mission_file: Path, environment=None, commands: list | None = None) -> np.ndarray:
    from bb2_mission import MissionRunner, build_model, load_mission

    m = load_mission(mission_file)
    runner = MissionRunner(m, model=build_model(m, environment)) if environment is not None else MissionRunner(m)
    xs = [np.r_[runner.sim.t, runner.sim.x]]
    while not runner.done:
        st = runner.step()
        if commands is not None and st.output is not None:
            commands.append(np.asarray(st.output.planes_deg, float))
        xs.append(np.r_[runner.sim.t, runner.sim.x])
    return np.array(xs)


def _run_graph(tmp_path: Path, mission: Path, domain_id: int, extra: str = "") -> tuple[np.ndarray, list[str]]:
    """Fly ``mission`` through the five nodes in lockstep; the simulator's trajectory and the /bb2/sea it
    latched (read by a listener that joins while the graph runs).  The simulator stays up at the end
    (``exit_at_end`` false) until the listener has the sea: a lockstep flight of a loaded machine once ended
    before the late listener had matched the simulator (clean-clone CI: no /bb2/sea received)."""
    csv_file = tmp_path / "traj.csv"
    common = ["--params-file", str(PARAMS), "-p", f"mission_file:={mission}", "-p", "status_period_s:=0.5"]
    procs = {m: spawn_node(m, domain_id, *common) for m in CONTROLLERS}
    sim = None
    listener = None
    try:
        overrides = tmp_path / "overrides.yaml"
        overrides.write_text(f"simulator:\n  ros__parameters:\n    trajectory_csv: {csv_file}\n"
                             f"    exit_at_end: false\n    min_state_subscribers: 2\n"
                             f"    lockstep_timeout_s: 20.0\n{extra}")   # a loaded machine never steps on held
        sim = spawn_node("bb2_ros.simulator", domain_id, *common, "--params-file", str(overrides))
        listener = SeaListener(domain_id)   # joins late (the sea was published at start): transient local
        deadline = time.monotonic() + 150
        while sim.poll() is None and time.monotonic() < deadline and not (listener.finished.is_set() and listener.sea):
            time.sleep(0.1)
        assert sim.poll() is None, sim.communicate()[0]  # up at the end, until told to stop
        sim.send_signal(signal.SIGINT)
        out, _ = sim.communicate(timeout=30)
        assert listener.finished.is_set() and sim.returncode == 0, out
        assert "lockstep timeout" not in out and "no answer to step" not in out, out
        for m, p in procs.items():
            assert p.poll() is None, f"{m} died: {p.communicate()[0]}"
    finally:
        codes, said = stop_nodes(procs)
        if sim is not None and sim.poll() is None:
            sim.kill()
        seen = list(listener.sea) if listener is not None else []
        if listener is not None:
            listener.close()
    assert codes == {m: 0 for m in CONTROLLERS}, (codes, said)
    return np.loadtxt(csv_file, delimiter=",", skiprows=1), seen


def _assert_equal_runs(traj: np.ndarray, ref: np.ndarray) -> None:
    assert traj.shape == ref.shape == (int(round(DURATION_S / 0.05)) + 1, 13)
    np.testing.assert_array_equal(traj[:, 0], ref[:, 0])
    assert np.max(np.abs(traj[:, 1:4] - ref[:, 1:4])) <= 1e-9
    assert np.max(np.abs(traj[:, 4:] - ref[:, 4:])) <= 1e-9


def test_graph_in_sea_state_5_equals_library_runner_and_latches_the_sea(tmp_path):
    from bb2_mission import load_mission
    from bb2_sim.environment import environment_from_description

    mission = tmp_path / "periscope_short.yaml"
    mission.write_text(f"extends: {REPO / 'missions' / 'canyon_periscope_ss5.yaml'}\nduration_s: {DURATION_S}\n")
    ref = _library_trajectory(mission)
    traj, seen = _run_graph(tmp_path, mission, claimed_domain())
    _assert_equal_runs(traj, ref)
    assert np.ptp(ref[:, 4]) > 0.01            # the waves roll the boat (phi, rad)

    assert seen, "no /bb2/sea received"
    d = json.loads(seen[-1])
    env = load_mission(mission).environment
    assert d == json.loads(env.description_json())
    rebuilt = environment_from_description(seen[-1]).sea.wave_components()
    ours = env.sea.wave_components()
    for f in ("amplitude", "omega", "direction", "phase"):
        assert np.array_equal(getattr(rebuilt, f), getattr(ours, f))


def test_sea_file_parameter_replaces_the_mission_sea(tmp_path):
    from bb2_sim.environment import Environment, environment_from_description

    mission = tmp_path / "periscope_short.yaml"
    mission.write_text(f"extends: {REPO / 'missions' / 'canyon_periscope_ss5.yaml'}\nduration_s: {DURATION_S}\n")
    # a sea rough enough that the stack commands planes beyond the ROM's +-30 deg limit: the graph's lockstep gate
    # and the library runner clamp them by the same rule, so the runs stay equal
    other = Environment.from_mappings({"spectrum": "ittc", "hs": 3.25, "tp": 9.7, "heading_deg": 0.0,
                                       "components": 12, "seed": 1}, {"speed_mps": 0.2, "heading_deg": 90.0})
    sea_file = tmp_path / "sea.json"
    sea_file.write_text(other.description_json())
    commands: list = []
    ref = _library_trajectory(mission, environment_from_description(sea_file.read_text()), commands)
    assert np.max(np.abs(commands)) > 30.0, "the sea should drive the plane commands past the limit"
    traj, seen = _run_graph(tmp_path, mission, claimed_domain(), f"    sea_file: {sea_file}\n")
    _assert_equal_runs(traj, ref)
    assert seen and json.loads(seen[-1])["sea"]["components"]["amplitude_m"] == \
        [float(a) for a in other.sea.wave_components().amplitude]
