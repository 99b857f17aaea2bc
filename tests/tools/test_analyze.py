"""bb2-analyze on bags built in-process from the library mission runner.

Each test bag holds what the node graph publishes for the same ticks (the contract conversions,
serialized with rclpy and written with BagWriter as the recorder writes them): the runner's state at
every tick, the stack's path error / rate / deltaV-deltaH / plane / propeller commands stamped with it,
the ROM's actual planes after the step, the final state (which the path follower also answers, as in
the graph), the exact Bernstein path and the path samples.  The analysis must then reproduce the
runner's own figures.
"""
from __future__ import annotations

import base64
import dataclasses
import io
import math
import re
import shutil
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest

rclpy = pytest.importorskip("rclpy", reason="rclpy (ROS 2 Jazzy wheels) not installed")

from rclpy.serialization import serialize_message  # noqa: E402

from bb2_msgs_py import conversions as cv  # noqa: E402
from bb2_msgs_py.contract import topic  # noqa: E402
from bb2_tools import analyze as an  # noqa: E402
from bb2_tools.analysis import analyze  # noqa: E402
from bb2_tools.bag_run import read_bag  # noqa: E402
from bb2_tools.bagfile import BagWriter, qos_entry  # noqa: E402
from bb2_mission import MissionRunner, load_mission  # noqa: E402
from bb2_tools.recorder import tf_from_odometry  # noqa: E402

TWO_PI = 2.0 * math.pi


def _qos(name: str) -> list[dict]:
    q = topic(name).qos_description
    return [qos_entry(reliability=q.reliability, durability=q.durability, history=q.history, depth=q.depth)]


class _Bag:
    """BagWriter plus serialize_message, topics added on first use (as the recorder does)."""

    def __init__(self, out: Path, custom: dict[str, str], chunk_size: int, topics: set[str] | None):
        self.w = BagWriter(out, chunk_size=chunk_size, custom_data=custom)
        self.only = topics

    def put(self, name: str, msg, t: float) -> None:
        if self.only is not None and name not in self.only:
            return
        if name not in self.w.topics:
            self.w.add_topic(name, topic(name).type, offered_qos=_qos(name))
        ns = cv.seconds_to_ns(t)
        self.w.write(name, serialize_message(msg), ns, time.time_ns())
        if name == "/bb2/odom":
            if "/tf" not in self.w.topics:
                self.w.add_topic("/tf", "tf2_msgs/msg/TFMessage", offered_qos=_qos("/tf"))
            self.w.write_dict("/tf", tf_from_odometry(msg), ns, time.time_ns())


def _publish_state(bag: _Bag, state, terrain) -> None:
    t = state.t
    bag.put("/clock", cv.clock_message(t), t)
    bag.put("/bb2/state_native", cv.state_native_message(state), t)
    bag.put("/bb2/odom", cv.state_to_odometry(state), t)
    bag.put("/bb2/depth", cv.depth_message(t, state.depth_m), t)
    if terrain is not None:
        try:
            alt = float(terrain.clearance(state.p_native))
        except ValueError:
            alt = math.inf
        bag.put("/bb2/altitude", cv.altitude_message(t, alt), t)


def _publish_answers(bag: _Bag, t: float, out) -> None:
    bag.put("/bb2/guidance/rate_cmd", cv.rate_command_message(t, out.q_c, out.r_c), t)
    bag.put("/bb2/guidance/path_error", cv.path_error_message(t, [0.0, out.e_horizontal_m, out.e_vertical_m]), t)
    bag.put("/bb2/autopilot/vh_cmd", cv.vh_message(t, math.radians(out.dV_deg), math.radians(out.dH_deg)), t)
    bag.put("/bb2/planes/cmd", cv.planes_message(t, np.radians(out.planes_deg)), t)
    bag.put("/bb2/propeller/cmd", cv.propeller_message(t, out.rps * TWO_PI), t)


def write_mission_bag(mission, out: Path, *, custom: dict[str, str] | None = None, chunk_size: int = 64 * 1024,
                      topics: set[str] | None = None, progress_one_at: float | None = None):
    """Fly ``mission`` with the library runner, writing the graph's messages of every tick; (bag, result)."""
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
    from std_msgs.msg import Header

    runner = MissionRunner(mission)
    bag = _Bag(out, custom or {"recorder": "tests/ros/test_analyze.py"}, chunk_size, topics)
    path = mission.path
    bag.put("/bb2/path/bernstein", cv.bernstein_message(path), 0.0)
    native = path.to_frame("native") if path.frame != "native" else path
    bag.put("/bb2/path", cv.path_message(0.0, native.sample(401)[1]), 0.0)
    rows = []
    wall0 = time.perf_counter()
    while not runner.done:
        st = runner.step()
        rows.append(st.row.values())
        _publish_state(bag, st.state, mission.terrain)
        _publish_answers(bag, st.state.t, st.output)
        if progress_one_at is not None:  # as the path follower: 1 from the tick its virtual time ends on
            from std_msgs.msg import Float64
            t = st.state.t
            bag.put("/bb2/mission/progress", Float64(data=1.0 if t >= progress_one_at - 1e-9 else t / 1e3), t)
        if st.record is not None:
            bag.put("/bb2/planes/state", cv.planes_message(st.record.t, np.radians(st.record.act.planes_deg)),
                    st.record.t)
            bag.put("/bb2/propeller/state", cv.propeller_message(st.record.t, st.record.act.rps * TWO_PI),
                    st.record.t)
    from bb2_sim.state import VehicleState

    final = VehicleState.from_vector(runner.sim.t, runner.sim.x)
    _publish_state(bag, final, mission.terrain)
    _publish_answers(bag, final.t, runner.stack.step(final))  # the graph answers the last state too
    rtf = runner.sim.t / (time.perf_counter() - wall0)
    status = DiagnosticStatus(name="bb2/simulator", message="finished", values=[  # as the simulator's last one
        KeyValue(key="state", value="finished"), KeyValue(key="duration_s", value=f"{mission.duration:g}"),
        KeyValue(key="real_time_factor", value=f"{rtf:.3f}"), KeyValue(key="mission_file", value="")])
    bag.put("/bb2/status", DiagnosticArray(header=Header(stamp=cv.stamp(final.t)), status=[status]), final.t)
    bag.w.close()
    arr = np.array(rows)
    from bb2_mission import MISSION_COLUMNS

    traj = {c: arr[:, i] for i, c in enumerate(MISSION_COLUMNS)}
    return out, runner, traj


def _short(name: str, seconds: float, **kw):
    m = load_mission(name)
    return dataclasses.replace(m, duration_s=seconds, **kw)


@pytest.fixture(scope="module")
def bags(tmp_path_factory):
    root = tmp_path_factory.mktemp("analyze")
    circle = _short("circle", 40.0)
    out = {}
    out["circle"] = write_mission_bag(circle, root / "circle")
    out["circle_noad"] = write_mission_bag(circle.with_adaptation(False), root / "circle_noad")
    out["circle_odom"] = write_mission_bag(circle, root / "circle_odom", topics={
        "/bb2/odom", "/bb2/path", "/bb2/guidance/path_error", "/bb2/autopilot/vh_cmd", "/clock"})
    canyon_file = Path(an.__file__).resolve().parents[1] / "missions" / "canyon.yaml"
    canyon = dataclasses.replace(load_mission(canyon_file), duration_s=15.0)
    out["canyon"] = write_mission_bag(canyon, root / "canyon", custom={"mission_file": str(canyon_file)})
    out["root"] = root
    return out


def _summary_of(runner, traj):
    from bb2_mission import summarize

    return summarize(runner, traj, runner.mission.path.to_frame("native")
                     if runner.mission.path.frame != "native" else runner.mission.path, 1.0)


# ------------------------------------------------------------------------------------------ agreement
def test_path_errors_equal_runner(bags):
    bag, runner, traj = bags["circle"]
    s = _summary_of(runner, traj)
    a = analyze(read_bag(bag))
    f = a.figures
    assert a.run.state_source == "state_native" and a.run.path_source == "/bb2/path/bernstein"
    assert f.times.ticks == len(traj["t_s"])  # the final state (answered by the graph) is not a tick
    pe, pc = f.path_error, f.path_error_closest
    for k, v in (("rms_vertical_m", pe.rms_vertical_m), ("max_vertical_m", pe.max_vertical_m),
                 ("rms_horizontal_m", pe.rms_horizontal_m), ("max_horizontal_m", pe.max_horizontal_m),
                 ("rms_vertical_closest_m", pc.rms_vertical_m), ("max_vertical_closest_m", pc.max_vertical_m),
                 ("rms_horizontal_closest_m", pc.rms_horizontal_m),
                 ("max_horizontal_closest_m", pc.max_horizontal_m), ("mission_time_s", f.times.mission_time_s)):
        assert abs(v - getattr(s, k)) <= 1e-9, (k, v, getattr(s, k))
    np.testing.assert_allclose(a.e_vertical, traj["e_vertical_m"], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(a.run.x[:-1, 0], traj["x_m"])
    # command statistics from the same samples
    assert f.commands.dV.unit == "rad"
    assert f.commands.dV.max_abs == pytest.approx(np.max(np.abs(np.radians(traj["dV_deg"]))), abs=1e-12)
    assert f.commands.planes_cmd.max_abs_rad == pytest.approx(
        np.max(np.abs(np.radians([traj[f"cmd_d{i}_deg"] for i in range(1, 6)]))), abs=1e-12)
    assert 0.0 <= f.commands.planes.any_saturated_fraction <= 1.0
    assert math.isfinite(f.real_time_factor) and f.real_time_factor > 0
    assert f.clearance.min_clearance_m is None and f.clearance.min_altitude_m is None  # circle: no terrain
    # the named figures (printed, figures.json) are these records flattened, in a fixed order
    named = a.named_figures
    assert list(named)[:5] == ["mission_time_s", "recorded_time_s", "ticks", "rms_vertical_m", "max_vertical_m"]
    assert named["ticks"] == f.times.ticks and named["rms_horizontal_closest_m"] == pc.rms_horizontal_m
    assert named["planes_cmd_d3_max_abs_rad"] == f.commands.planes_cmd.max_abs_each_rad[2]
    assert named["dH_max_abs_rate_rad_s"] == f.commands.dH.max_abs_rate
    assert "min_clearance_m" not in named and list(named)[-1] == "real_time_factor"


def test_analysis_ends_where_the_mission_finished(bags):
    """A graph run records past the finish (the launcher stops on the progress it sees): the analysis stops at
    the tick whose progress is 1 and the state after it, so its figures are those of a run that ended there."""
    bag_a, runner_a, traj_a = bags["circle"]  # ended by its 40 s duration: last tick t = 39.95 s
    longer = _short("circle", 46.0)
    bag_b, _, _ = write_mission_bag(longer, bags["root"] / "circle_past_finish", progress_one_at=39.95)
    a = analyze(read_bag(bag_a))
    b = analyze(read_bag(bag_b))
    assert b.figures.times.ticks == a.figures.times.ticks == len(traj_a["t_s"])
    assert b.figures.path_error == a.figures.path_error  # rms/max, vertical/horizontal
    assert b.figures.times.mission_time_s == a.figures.times.mission_time_s
    assert b.figures.path_error_closest.rms_vertical_m == a.figures.path_error_closest.rms_vertical_m
    assert b.figures.times.mission_time_s == pytest.approx(40.0)
    assert b.figures.times.recorded_time_s == pytest.approx(46.0)
    assert any("finished at t = 39.95 s" in w and "not analysed" in w for w in b.warnings)
    assert not any("finished at" in w for w in a.warnings)


def test_odometry_only_bag(bags):
    """Without /bb2/state_native and the Bernstein path: odometry back to native, the sampled path."""
    bag, runner, traj = bags["circle_odom"]
    a = analyze(read_bag(bag))
    assert a.run.state_source == "odometry" and a.run.path_source == "/bb2/path"
    np.testing.assert_allclose(a.run.x[:-1, 0:3], np.c_[traj["x_m"], traj["y_m"], traj["z_m"]], atol=1e-9)
    np.testing.assert_allclose(np.degrees(a.run.x[:-1, 5]), traj["psi_deg"], atol=1e-7)
    s = _summary_of(runner, traj)
    assert abs(a.figures.path_error.rms_vertical_m - s.rms_vertical_m) <= 1e-9  # path_error topic: exact
    # closest point on 401 samples vs the exact path: close, and flagged
    assert a.figures.path_error_closest.rms_horizontal_m == pytest.approx(s.rms_horizontal_closest_m, abs=0.05)
    assert any("odometry" in w for w in a.warnings) and any("resolution-limited" in w for w in a.warnings)


def test_ground_clearance_from_mission(bags):
    bag, runner, traj = bags["canyon"]
    s = _summary_of(runner, traj)
    a = analyze(read_bag(bag))  # the mission comes from the bag's custom_data
    assert a.mission is not None and a.mission.terrain is not None
    assert math.isfinite(s.min_clearance_m)
    cl = a.figures.clearance
    assert abs(cl.min_clearance_m - s.min_clearance_m) <= 1e-9
    assert abs(cl.min_hull_clearance_m - s.min_hull_clearance_m) <= 1e-9
    assert cl.min_clearance_t_s == s.min_clearance_t_s
    # without the mission: the altimeter, and a warning that says so
    run = read_bag(bag)
    run.custom_data.pop("mission_file")
    b = analyze(run)
    assert b.figures.clearance.min_clearance_m is None and math.isfinite(b.figures.clearance.min_altitude_m)
    assert any("altimeter" in w for w in b.warnings)


def test_end_of_the_run_by_the_runner_rules(bags, tmp_path):
    """The run's end, as the library runner would give it: the duration, the finish (progress 1), and the first
    tick that breaks the mission's limits -- found in a bag whose graph flew on past it -- with the runner's own
    message; figures.json and the printout carry it."""
    bag, runner, traj = bags["circle"]
    a = analyze(read_bag(bag))
    assert runner.end_reason.value == "duration" and a.figures.end.reason == "duration"
    assert not a.figures.end.completed and a.figures.end.message == ""
    past = bags["root"] / "circle_past_finish"  # written by test_analysis_ends_where_the_mission_finished
    if not past.exists():
        write_mission_bag(_short("circle", 46.0), past, progress_one_at=39.95)
    b = analyze(read_bag(past))
    assert b.figures.end.reason == "finished" and b.figures.end.completed and b.figures.end.t_s == pytest.approx(40.0)

    # the canyon bag flew 15 s; a mission with a hull-clearance limit it crosses on the way grounds there
    cbag, crunner, ctraj = bags["canyon"]
    hull = ctraj["hull_clearance_m"]
    limit = float(hull[0] + np.nanmin(hull)) / 2.0
    tight = dataclasses.replace(crunner.mission, limits=dataclasses.replace(crunner.mission.limits,
                                                                            min_hull_clearance_m=limit))
    ref = MissionRunner(tight).run()
    assert ref.summary.end_reason.value == "grounded" and 0.0 < ref.summary.event.t < 14.0
    c = analyze(read_bag(cbag), mission=tight)
    end = c.figures.end
    assert (end.reason, end.t_s, end.message) == ("grounded", ref.summary.event.t, str(ref.summary.event))
    assert any(w.startswith(f"the run grounded at t = {ref.summary.event.t:.2f} s") for w in c.warnings)
    assert f"  end: {str(ref.summary.event)}" in an.figure_lines(c)
    files = an.write_outputs([c], tmp_path / "out")
    import json

    doc = next(iter(json.loads(files["figures_json"].read_text()).values()))
    assert doc["end"] == {"reason": "grounded", "t_s": ref.summary.event.t, "completed": False,
                          "message": str(ref.summary.event)}


# ------------------------------------------------------------------------------------------ CLI
def test_two_bags_overlay_and_differences(bags, capsys, tmp_path):
    (b1, r1, t1), (b2, r2, t2) = bags["circle"], bags["circle_noad"]
    s1, s2 = _summary_of(r1, t1), _summary_of(r2, t2)
    out = tmp_path / "cmp"
    assert an.main([str(b1), str(b2), "--out", str(out), "--label", "L1 on", "--label", "L1 off"]) == 0
    text = capsys.readouterr().out
    assert "comparison  A = L1 on  B = L1 off" in text
    line = next(ln for ln in text.splitlines() if ln.strip().startswith("rms_vertical ") and "L1" not in ln
                and len(ln.split()) >= 5)
    _, va, vb, d, unit = line.split()
    assert unit == "m"
    assert float(va) == pytest.approx(s1.rms_vertical_m, abs=1e-4)
    assert float(vb) == pytest.approx(s2.rms_vertical_m, abs=1e-4)
    assert float(d) == pytest.approx(s2.rms_vertical_m - s1.rms_vertical_m, abs=2e-4)
    assert s1.rms_vertical_m != s2.rms_vertical_m  # the runs really differ
    html = (out / "report.html").read_text()
    assert "B - A" in html and html.count("data:image/png;base64,") == 6
    import json

    doc = json.loads((out / "figures.json").read_text())
    cmp = {r["figure"]: r for r in doc["comparison"]}
    assert cmp["max_horizontal_m"]["B_minus_A"] == pytest.approx(s2.max_horizontal_m - s1.max_horizontal_m, abs=1e-9)


def test_a_fleet_folder_reports_every_vehicle_as_alone_and_side_by_side(bags, capsys, tmp_path):
    """Issue 13, point 4: ``bb2-analyze FLEET_DIR`` (a folder of boat bags, as fleet.launch.py writes them) prints
    every vehicle's figures as ``bb2-analyze`` of its bag alone does, then one table with a column per vehicle;
    each vehicle's report goes into ``analysis/<boat>/`` and figures.json holds them all.  Three bags or more
    given one by one are a fleet too."""
    import json

    fleet = tmp_path / "fleet_20261203_120000"
    fleet.mkdir()
    boats = {"boat1": "circle", "boat2": "circle_noad", "boat3": "canyon"}
    for name, key in boats.items():
        shutil.copytree(bags[key][0], fleet / name)
    alone = {}
    for name, key in boats.items():
        assert an.main([str(bags[key][0]), "--no-report", "--label", name]) == 0
        alone[name] = capsys.readouterr().out.splitlines()[1:]  # after the label and source line
    assert an.main([str(fleet)]) == 0
    text = capsys.readouterr().out
    for name in boats:
        block = text.split(f"{name}: {fleet / name}\n", 1)[1].splitlines()[:len(alone[name])]
        assert block == alone[name], name
    table = text.split("fleet  3 vehicles: boat1, boat2, boat3\n", 1)[1].splitlines()
    assert table[0].split() == ["figure", "boat1", "boat2", "boat3"]
    row = next(ln.split() for ln in table if ln.split()[0] == "rms_vertical")
    for name, value in zip(boats, row[1:4]):
        s = _summary_of(*bags[boats[name]][1:])
        assert float(value) == pytest.approx(s.rms_vertical_m, abs=1e-4), name
    assert row[4] == "m" and row[1] != row[2]  # the vehicles really differ
    doc = json.loads((fleet / "analysis" / "figures.json").read_text())
    assert list(doc) == list(boats) and all((fleet / "analysis" / b / "report.html").is_file() for b in boats)
    assert an.main([str(fleet)]) == 2  # the reports are there: not overwritten without --overwrite
    err = capsys.readouterr().err
    assert "report.html exists (give --overwrite" in err and len(err.strip().splitlines()) == 1, err
    spread = [str(fleet / b) for b in boats]
    assert an.main([*spread, "--no-report"]) == 0
    assert "fleet  3 vehicles: boat1, boat2, boat3" in capsys.readouterr().out


def test_a_fleet_bag_one_recorder_for_all_reads_and_reports_every_vehicle_as_alone(bags, capsys, tmp_path):
    """Issue 13, point 4: the one bag of a fleet's recorder (every boat's topics under its namespace,
    ``/boat1/bb2/odom``, one ``/tf``): ``BagReader(bag, vehicle)`` reads a boat under the contract's names, its gaps
    too; ``bb2-analyze FLEET_BAG`` prints every vehicle as ``bb2-analyze`` of its own bag does, then the table."""
    import json

    from bb2_tools.bagfile import GAPS_KEY, BagError, BagReader, Gap, bag_gaps

    boats = {"boat1": "circle", "boat2": "canyon"}
    fleet = tmp_path / "fleet_20261204_120000"
    lost = Gap("/boat2/bb2/odom", 2, 10, 13, 0.5, 0.65)  # a gap of boat2's, said in the fleet bag's metadata
    with BagWriter(fleet, custom_data={GAPS_KEY: json.dumps([lost.as_dict()])}) as w:
        for name, key in boats.items():
            r = BagReader(bags[key][0])
            infos = {t.name: t for t in r.topic_infos()}
            for m in r.raw_messages(file_order=True):
                topic = m.topic if m.topic in ("/tf", "/tf_static") else f"/{name}{m.topic}"
                w.add_topic(topic, m.type, offered_qos=infos[m.topic].offered_qos, dds_sequence=infos[m.topic].dds_sequence)
                w.write(topic, m.data, m.log_time_ns, m.publish_time_ns, sequence=m.sequence)
    bag = BagReader(fleet)
    assert bag.vehicles == ["boat1", "boat2"] and "/bb2/odom" not in bag.topics
    b2 = BagReader(fleet, "boat2")
    alone2 = BagReader(bags["canyon"][0])
    assert b2.topics == alone2.topics  # its own topics under the contract's names and the global /tf, /tf_static
    mine = {k: v for k, v in b2.message_counts.items() if k not in ("/tf", "/tf_static")}
    assert mine == {k: v for k, v in alone2.message_counts.items() if k not in ("/tf", "/tf_static")}
    assert b2.message_counts["/tf"] == bag.message_counts["/tf"] > alone2.message_counts["/tf"]  # every boat's
    assert [m.data for m in b2.raw_messages("/bb2/state_native")] == \
        [m.data for m in alone2.raw_messages("/bb2/state_native")]
    assert bag_gaps(b2) == [Gap("/bb2/odom", 2, 10, 13, 0.5, 0.65)] and bag_gaps(BagReader(fleet, "boat1")) == []
    with pytest.raises(BagError, match="no vehicle 'boat3' in the bag"):
        BagReader(fleet, "boat3")
    alone = {}
    for name, key in boats.items():
        assert an.main([str(bags[key][0]), "--no-report", "--label", name]) == 0
        alone[name] = capsys.readouterr().out.splitlines()[1:]
    assert an.main([str(fleet)]) == 0
    text = capsys.readouterr().out
    for name in boats:
        # (boat2 read from the fleet bag says its gap; alone it has none; alone, the canyon's terrain is known from
        # its bag's custom_data mission_file, which this hand-made fleet bag has not -- a fleet recorder's bag
        # knows it from each boat's bb2/status -- so the terrain figures are left out)
        def mine(lines):
            return [ln for ln in lines if not any(w in ln for w in ("warning", "clearance", "altitude", "terrain"))]
        own = mine(alone[name])
        block = mine(text.split(f"{name}: {fleet}\n", 1)[1].splitlines())
        assert block[:len(own)] == own, name
    assert "fleet  2 vehicles: boat1, boat2" in text
    assert "gap(s) on /bb2/odom: 1 gap(s), 2 message(s) lost" in text.split(f"boat2: {fleet}\n", 1)[1]
    doc = json.loads((fleet / "analysis" / "figures.json").read_text())
    assert list(doc) == list(boats) and (fleet / "analysis" / "boat2" / "report.html").is_file()


def test_truncated_bag_read_to_last_chunk(bags, tmp_path, capsys):
    bag, runner, traj = bags["circle"]
    mcap = next(bag.glob("*.mcap"))
    data = mcap.read_bytes()
    cut = tmp_path / "killed"
    cut.mkdir()
    (cut / "killed_0.mcap").write_bytes(data[: len(data) // 2])  # no metadata.yaml: recorder killed
    run = read_bag(cut)
    assert run.truncated and 10 < len(run.t) < len(traj["t_s"])
    a = analyze(run)
    k = a.figures.times.ticks
    ev = traj["e_vertical_m"][:k]
    assert abs(a.figures.path_error.rms_vertical_m - math.sqrt(np.mean(ev ** 2))) <= 1e-9
    assert any("truncated" in w for w in a.warnings)
    assert an.main([str(cut), "--out", str(tmp_path / "rep")]) == 0
    assert "truncated" in capsys.readouterr().out
    assert "truncated bag" in (tmp_path / "rep" / "report.html").read_text()


def test_bad_inputs_exit_2(bags, tmp_path, capsys):
    assert an.main([str(tmp_path / "nope")]) == 2
    assert "no bag at" in capsys.readouterr().err
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"this is not an mcap file at all" * 10)
    assert an.main([str(junk)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("bb2-analyze: error:") and len(err.strip().splitlines()) == 1
    with BagWriter(tmp_path / "clock_only") as w:  # a valid bag without any usable topic
        w.add_topic("/clock", "rosgraph_msgs/msg/Clock")
        w.write("/clock", serialize_message(cv.clock_message(1.0)), 1_000_000_000)
    assert an.main([str(tmp_path / "clock_only")]) == 2
    assert "no usable topics" in capsys.readouterr().err
    bad_mission = tmp_path / "bad.yaml"
    bad_mission.write_text("path: circle_r400\nbogus_key: 1\n")
    assert an.main([str(bags["circle"][0]), "--mission", str(bad_mission), "--no-report"]) == 2
    assert "bogus_key" in capsys.readouterr().err
    assert an.main([str(bags["circle"][0])] * 3) == 2


# ------------------------------------------------------------------------------------------ HTML in Chromium
def _png_sizes(html: str) -> list[tuple[int, int]]:
    import matplotlib.image as mpimg

    sizes = []
    for b64 in re.findall(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"', html):
        raw = base64.b64decode(b64, validate=True)
        assert raw.startswith(b"\x89PNG\r\n\x1a\n")
        img = mpimg.imread(io.BytesIO(raw), format="png")
        sizes.append(img.shape[:2])
    return sizes


def test_report_renders_in_chromium(bags, tmp_path):
    bag = bags["canyon"][0]
    out = tmp_path / "report"
    assert an.main([str(bag), "--out", str(out)]) == 0
    html_file = out / "report.html"
    html = html_file.read_text()
    # self-contained: every image decodes, nothing is referenced outside the file
    sizes = _png_sizes(html)
    assert len(sizes) == 6 and all(h > 300 and w > 500 for h, w in sizes)
    refs = re.findall(r'(?:src|href)\s*=\s*"([^"]*)"', html)
    assert refs and all(r.startswith("data:image/png;base64,") for r in refs), [r[:40] for r in refs]
    assert "<script" not in html and "url(" not in html
    chromium = shutil.which("chromium")
    if chromium is None:
        pytest.skip("chromium not installed (run tools/install_chromium.sh): screenshot check skipped")
    shot = tmp_path / "shot.png"
    proc = subprocess.run(
        [chromium, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         f"--user-data-dir={tmp_path / 'profile'}", "--enable-logging=stderr", "--v=0",
         f"--screenshot={shot}", "--window-size=1400,2000", html_file.as_uri()],
        capture_output=True, text=True, timeout=90)
    assert proc.returncode == 0 and shot.is_file(), proc.stderr[-2000:]
    console = [ln for ln in proc.stderr.splitlines() if "CONSOLE" in ln or "Uncaught" in ln
               or "Failed to load resource" in ln or "net::ERR" in ln]
    assert not console, console
    import matplotlib.image as mpimg

    img = mpimg.imread(shot)[:, :, :3]
    assert img.shape[0] >= 1900 and img.shape[1] >= 1300
    px = (img * 255).round().astype(int)
    non_white = np.mean(np.any(px < 235, axis=2))
    assert non_white > 0.05, f"screenshot nearly blank ({non_white:.3f} non-white)"
    colours = len(np.unique(px[::4, ::4].reshape(-1, 3) // 16, axis=0))
    assert colours > 40, f"only {colours} colour bins: the figures did not render"
    # the track (tab:blue 31,119,180) and the path (tab:red 214,39,40) of the plots are on screen
    def near(rgb):
        return int(np.sum(np.all(np.abs(px - np.array(rgb)) < 30, axis=2)))

    assert near((31, 119, 180)) > 200 and near((214, 39, 40)) > 100


def test_a_run_the_graph_stopped_before_its_end_says_so(bags):
    """A graph stopped before the mission's end (``bb2-launch --timeout``, Ctrl-C, a node that failed, its stall
    check) was reported as ended at its ``duration``: now ``stopped``, where, and whether the simulator was
    stepping on its failsafe; a simulator that said ``finished``, or a recording that reaches the duration, ends
    at the duration as before."""
    from bb2_tools.bag_run import StatusEntry

    bag, runner, _traj = bags["circle"]  # 40 s flown, its mission's duration; the simulator said finished
    assert analyze(read_bag(bag)).figures.end.reason == "duration"

    def stopped_run(**values):  # the bag as a graph stopped at 40 s leaves it: its simulator never finished
        run = read_bag(bag)
        run.status = [st for st in run.status if st.name != "bb2/simulator"]
        if values:
            run.status.append(StatusEntry(40.0, "bb2/simulator", {"state": "running", **values}))
        return run

    longer = dataclasses.replace(runner.mission, duration_s=60.0)  # no duration in its statuses: the mission's
    end = analyze(stopped_run(), mission=longer).figures.end
    assert (end.reason, end.t_s) == ("stopped", pytest.approx(40.0)) and not end.completed, end
    assert end.message == ("stopped at t = 40.00 s, before the mission's end (duration 60 s): the recording ends "
                           "there (the graph or its recorder was stopped)")
    assert analyze(stopped_run(), mission=runner.mission).figures.end.reason == "duration"  # it reached its end
    # the simulator's own duration first (its duration_s parameter may replace the mission's); its failsafe said
    end = analyze(stopped_run(duration_s="600", failsafe="true", failsafe_reason="lockstep timeout: neutral planes, "
                             "this step's propeller"), mission=longer).figures.end
    assert end.message == ("stopped at t = 40.00 s, before the mission's end (duration 600 s): the recording ends "
                           "there (the graph or its recorder was stopped); the simulator was stepping on its "
                           "failsafe (lockstep timeout: neutral planes, this step's propeller)"), end
    assert analyze(stopped_run(duration_s="40"), mission=longer).figures.end.reason == "duration"


# ------------------------------------------------------------------------------------------ maneuver
def test_a_missions_run_with_a_maneuvers_figures_keeps_its_own_end(bags):
    """--maneuver on a mission's bag (a turn of the path read as a turning circle): the maneuver's figures, and the
    run's end as the runner gives it (it was dropped, as for a maneuver's bag, which has no mission end)."""
    bag, runner, _traj = bags["circle"]
    a = analyze(read_bag(bag), maneuver="turning-circle")
    assert a.maneuver == "turning-circle" and a.maneuver_figures is not None
    assert a.figures.end.reason == runner.end_reason.value == "duration"


def test_maneuver_settings_are_checked_not_ignored(bags):
    """--maneuver-settings with a misspelt key ({"rudder": 20}), or on a bag that names no maneuver without
    --maneuver, were ignored without a word: each is refused, the misspelt key with the likely one."""
    from bb2_tools.bag_run import AnalysisError

    bag, _runner, _traj = bags["circle"]
    with pytest.raises(AnalysisError, match=r"unknown maneuver setting\(s\) \['rudder'\] \(did you mean 'rudder_deg'\?\); "
                                            r"the figures read: settle_window_s, amplitude_deg"):
        analyze(read_bag(bag), maneuver="turning-circle", maneuver_settings={"rudder": 20})
    with pytest.raises(AnalysisError, match="maneuver settings apply to a maneuver's figures: name the maneuver"):
        analyze(read_bag(bag), maneuver_settings={"length_m": 70.0})
    a = analyze(read_bag(bag), maneuver="turning-circle", maneuver_settings={"rudder_deg": 20, "length_m": 35.0})
    b = analyze(read_bag(bag), maneuver="turning-circle")
    assert a.maneuver_figures is not None and a.maneuver_figures != b.maneuver_figures  # length_m read


def test_maneuver_figures_from_bag(tmp_path):
    """A turning circle recorded as the simulator would publish it: bb2_sim.metrics figures from the bag."""
    from dataclasses import asdict

    from bb2_sim.maneuvers import maneuver_settings, run_maneuver
    from bb2_sim.metrics import figures_for
    from bb2_sim.state import VehicleState

    s = maneuver_settings("turning-circle", duration=150.0)
    res = run_maneuver(s)
    tr = res.traj
    bag = _Bag(tmp_path / "tc", {"maneuver": "turning-circle"}, 64 * 1024, None)
    for k in range(len(tr["t_s"])):
        t = float(tr["t_s"][k])
        x = np.array([tr[c][k] for c in ("x_m", "y_m", "z_m")]
                     + [math.radians(tr[c][k]) for c in ("phi_deg", "theta_deg", "psi_deg")]
                     + [tr[c][k] for c in ("u_m_s", "v_m_s", "w_m_s")]
                     + [math.radians(tr[c][k]) for c in ("p_deg_s", "q_deg_s", "r_deg_s")])
        _publish_state(bag, VehicleState.from_vector(t, x), None)
        bag.put("/bb2/planes/state", cv.planes_message(t, np.radians([tr[f"dX{i}_deg"][k] for i in range(1, 6)])), t)
        bag.put("/bb2/planes/cmd", cv.planes_message(t, np.radians([tr[f"cmd_dX{i}_deg"][k] for i in range(1, 6)])), t)
        bag.put("/bb2/propeller/state", cv.propeller_message(t, tr["n_rps"][k] * TWO_PI), t)
    bag.w.close()
    a = analyze(read_bag(tmp_path / "tc"))
    assert a.maneuver == "turning-circle" and a.maneuver_figures is not None
    assert a.figures.end.reason == ""   # a maneuver's bag: no mission end
    want = figures_for("turning-circle", tr, **asdict(s)).to_dict()
    got = a.maneuver_figures.to_dict()
    assert math.isfinite(want["tactical_diameter_m"])  # the run reaches 180 degrees of heading change
    for k, v in want.items():
        if "thrust" in k or "torque" in k:  # not in the contract's topics: NaN from a bag
            assert not math.isfinite(got[k]), k
        elif isinstance(v, float) and math.isfinite(v):
            assert got[k] == pytest.approx(v, rel=1e-6, abs=1e-9), k
    assert a.named_figures["maneuver.tactical_diameter_m"] == got["tactical_diameter_m"]
    files = an.write_outputs([a], tmp_path / "out")
    assert "maneuver" in files and "Maneuver figures" in files["report"].read_text()
    assert a.warnings and any("no /bb2/guidance/path_error" in w for w in a.warnings)
    # n/a for want of time is said (the centre's drift needs a second turn); n/a for want of a topic is not "not
    # reached" (thrust and torque: the bag records neither)
    assert [w for w in a.warnings if "not reached" in w] == [
        "maneuver figures of 'turning-circle' not reached in this 150.0 s recording (n/a): circle_centre_drift_m"]
