"""``bb2-campaign`` (issue 14) on small campaigns of short missions.

* the same results (to the last digit, wall time aside) from the local pool with 1 and 2 workers and from Ray
  on a real local cluster started here (a head and a second node, ``--node-ip-address=127.0.0.1``; Ray 2.60 maps
  a loopback address to this machine's own address, so both raylets listen there, on this machine only);
* a driver SIGKILLed mid-campaign and resumed gives exactly the full set, no duplicates; a SIGKILLed pool
  worker loses no run;
* a broken run is recorded as ``error`` with its message, and the campaign goes on;
* a malformed SPEC exits 2 with one line naming the field;
* a run flown alone (``--only INDEX --out-run DIR``) and the library runner give the campaign's row;
* a maneuver campaign, whose runs each worker flies together in the batch ROM, gives the table it gives one run at
  a time (``--batch 1``, the single-run path of ``--only`` and ``run_maneuver``) and on Ray, to the last digit;
  a run that diverges in a batch is flown again alone for its own message.
"""
from __future__ import annotations

import collections
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

pa = pytest.importorskip("pyarrow")
import pyarrow.csv  # noqa: E402,F401
import pyarrow.parquet as pq  # noqa: E402

from bb2_tools.campaign import cli  # noqa: E402
from bb2_tools.campaign.spec import parse_spec  # noqa: E402
from rosenv import descendants  # noqa: E402  (tests/rosenv.py)

pytestmark = pytest.mark.slow(seconds=150)  # started first (tests/conftest.py)

REPO = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent

# 6 draws x 2 grid points = 12 runs of 3 s of the circle mission; with seed 8, sample 1 (runs 2, 3) draws a
# negative initial speed: the mission refuses it, so those runs are errors (run 0 is valid: the probe passes).
SPEC = {
    "mission": "circle",
    "seed": 8,
    "samples": 6,
    "vary": {
        "duration_s": 3,
        "adaptation": [True, False],
        "stack.guidance.d_m": {"uniform": [200.0, 300.0]},
        "initial.speed_mps": {"uniform": [-1.0, 6.0]},
        "initial.offset_m": {"choice": [[0, 0, 0], [0, 5, -2]]},
    },
    "collect": ["rms_vertical", "rms_horizontal", "max_vertical_m", "end_reason", "mission_time_s"],
}
N_RUNS = 12
BROKEN = {2, 3}


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PATH"] = f"{BIN}{os.pathsep}{env.get('PATH', '')}"
    env["PYTHONPATH"] = str(REPO) + os.pathsep + env.get("PYTHONPATH", "")
    env.setdefault("MPLBACKEND", "Agg")
    env["RAY_USAGE_STATS_ENABLED"] = "0"
    env["RAY_AUTH_MODE"] = "disabled"   # the test cluster is on 127.0.0.1; not whatever ~/.ray/auth_token says
    return env


def _campaign(*args: str, report: bool = False, timeout: float = 240) -> subprocess.CompletedProcess:
    extra = ["--quiet"] + ([] if report else ["--no-report"])
    return subprocess.run([str(BIN / "bb2-campaign"), *args, *extra], cwd=REPO, env=_env(), capture_output=True,
                          text=True, timeout=timeout)


def _write_spec(path: Path, doc: dict) -> Path:
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def _table(out: Path):
    return pq.read_table(out / "results.parquet")


def _comparable(t) -> list[dict]:
    return [{k: v for k, v in r.items() if k != "wall_time_s"} for r in t.to_pylist()]


@pytest.fixture(scope="module")
def spec_file(tmp_path_factory) -> Path:
    return _write_spec(tmp_path_factory.mktemp("campaign") / "small.yaml", SPEC)


@pytest.fixture(scope="module")
def reference(spec_file, tmp_path_factory) -> Path:
    """The campaign flown by the local pool with 2 workers."""
    out = tmp_path_factory.mktemp("ref") / "local2"
    r = _campaign(str(spec_file), "--out", str(out), "--workers", "2", report=True)
    assert r.returncode == 0, r.stderr
    return out


# ------------------------------------------------------------------------------------------ design
def test_design_is_a_function_of_the_spec_and_the_index():
    a, b = parse_spec(SPEC), parse_spec(json.loads(json.dumps(SPEC)))
    assert a.n_runs == N_RUNS and a.n_grid == 2
    assert [a.inputs(i) for i in range(N_RUNS)] == [b.inputs(i) for i in range(N_RUNS)]
    assert len({a.run_seed(i) for i in range(N_RUNS)}) == N_RUNS
    # grid fastest: runs 2k and 2k+1 share the draws and differ in adaptation only
    i0, i1 = a.inputs(4), a.inputs(5)
    assert i0["adaptation"] is True and i1["adaptation"] is False
    assert {k: v for k, v in i0.items() if k != "adaptation"} == {k: v for k, v in i1.items() if k != "adaptation"}
    # a name of a stack becomes {base: name} with the overridden gain
    doc = a.document(0)
    assert doc["stack"] == {"base": "rate_2022", "guidance": {"d_m": a.inputs(0)["stack.guidance.d_m"]}}


def test_latin_hypercube_stratifies_every_distribution():
    s = parse_spec({"mission": "circle", "seed": 3, "samples": 10, "sampling": "latin_hypercube",
                    "vary": {"initial.offset_m.2": {"uniform": [0.0, 10.0]}, "stack.guidance.d_m": {"uniform": [0, 1]}}})
    for key, width in (("initial.offset_m.2", 10.0), ("stack.guidance.d_m", 1.0)):
        bins = sorted(int(s.inputs(i)[key] / width * 10) for i in range(10))
        assert bins == list(range(10)), (key, bins)


# ------------------------------------------------------------------------------------------ engines
def test_local_one_and_two_workers_give_the_same_results(spec_file, reference, tmp_path):
    r = _campaign(str(spec_file), "--out", str(tmp_path / "local1"), "--workers", "1")
    assert r.returncode == 0, r.stderr
    one, two = _table(tmp_path / "local1"), _table(reference)
    assert one.num_rows == N_RUNS and one.column("index").to_pylist() == list(range(N_RUNS))
    assert _comparable(one) == _comparable(two)
    assert one.schema.names == ["index", "seed", *SPEC["vary"], *SPEC["collect"], "status", "message", "wall_time_s"]
    csv_rows = (tmp_path / "local1" / "results.csv").read_text().splitlines()
    assert len(csv_rows) == N_RUNS + 1 and csv_rows[0].startswith('"index","seed","duration_s"')
    for f in ("campaign.yaml", "report.html", "results.csv"):
        assert (reference / f).stat().st_size > 0
    meta = yaml.safe_load((reference / "campaign.yaml").read_text())
    assert meta["campaign"]["runs"] == N_RUNS and meta["software"]["package"] == "bb2-sim-suite"


def test_a_broken_run_is_recorded_with_its_message(reference):
    rows = _table(reference).to_pylist()
    bad = {r["index"] for r in rows if r["status"] == "error"}
    assert bad == BROKEN
    for i in BROKEN:
        assert "initial.speed_mps must be > 0" in rows[i]["message"], rows[i]["message"]
        assert rows[i]["rms_vertical"] is None
    ok = [r for r in rows if r["status"] == "ok"]
    assert len(ok) >= 8 and all(r["mission_time_s"] == 3.0 and r["end_reason"] == "duration" for r in ok)


def test_figures_equal_the_library_runner_and_a_run_alone(spec_file, reference, tmp_path):
    """The row of run 5 = bb2_mission's runner on the overridden document = ``--only 5 --out-run DIR``."""
    from bb2_mission.runner import MissionRunner
    from bb2_mission.schema import MISSIONS_DIR, mission_from_dict

    spec = parse_spec(SPEC)
    row = _table(reference).to_pylist()[5]
    s = MissionRunner(mission_from_dict(spec.document(5), base_dir=MISSIONS_DIR)).run().summary
    assert (row["rms_vertical"], row["rms_horizontal"], row["max_vertical_m"]) == \
        (s.rms_vertical_m, s.rms_horizontal_m, s.max_vertical_m)
    r = _campaign(str(spec_file), "--only", "5", "--out-run", str(tmp_path / "run5"))
    assert r.returncode == 0, r.stderr
    alone = pa.csv.read_csv(tmp_path / "run5" / "run.csv").to_pylist()[0]
    assert {k: alone[k] for k in SPEC["collect"]} == {k: row[k] for k in SPEC["collect"]}
    assert (tmp_path / "run5" / "circle.csv").stat().st_size > 1000


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _stop(p: subprocess.Popen) -> None:
    """End a process group this test started (SIGTERM, then SIGKILL)."""
    for sig, wait in ((signal.SIGTERM, 3), (signal.SIGKILL, 5)):
        try:
            os.killpg(p.pid, sig)
        except ProcessLookupError:
            return
        try:
            p.wait(wait)
            time.sleep(0.5)
        except subprocess.TimeoutExpired:
            continue


@pytest.fixture(scope="module")
def ray_cluster(tmp_path_factory):
    """A real two-node Ray cluster on this machine: a head and a second raylet, 1 CPU each, started with
    --node-ip-address=127.0.0.1 (which Ray resolves to this machine's address), token auth off."""
    pytest.importorskip("ray")
    port = _free_port()
    env = _env()
    logs = tmp_path_factory.mktemp("ray")
    common = ["--node-ip-address=127.0.0.1", "--num-cpus=1", "--block", "--disable-usage-stats"]
    procs = []
    try:
        head = subprocess.Popen([str(BIN / "ray"), "start", "--head", f"--port={port}", "--include-dashboard=false",
                                 *common], env=env, stdout=open(logs / "head.log", "w"), stderr=subprocess.STDOUT,
                                start_new_session=True)
        procs.append(head)
        addr = f"127.0.0.1:{port}"
        probe = ("import ray, sys, time; ray.init(address=sys.argv[1], log_to_driver=False); t = time.time()\n"
                 "while sum(n['Alive'] for n in ray.nodes()) < int(sys.argv[2]) and time.time() - t < 90: time.sleep(0.5)\n"
                 "print(sum(n['Alive'] for n in ray.nodes()))")
        deadline = time.time() + 90
        while time.time() < deadline:
            try:
                with socket.create_connection(("127.0.0.1", port), timeout=1):
                    break
            except OSError:
                assert head.poll() is None, (logs / "head.log").read_text()
                time.sleep(0.5)
        node = subprocess.Popen([str(BIN / "ray"), "start", f"--address={addr}", *common], env=env,
                                stdout=open(logs / "node.log", "w"), stderr=subprocess.STDOUT, start_new_session=True)
        procs.append(node)
        r = subprocess.run([sys.executable, "-c", probe, addr, "2"], env=env, capture_output=True, text=True,
                           timeout=150)
        assert r.returncode == 0 and r.stdout.strip().splitlines()[-1] == "2", r.stdout + r.stderr
        yield addr
    finally:
        for p in reversed(procs):
            _stop(p)
        # `ray start --head` wrote its address into this machine's Ray address file, which outlives the cluster:
        # leave no stopped cluster there for a later `ray.init()`
        current = Path(os.environ.get("RAY_TMPDIR") or os.environ.get("TMPDIR") or "/tmp") / "ray" / "ray_current_cluster"
        try:
            if current.read_text().strip().endswith(f":{port}"):
                current.unlink()
        except OSError:
            pass


def test_ray_on_a_two_node_local_cluster_gives_the_same_results(spec_file, reference, ray_cluster, tmp_path):
    r = _campaign(str(spec_file), "--out", str(tmp_path / "ray"), "--engine", "ray", "--address", ray_cluster)
    assert r.returncode == 0, r.stderr
    assert _comparable(_table(tmp_path / "ray")) == _comparable(_table(reference))


# ------------------------------------------------------------------------------------------ nothing is lost
def test_sigkilled_driver_resumes_to_exactly_the_full_set(spec_file, reference, tmp_path):
    out = tmp_path / "killed"
    p = subprocess.Popen([str(BIN / "bb2-campaign"), str(spec_file), "--out", str(out), "--workers", "2", "--quiet"],
                         cwd=REPO, env=_env(), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                         start_new_session=True)
    journal = out / "runs.jsonl"
    try:
        deadline = time.time() + 120
        while time.time() < deadline and p.poll() is None:
            if journal.exists() and journal.read_bytes().count(b"\n") >= 3:
                break
            time.sleep(0.02)
        assert p.poll() is None, "the campaign ended before it could be killed"
        os.kill(p.pid, signal.SIGKILL)
        p.wait(10)
    finally:
        _stop(p)   # the pool's processes left behind (same session)
    before = journal.read_bytes().count(b"\n")
    assert 3 <= before < N_RUNS and not (out / "results.parquet").exists()
    r = _campaign(str(spec_file), "--out", str(out), "--resume", "--workers", "2")
    assert r.returncode == 0, r.stderr
    lines = [json.loads(x) for x in journal.read_text().splitlines()]
    assert sorted(x["index"] for x in lines) == list(range(N_RUNS)), "each run exactly once in the journal"
    assert _comparable(_table(out)) == _comparable(_table(reference))
    assert f"this session flew {N_RUNS - before} " in r.stdout
    again = _campaign(str(spec_file), "--out", str(out), "--resume")
    assert again.returncode == 0 and "this session flew 0 " in again.stdout


def test_an_existing_campaign_is_not_overwritten(spec_file, reference):
    r = _campaign(str(spec_file), "--out", str(reference))
    assert r.returncode == 2 and "--resume" in r.stderr and len(r.stderr.strip().splitlines()) == 1


# ------------------------------------------------------------------------------------------ bad input
BAD = [
    ({"mision": "circle"}, "mision"),
    ({}, "mission / maneuver"),
    ({"mission": "no_such_mission.yaml"}, "mission"),
    ({"mission": "circel"}, "mission: file 'circel' not found (looked beside the SPEC, in the working directory and in "
                            "missions/) (did you mean 'circle'?); shipped missions: canyon"),
    ({"mission": "circle", "samples": 0}, "samples"),
    ({"mission": "circle", "vary": {"initial.speed_mps": {"uniform": [5, 1]}}}, "vary.initial.speed_mps"),
    ({"mission": "circle", "vary": {"initial.speed_mps": {"gauss": [5, 1]}}}, "vary.initial.speed_mps"),
    ({"mission": "circle", "vary": {"bogus_field": [1, 2]}}, "vary.bogus_field"),
    ({"mission": "circle", "vary": {"initial.offset_m": {"choice": [[0, 0, 0], [1, 2]]}}}, "initial.offset_m"),
    ({"mission": "circle", "vary": {"sea_state": [0, 42]}}, "vary.sea_state"),
    # names that become file names: the --out folder, a run's CSV (../ would write outside the folder meant)
    ({"mission": "circle", "name": "../../elsewhere"}, "name must be a plain name"),
    ({"mission": "circle", "vary": {"name": ["a", "../b"]}}, "vary.name = '../b': name must be a plain name"),
    ({"mission": "circle", "vary": {"name": [1e3]}}, "vary.name = 1000.0: name must be a text"),
    ({"mission": "circle", "collect": ["rms_vertical", "rms_sideways"]}, "collect"),
    ({"mission": "circle", "collect": ["rms_vertcal"]}, "collect: unknown figure(s) ['rms_vertcal'] (did you mean "
                                                        "'rms_vertical'?) of the mission summary"),
    ({"mission": "circle", "vary": {"stack.guidance.d_mm": [100, 200]}}, "vary.stack.guidance.d_mm"),  # it flew d_m
    ({"maneuver": {"name": "barrel-roll"}}, "maneuver.name"),
    ({"maneuver": {"name": "turning-circle"}, "vary": {"rudder": [10, 20]}}, "vary.rudder"),
    ({"maneuver": {"name": "hzz"}, "vary": {"rudder_deg": [10, 20]}}, "rudder_deg not read by maneuver hzz"),
    ({"maneuver": {"name": "turning-circle", "options": {"amplitude_deg": 5}}}, "amplitude_deg not read"),
    ({"maneuver": {"name": "turning-circle", "options": {"duration_s": 20}}}, "did you mean 'duration'"),
    ({"maneuver": {"name": "turning-circle", "options": {"environment": {"hs": 2}}}}, "sea: and current: blocks"),
    ({"maneuver": {"name": "turning-circle", "options": {"sea": {"spectrum": "jonswap", "hs": 2, "tp": 8}}},
      "vary": {"sea.swell": [1, 2]}}, "vary.sea.swell"),
]


@pytest.mark.parametrize("doc, field", BAD, ids=[b[1] for b in BAD])
def test_a_malformed_spec_exits_2_with_one_line_naming_the_field(doc, field, tmp_path, capsys):
    f = _write_spec(tmp_path / "bad.yaml", doc)
    assert cli.main([str(f), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("bb2-campaign: error: ") and field in err[0], err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("doc, said", [
    ({"maneuver": {"name": "turning-circle", "options": {"rudder_deg": 35}}},
     "maneuver.options: maneuver turning-circle: the planes are asked for up to 35 deg (its rudder of 35 deg)"),
    ({"maneuver": {"name": "turning-circle"}, "vary": {"rudder_deg": {"uniform": [10, 40]}}},
     "vary.rudder_deg = 40.0: maneuver turning-circle: the planes are asked for up to 40 deg"),
    ({"maneuver": {"name": "hzz"}, "vary": {"amplitude_deg": [10, 45, 20]}},
     "vary.amplitude_deg = 45: maneuver hzz: the planes are asked for up to 45 deg (its zigzag amplitude of 45"),
    ({"maneuver": {"name": "turning-circle"}, "vary": {"rudder_deg": {"normal": [20, 10], "clip": [5, 30]}}}, None),
    ({"maneuver": {"name": "hzz"}, "vary": {"amplitude_deg": [10, 30]}}, None),
    ({"mission": "circle", "vary": {"duration_s": [10, 20]}}, None),
    ({"mission": "canyon_periscope_ss5", "vary": {"sea.hs": {"uniform": [1, 30]}}},
     "vary.sea.hs = 30.0: the sea (jonswap Hs 30 m, Tp 9.7 s"),
    ({"mission": "canyon_periscope_ss5", "vary": {"sea.hs": {"uniform": [1, 5]}}}, None),
])
def test_plane_commands_beyond_the_limit_and_seas_steeper_than_any_wave_are_warned_before_the_campaign(
        doc, said):
    """Runs past the 30 deg limit fly at the limit (as bb2-sim maneuver warns): a sweep past it would give flat
    figures without a word; a sea past Michell's steepness does not exist.  The campaign says so once per key, at
    its extreme values."""
    from bb2_tools.campaign.worker import campaign_warnings

    got = campaign_warnings(parse_spec({"seed": 1, "samples": 2, **doc}))
    if said is None:
        assert got == []
    else:
        assert len(got) == 1 and got[0].startswith(said), got


def test_a_ray_address_nobody_answers_is_said_at_once_before_the_campaign_folder(tmp_path, monkeypatch):
    """A wrong --address (nothing listens there, or auto finds a cluster that has stopped) is one line and exit 2
    within seconds, and no campaign folder is written: Ray alone retried for minutes, with the progress bar up."""
    pytest.importorskip("ray")
    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        dead = s.getsockname()[1]
    f = _write_spec(tmp_path / "s.yaml", {"mission": "circle", "samples": 2})
    for address, said in ((f"127.0.0.1:{dead}", f"--address 127.0.0.1:{dead}: no Ray cluster answers there"),
                          ("nonsense", "--address nonsense: expected auto or HOST:PORT")):
        t0 = time.monotonic()
        r = _campaign(str(f), "--out", str(tmp_path / "o"), "--engine", "ray", "--address", address, timeout=120)
        assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and said in r.stderr, r.stderr
        assert time.monotonic() - t0 < 60 and not (tmp_path / "o").exists()
    from bb2_tools.campaign.engines import RayEngine
    from bb2_tools.campaign.errors import SpecError

    monkeypatch.setenv("RAY_ADDRESS", f"127.0.0.1:{dead}")  # where auto looks first
    with pytest.raises(SpecError, match=rf"--address auto \(auto: 127.0.0.1:{dead}, .*\): no Ray cluster answers"):
        RayEngine(address="auto")._probe_address()


def test_an_address_where_something_other_than_ray_answers_is_said_as_such(monkeypatch):
    """A port that answers but is no Ray cluster (measured here: any address through this machine's proxy): Ray's
    ConnectionError, an OSError, was said as 'cannot write into out/campaigns/<name>: Failed to connect to Ray
    cluster at ...', as if the campaign folder were the fault.  (Ray's own retries take ~20 s: ray.init stands in.)"""
    ray = pytest.importorskip("ray")
    from bb2_tools.campaign.engines import RayEngine
    from bb2_tools.campaign.errors import SpecError

    with socket.socket() as s:   # something listens there
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]

        def refuse(address, **_kw):
            raise ConnectionError(f"Failed to connect to Ray cluster at {address}.\nPlease ensure ...")

        monkeypatch.setattr(ray, "init", refuse)
        with pytest.raises(SpecError, match=rf"^--engine ray: --address 127.0.0.1:{port}: Failed to connect to Ray "
                                            rf"cluster at 127.0.0.1:{port}. Please ensure ...; start a cluster with"):
            RayEngine(address=f"127.0.0.1:{port}").prepare()


def test_ray_without_an_address_starts_its_own_instance_whatever_the_last_cluster_left(tmp_path):
    """``--engine ray`` without ``--address``: a Ray instance started for this driver (RAY_ADDRESS when set).  Left
    to Ray, no address means the last cluster ``ray start`` ran on this machine too, and its address file outlives
    it (the two-node test cluster above left one): the driver retried a stopped cluster for minutes, without a
    word.  Here the machine's address file names a port nobody listens on; the campaign flies on its own."""
    pytest.importorskip("ray")
    import tempfile

    from bb2_tools.campaign.engines import RayEngine

    ray_tmp = Path(tempfile.mkdtemp(prefix="r", dir="/tmp"))   # short: Ray's socket paths live below it
    try:
        (ray_tmp / "ray").mkdir()
        (ray_tmp / "ray" / "ray_current_cluster").write_text(f"127.0.0.1:{_free_port()}")
        f = _write_spec(tmp_path / "s.yaml", {"maneuver": {"name": "turning-circle", "options": {"duration": 3}},
                                              "samples": 2, "collect": ["initial_speed_m_s"]})
        env = {**_env(), "RAY_TMPDIR": str(ray_tmp)}
        env.pop("RAY_ADDRESS", None)
        r = subprocess.run([str(BIN / "bb2-campaign"), str(f), "--out", str(tmp_path / "o"), "--engine", "ray",
                            "--workers", "1", "--quiet", "--no-report"], cwd=REPO, env=env, capture_output=True,
                           text=True, timeout=240)
        assert r.returncode == 0, r.stdout + r.stderr
        assert "ray at a local Ray instance" in r.stdout and len(_table(tmp_path / "o")) == 2, r.stdout
    finally:
        shutil.rmtree(ray_tmp, ignore_errors=True)
    old = os.environ.pop("RAY_ADDRESS", None)
    try:
        assert RayEngine()._init_address() == "local" and RayEngine(address="auto")._init_address() == "auto"
        os.environ["RAY_ADDRESS"] = "10.0.0.1:6379"
        assert RayEngine()._init_address() == "10.0.0.1:6379"
        from bb2_tools.campaign.errors import SpecError

        dead = _free_port()
        os.environ["RAY_ADDRESS"] = f"127.0.0.1:{dead}"   # probed as --address would be, and said to be RAY_ADDRESS
        with pytest.raises(SpecError, match=rf"^RAY_ADDRESS=127.0.0.1:{dead} \(no --address\): no Ray cluster answers"):
            RayEngine()._probe_address()
        assert RayEngine(address="127.0.0.1:1")._init_address() == "127.0.0.1:1"
    finally:
        os.environ.pop("RAY_ADDRESS", None)
        if old is not None:
            os.environ["RAY_ADDRESS"] = old


def test_bad_command_lines_exit_2(tmp_path):
    f = _write_spec(tmp_path / "s.yaml", {"mission": "circle"})
    r = _campaign(str(f), "--workers", "0")
    assert r.returncode == 2 and "--workers" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    r = _campaign(str(f), "--only", "3", "--out-run", str(tmp_path / "x"))
    assert r.returncode == 2 and "--only 3" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    # a campaign's options with --only were flown past without a word (one run, here, into --out-run)
    r = _campaign(str(f), "--only", "0", "--out-run", str(tmp_path / "x"), "--resume", "--out", str(tmp_path / "c"))
    assert r.returncode == 2 and r.stderr == ("bb2-campaign: error: --out, --resume go with a campaign, not --only "
                                              "(one run, flown here, written to --out-run)\n"), r.stderr
    assert not (tmp_path / "x").exists()


def test_maneuver_campaign_collects_the_printed_figures(tmp_path):
    """A maneuver campaign in-process: the figures of bb2_sim.metrics by field name and in degrees."""
    import math

    from bb2_tools.campaign.worker import run_one

    spec = parse_spec({"maneuver": {"name": "turning-circle", "options": {"duration": 20}},
                       "vary": {"rudder_deg": [10, 20]},
                       "collect": ["peak_roll_rad", "peak_roll_deg", "initial_speed_m_s", "time_90_s"]})
    row, res = run_one(spec, 1)
    assert row["status"] == "ok" and row["rudder_deg"] == 20 and res.settings.rudder_deg == 20
    # an empty cell of an ok row is said: the run was too short for it (it was an empty cell, no word)
    assert row["time_90_s"] is None and row["message"] == "not reached in this 20 s run: time_90_s", row
    assert math.isclose(row["peak_roll_deg"], math.degrees(row["peak_roll_rad"]), rel_tol=1e-15)
    row, _ = run_one(parse_spec({"maneuver": {"name": "turning-circle", "options": {"duration": 20}},
                                 "collect": ["peak_roll_rad"]}), 0)
    assert row["status"] == "ok" and row["message"] == "", row
    shutil.rmtree(tmp_path, ignore_errors=True)


def test_a_maneuver_campaign_in_a_sea_and_a_current_flies_as_bb2_sim_maneuver(tmp_path):
    """A maneuver's options take a mission's sea: and current: blocks, varied by dotted keys (each run's own seed
    its wave phases with ``seed_key: sea.seed``).  A run alone (``--only 3 --out-run DIR``) writes, byte for byte,
    the CSV that ``bb2-sim maneuver`` writes with the same sea and current options: every column, ``eta_cg_m``
    included, under a header that names them all (it named one fewer than its rows held)."""
    doc = {"maneuver": {"name": "turning-circle",
                        "options": {"rudder_deg": 20, "duration": 6,
                                    "sea": {"spectrum": "jonswap", "hs": 2, "tp": 8, "heading_deg": 45}}},
           "seed": 7, "samples": 2, "seed_key": "sea.seed",
           "vary": {"sea.hs": {"uniform": [1, 3]}, "current.speed_mps": [0, 0.5]},
           "collect": ["initial_speed_m_s", "peak_roll_deg"]}
    f = _write_spec(tmp_path / "sea.yaml", doc)
    r = _campaign(str(f), "--only", "3", "--out-run", str(tmp_path / "run3"))
    assert r.returncode == 0, r.stderr
    row = pa.csv.read_csv(tmp_path / "run3" / "run.csv").to_pylist()[0]
    assert row["status"] == "ok" and row["current.speed_mps"] == 0.5 and 1 <= row["sea.hs"] <= 3, row
    alone = tmp_path / "cli.csv"
    c = subprocess.run([str(BIN / "bb2-sim"), "maneuver", "turning-circle", "--rudder-deg", "20", "--duration", "6",
                        "--spectrum", "jonswap", "--hs", repr(row["sea.hs"]), "--tp", "8", "--wave-heading-deg", "45",
                        "--seed", str(row["seed"]), "--current-mps", "0.5", "--out", str(alone), "--quiet"],
                       cwd=REPO, env=_env(), capture_output=True, text=True, timeout=240)
    assert c.returncode == 0, c.stderr
    assert f"seed {row['seed']}; current 0.5 m/s" in c.stdout, c.stdout   # the run's own seed, its current
    ours = (tmp_path / "run3" / "turning-circle.csv").read_text()
    assert ours == alone.read_text()
    lines = ours.splitlines()
    assert lines[0].split(",")[-1] == "eta_cg_m" and len(lines) > 50
    assert {len(ln.split(",")) for ln in lines} == {len(lines[0].split(","))}
    # and the sea is the run's own: run 2 (the same draw of sea.hs, no current) flies other waves
    from bb2_tools.campaign.worker import run_one

    spec = parse_spec(doc)
    (r2, res2), (r3, res3) = run_one(spec, 2), run_one(spec, 3)
    assert r2["sea.hs"] == r3["sea.hs"] and r2["seed"] != r3["seed"]
    assert res2.settings.environment.sea.seed == r2["seed"] and res3.settings.environment.current.speed_mps == 0.5
    assert r3["peak_roll_deg"] == row["peak_roll_deg"]


# the issue's own example SPEC, word for word: the canyon mission is calm (no sea block)
ISSUE_SPEC = {
    "mission": "missions/canyon.yaml",
    "seed": 7,
    "samples": 200,
    "vary": {"sea.hs": {"uniform": [0.5, 3.5]}, "sea.heading_deg": {"choice": [0, 90, 180]},
             "adaptation": [True, False], "duration_s": [120, 240]},
    "collect": ["rms_vertical", "rms_horizontal", "min_clearance"],
}


def test_a_sea_varied_on_a_calm_mission_gets_a_spectrum_and_each_run_its_own_waves(tmp_path, monkeypatch):
    """Varying sea.hs on a mission without a sea (the issue's example on the calm canyon) was refused, every run
    ('sea: heading_deg, hs need a spectrum'): the runs now fly a Pierson-Moskowitz sea of the drawn Hs (JONSWAP
    when a Tp is given), each with its own wave phases (the run's seed in sea.seed), and the SPEC says so."""
    import numpy as np

    from bb2_sim.environment import sea_from_mapping
    from bb2_tools.campaign.errors import SpecError
    from bb2_tools.campaign.spec import run_seed
    from bb2_tools.campaign.store import check_campaign_yaml, write_campaign_yaml
    from bb2_tools.campaign.worker import probe

    monkeypatch.chdir(tmp_path)   # missions/canyon.yaml is the shipped one from any working directory
    spec = parse_spec(ISSUE_SPEC)
    probe(spec)   # was: SpecError 'vary (run 0): sea: heading_deg, hs need a spectrum'
    assert spec.base["sea"] == {"spectrum": "pm", "hs": 0.0} and spec.seed_key == "sea.seed"
    assert len(spec.notes) == 2 and "Pierson-Moskowitz" in spec.notes[0] and "sea.seed" in spec.notes[1]
    waves = []
    for i in (0, 2):   # the same draw (sample 0), adaptation true / false: the same Hs and heading, other seeds
        sea = spec.document(i)["sea"]
        assert sea["hs"] == spec.inputs(i)["sea.hs"] and sea["seed"] == run_seed(7, i), sea
        w = sea_from_mapping(sea).wave_components()
        assert np.all(np.degrees(w.direction) == sea["heading_deg"])
        assert abs(4 * np.sqrt(np.sum(w.amplitude ** 2) / 2) / sea["hs"] - 1) < 0.01   # Hs = 4 sqrt(m0)
        waves.append(w)
    assert np.array_equal(waves[0].amplitude, waves[1].amplitude)
    assert not np.array_equal(waves[0].phase, waves[1].phase)            # each run its own realisation
    # the resolved campaign (its sea, seed key and notes) is what campaign.yaml keeps, and --resume accepts it
    write_campaign_yaml(tmp_path, spec)
    kept = yaml.safe_load((tmp_path / "campaign.yaml").read_text())["campaign"]
    assert kept["mission_document"]["sea"] == spec.base["sea"] and kept["seed_key"] == "sea.seed"
    assert kept["notes"] == list(spec.notes)
    check_campaign_yaml(tmp_path, parse_spec(ISSUE_SPEC))

    # a peak period given: JONSWAP; the SPEC's own seed key kept (and no note about it)
    s = parse_spec({**ISSUE_SPEC, "seed_key": "sensors.seed",
                    "vary": {**ISSUE_SPEC["vary"], "sea.tp": {"uniform": [6, 10]}}})
    assert s.base["sea"]["spectrum"] == "jonswap" and s.seed_key == "sensors.seed" and len(s.notes) == 1
    # a sea the mission defines is its own: nothing chosen (canyon_periscope_ss5 names its spectrum)
    from bb2_mission.schema import MISSIONS_DIR, read_mission_document

    s = parse_spec({"mission": "canyon_periscope_ss5", "vary": {"sea.hs": {"uniform": [1, 3]}}})
    own = read_mission_document(MISSIONS_DIR / "canyon_periscope_ss5.yaml")["sea"]
    assert not s.notes and s.seed_key is None and s.base["sea"] == own and own["spectrum"] == "jonswap", own
    # a mission file's own sea_state: 0 (the authors' table, calm) is calm too, and goes (the schema takes a
    # sea_state or a sea block, not both)
    calm0 = _write_spec(tmp_path / "calm0.yaml", {**read_mission_document(MISSIONS_DIR / "canyon.yaml"),
                                                  "sea_state": 0})
    s = parse_spec({"mission": str(calm0), "vary": {"sea.hs": [1.0, 2.0]}})
    assert s.notes and "sea_state" not in s.base and s.base["sea"]["spectrum"] == "pm"
    probe(s)
    s = parse_spec({"mission": str(calm0), "vary": {"sea.hs": [1.0, 2.0], "sea_state": 0}})   # varied: its own
    assert not s.notes and s.base["sea_state"] == 0
    # a number of components of no spectrum means nothing either (it flew calm runs, every one alike)
    s = parse_spec({"mission": "missions/canyon.yaml", "vary": {"sea.components": [16, 32]}})
    with pytest.raises(SpecError, match="components need a spectrum"):
        probe(s)
    # a direction alone on a calm sea means nothing: still refused, naming the key
    s = parse_spec({"mission": "missions/canyon.yaml", "vary": {"sea.heading_deg": {"choice": [0, 90]}}})
    with pytest.raises(SpecError, match="heading_deg need a spectrum"):
        probe(s)


@pytest.mark.parametrize("example", sorted(p.name for p in (REPO / "examples" / "campaigns").glob("*.yaml")))
def test_the_shipped_example_specs_hold(example, tmp_path, monkeypatch):
    """The README's worked Monte Carlos: each example SPEC parses and its run 0 builds (the probe), as written,
    from any working directory (its ``missions/...`` is the shipped mission)."""
    from bb2_tools.campaign.spec import load_spec

    monkeypatch.chdir(tmp_path)
    from bb2_tools.campaign.worker import probe

    spec = load_spec(REPO / "examples" / "campaigns" / example)
    probe(spec)
    assert spec.n_runs >= 24 and not spec.notes, (spec.n_runs, spec.notes)


def test_the_issue_example_spec_flies_as_written(tmp_path):
    """``bb2-campaign`` on the issue's example SPEC, unchanged: run 0 (120 s of the canyon in a sea of the drawn Hs
    and heading) flies alone, its row under the SPEC's column names, and the notes say what sea it flew."""
    f = _write_spec(tmp_path / "issue.yaml", ISSUE_SPEC)
    r = _campaign(str(f), "--only", "0", "--out-run", str(tmp_path / "run0"))
    assert r.returncode == 0, r.stderr
    assert "note:" in r.stderr and "Pierson-Moskowitz" in r.stderr, r.stderr
    with open(tmp_path / "run0" / "run.csv") as fh:
        header = fh.readline().strip().replace('"', "").split(",")
    assert header == ["index", "seed", *ISSUE_SPEC["vary"], *ISSUE_SPEC["collect"], "status", "message",
                      "wall_time_s"]
    row = pa.csv.read_csv(tmp_path / "run0" / "run.csv").to_pylist()[0]
    assert row["status"] == "ok", row
    assert 0.5 <= row["sea.hs"] < 3.5 and row["sea.heading_deg"] in (0, 90, 180) and row["duration_s"] == 120
    assert 0 < row["rms_vertical"] < 5 and 0 < row["rms_horizontal"] < 5 and 30 < row["min_clearance"] < 60, row


def test_a_campaign_over_the_sensor_noise_collects_the_navigation_figures(tmp_path):
    """Issue 12: a Monte Carlo over the sensor seed of a mission flown on the navigation filter; the figures are
    the runner's own, each run's seed its own sensor noise."""
    import math

    from bb2_tools.campaign.worker import run_one

    spec = parse_spec({"mission": "canyon", "seed": 3, "samples": 2, "seed_key": "sensors.seed",
                       "vary": {"duration_s": 10, "navigation": "sensors", "sensors.suite": "mems"},
                       "collect": ["rms_nav_error", "max_nav_heading_error_deg", "rms_horizontal_m"]})
    rows = [run_one(spec, i)[0] for i in range(2)]
    for row in rows:
        assert row["status"] == "ok", row
        assert math.isfinite(row["rms_nav_error"]) and row["rms_nav_error"] > 0
    assert rows[0]["rms_nav_error"] != rows[1]["rms_nav_error"]     # two seeds, two noise draws
    assert run_one(spec, 1)[0]["rms_nav_error"] == rows[1]["rms_nav_error"]   # a run alone: the same
    shutil.rmtree(tmp_path, ignore_errors=True)


def test_a_torn_last_journal_line_is_cut_off_on_resume(tmp_path):
    from bb2_tools.campaign.store import Journal

    j = Journal(tmp_path / "runs.jsonl")
    for i in (0, 2, 1):
        j.append({"index": i, "status": "ok", "x": float("nan")})
    j.close()
    with open(j.path, "ab") as fh:
        fh.write(b'{"index": 7, "sta')
    assert Journal(j.path).recover() == {0, 1, 2}
    assert j.path.read_text().endswith("}\n") and '"x": null' in j.path.read_text()


def test_a_sigkilled_worker_loses_no_run(reference):
    """SIGKILL one pool worker mid-campaign: the pool is rebuilt, the runs in flight fly again, the table is the
    same as the reference (no error rows added, none twice)."""
    from bb2_tools.campaign.engines import LocalEngine

    spec = parse_spec(SPEC)
    rows: list[dict] = []
    killed: list[int] = []

    def on_row(row: dict) -> None:
        rows.append(row)
        if len(rows) == 2 and not killed:
            servers = [p for p in descendants(os.getpid())
                       if b"forkserver" in Path(f"/proc/{p}/cmdline").read_bytes()]
            workers = [w for srv in servers for w in descendants(srv)]   # the pool's workers fork from it
            assert workers, "no pool worker found"
            os.kill(workers[-1], signal.SIGKILL)
            killed.append(workers[-1])

    LocalEngine(2).run(spec, range(N_RUNS), on_row)
    assert killed
    by_index: dict[int, dict] = {}
    for r in rows:
        by_index.setdefault(r["index"], r)      # the driver keeps the first of a run delivered twice
    assert sorted(by_index) == list(range(N_RUNS))
    from bb2_tools.campaign.store import results_schema

    got = pa.Table.from_pylist([by_index[i] for i in range(N_RUNS)], schema=results_schema(spec))
    assert _comparable(got) == _comparable(_table(reference))


@pytest.mark.ros
def test_graph_runs_fly_the_ros_graph_and_equal_the_library_runner(tmp_path):
    """--graph: two runs, each the whole lockstep graph on its own ROS_DOMAIN_ID with its bag, at the same time;
    their figures (bb2-analyze of the bag) equal the library runner's to the last digit.  A run that breaks the
    mission's limits has the runner's status, end reason and message (the graph flies on past the event: its
    path figures then cover the whole run, the runner's stop there)."""
    pytest.importorskip("rclpy", reason="rclpy (ROS 2 Jazzy wheels) not installed")
    from bb2_tools.campaign.worker import run_one

    # 44.4 m: the canyon's lowest hull point at the start; a 60 m limit grounds the run at its first tick
    doc = {"mission": "canyon", "seed": 1, "vary": {"duration_s": 3, "limits.min_hull_clearance_m": [0.0, 60.0]},
           "collect": ["rms_vertical", "rms_horizontal", "max_vertical_m", "mission_time_s", "end_reason",
                       "completed"]}
    f = _write_spec(tmp_path / "g.yaml", doc)
    # another launch of this machine holds domains 1 and 2 (the campaign once took 1 + index: run 0 recorded a
    # concurrent test's 90 s canyon): each run's bb2-launch claims a free domain of its own
    from bb2_tools.graph_monitor import claim_domain
    held = [fd for fd in (claim_domain(1), claim_domain(2)) if fd is not None]
    try:
        r = _campaign(str(f), "--out", str(tmp_path / "g"), "--graph", "--workers", "2", timeout=400)
    finally:
        for fd in held:
            os.close(fd)
    assert r.returncode == 0, r.stderr
    for log in sorted((tmp_path / "g" / "graph").glob("*/launch.log")):
        text = log.read_text()
        assert "another bb2-launch runs" not in text and "ROS_DOMAIN_ID=1 |" not in text, text[:600]
    rows = sorted(_table(tmp_path / "g").to_pylist(), key=lambda row: row["index"])
    spec = parse_spec(doc)
    assert [row["status"] for row in rows] == ["ok", "grounded"], [row["message"] for row in rows]
    for r in rows:
        lib = run_one(spec, r["index"])[0]
        assert (r["status"], r["message"], r["end_reason"], r["completed"]) == \
            (lib["status"], lib["message"], lib["end_reason"], lib["completed"])
        if r["status"] == "ok":
            assert {k: r[k] for k in doc["collect"]} == {k: lib[k] for k in doc["collect"]}
        else:
            assert r["message"].startswith("grounded at t = 0.00 s") and r["mission_time_s"] == 3.0
        run = tmp_path / "g" / "graph" / f"{r['index']:06d}"
        assert list((run / "bag").glob("*.mcap")) and (run / "analysis" / "figures.json").exists()
    assert yaml.safe_load((tmp_path / "g" / "campaign.yaml").read_text())["campaign"]["graph"] is True


# ------------------------------------------------------------------------------------------ maneuver batches
# 32 turning circles of 15 s (two workers: two batches of 16); speed 0 diverges at the first step (quirk Q13)
MANEUVER_SPEC = {
    "maneuver": {"name": "turning-circle", "options": {"duration": 15}},
    "seed": 11,
    "samples": 32,
    "vary": {"rudder_deg": {"uniform": [15.0, 35.0]}, "sea_state": {"choice": [0, 3, 5]},
             "speed_mps": {"choice": [0.0, 4.0, 5.0, 5.5, 6.0]}},
    "collect": ["peak_roll_rad", "z_change_m", "initial_speed_m_s", "time_90_s"],
}


@pytest.fixture(scope="module")
def maneuver_batched(tmp_path_factory) -> tuple[Path, Path]:
    """The maneuver campaign flown by the local pool of 2 workers, each flying its 16 runs as one batch."""
    tmp = tmp_path_factory.mktemp("maneuvers")
    spec = _write_spec(tmp / "circles.yaml", MANEUVER_SPEC)
    r = _campaign(str(spec), "--out", str(tmp / "batched"), "--workers", "2", timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    return spec, tmp / "batched"


def test_maneuver_batches_give_the_table_of_runs_flown_one_by_one(maneuver_batched, tmp_path):
    spec, batched = maneuver_batched
    r = _campaign(str(spec), "--out", str(tmp_path / "alone"), "--workers", "2", "--batch", "1", timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    alone = _comparable(_table(tmp_path / "alone"))
    assert len(alone) == 32 and _comparable(_table(batched)) == alone
    status = [r["status"] for r in alone]
    assert status.count("ok") >= 16 and "diverged" in status, status
    assert {r["message"] for r in alone if r["status"] == "ok"} == {"not reached in this 15 s run: time_90_s"}
    assert {r["sea_state"] for r in alone} == {0, 3, 5}


def test_ray_flies_maneuver_batches_as_the_local_pool(maneuver_batched, ray_cluster, tmp_path):
    spec, batched = maneuver_batched
    r = _campaign(str(spec), "--out", str(tmp_path / "ray"), "--engine", "ray", "--address", ray_cluster,
                  timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    assert _comparable(_table(tmp_path / "ray")) == _comparable(_table(batched))


def test_ray_counts_what_its_batches_in_flight_have_flown(ray_cluster):
    """On Ray too the progress counts what the chunks in flight have flown (their tasks tell an actor), before
    their runs land together: two chunks of 16 missions, one on each node."""
    from bb2_tools.campaign.engines import RayEngine

    spec = parse_spec({"mission": "canyon", "seed": 5, "samples": 32,
                       "vary": {"duration_s": 60, "stack.guidance.d_m": {"uniform": [150.0, 350.0]}},
                       "collect": ["rms_vertical"]})
    engine = RayEngine(None, ray_cluster)
    ticks: list[tuple[int, float]] = []
    rows: list[dict] = []
    try:
        engine.prepare()
        engine.run(spec, range(32), rows.append, lambda flying=0.0: ticks.append((len(rows), flying)))
    finally:
        engine.shutdown()
    assert sorted(r["index"] for r in rows) == list(range(32)) and {r["status"] for r in rows} == {"ok"}
    assert any(n == 0 and 0 < f < 32 for n, f in ticks), ticks
    assert ticks[-1] == (32, 0.0), ticks


def _spy_single_runs(monkeypatch, worker) -> tuple[list[int], object]:
    """Records the runs ``worker.run_tasks`` flies alone (through ``run_task``); returns (that list, the original
    ``run_task``)."""
    alone: list[int] = []
    single = worker.run_task

    def spy(s, i):
        alone.append(int(i))
        return single(s, i)

    monkeypatch.setattr(worker, "run_task", spy)
    return alone, single


def test_a_chunk_of_maneuvers_flies_as_one_batch_and_only_the_diverged_runs_alone(monkeypatch):
    """``run_tasks``: the runs of a chunk fly together; ``run_task`` (the single run) is called only for those that
    diverged in the batch, whose rows then carry the single run's own message."""
    from bb2_tools.campaign import worker

    spec = parse_spec(MANEUVER_SPEC)
    alone, single = _spy_single_runs(monkeypatch, worker)
    rows = worker.run_tasks(spec, list(range(worker.BATCH_MIN)))
    assert [r["index"] for r in rows] == list(range(worker.BATCH_MIN))
    diverged = [r["index"] for r in rows if r["status"] == "diverged"]
    assert diverged and alone == diverged, (alone, diverged)
    assert all("non-finite model evaluation" in r["message"] for r in rows if r["status"] == "diverged")
    # fewer runs than a batch pays for: every one alone
    alone.clear()
    worker.run_tasks(spec, [0, 1, 2])
    assert alone == [0, 1, 2]


# ------------------------------------------------------------------------------------------ mission batches
# 32 canyon runs of 3 s (two workers: two batches of 16): sea states, adaptation, a gain; limit 60 m grounds a run
# at its first tick (the lowest hull point starts 44.4 m above the floor)
MISSION_BATCH_SPEC = {
    "mission": "canyon",
    "seed": 5,
    "samples": 16,
    "vary": {"duration_s": 3, "sea_state": {"choice": [0, 3, 5]},
             "stack.guidance.d_m": {"uniform": [150.0, 350.0]},
             "limits.min_hull_clearance_m": {"choice": [0.0, 0.0, 0.0, 60.0]}, "adaptation": [True, False]},
    "collect": ["rms_vertical", "rms_horizontal", "max_vertical_m", "min_clearance", "end_reason",
                "mission_time_s"],
}


def test_mission_batches_give_the_table_of_runs_flown_one_by_one(tmp_path):
    spec = _write_spec(tmp_path / "canyon32.yaml", MISSION_BATCH_SPEC)
    r = _campaign(str(spec), "--out", str(tmp_path / "batched"), "--workers", "2", timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    r = _campaign(str(spec), "--out", str(tmp_path / "alone"), "--workers", "2", "--batch", "1", timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    alone = _comparable(_table(tmp_path / "alone"))
    assert len(alone) == 32 and _comparable(_table(tmp_path / "batched")) == alone
    status = [row["status"] for row in alone]
    assert status.count("ok") >= 16 and "grounded" in status, status
    assert {row["sea_state"] for row in alone} == {0, 3, 5}



def test_substeps_varied_fly_each_value_as_its_own_batch_with_the_single_runs_rows(monkeypatch):
    """``substeps`` (ROM ode3 steps per 0.05 s step) is a mission field like any: varied as a grid, the runs of each
    value fly together (one batch each, no single run), each row equal to its run flown alone; the same draws with
    1 and 2 sub-steps give close, not equal, figures."""
    from bb2_tools.campaign import worker

    spec = parse_spec({**MISSION_BATCH_SPEC, "samples": worker.BATCH_MIN,  # a batch of each value
                       "vary": {"duration_s": 3, "sea_state": {"choice": [0, 3, 5]},
                                "stack.guidance.d_m": {"uniform": [150.0, 350.0]}, "substeps": [1, 2]}})
    alone, single = _spy_single_runs(monkeypatch, worker)
    rows = worker.run_tasks(spec, list(range(2 * worker.BATCH_MIN)))
    assert alone == [] and [r["substeps"] for r in rows[:4]] == [1, 2, 1, 2]
    assert all(r["status"] == "ok" for r in rows), rows

    def same(row):
        return {k: v for k, v in row.items() if k != "wall_time_s"}

    assert [same(single(spec, i)) for i in (0, 1)] == [same(r) for r in rows[:2]]
    one, two = rows[0]["rms_vertical"], rows[1]["rms_vertical"]  # the same sample's draws
    assert one != two and abs(one - two) < 1e-3 * max(abs(one), 1.0), (one, two)


def test_a_run_diverging_at_speed_is_told_of_substeps_in_its_row():
    """The sprint mission (16 m/s) with the authors' step (1 sub-step) diverges: its row says so with the advice
    ``bb2-sim mission`` prints (the sub-steps the shipped file flies with); the same draw with those flies to its
    end.  A maneuver that capsizes slowly gets no such advice."""
    from bb2_mission import MISSIONS_DIR, load_mission
    from bb2_tools.campaign import worker

    k = load_mission(MISSIONS_DIR / "sprint.yaml").substeps
    spec = parse_spec({"mission": str(MISSIONS_DIR / "sprint.yaml"), "seed": 3,
                       "vary": {"substeps": [1, k], "duration_s": 6.0}, "collect": ["end_reason", "mission_time_s"]})
    one, fast = worker.run_tasks(spec, [0, 1])
    said = one["message"]
    assert one["status"] == "diverged" and "diverged at t = " in said, one
    assert "m/s, near or past where the ROM's 0.05 s step in 1 ode3 step(s) turns numerically unstable" in said, one
    assert said.endswith(f"; substeps: {k} integrates it in {k}"), one
    assert fast["status"] == "ok" and fast["message"] == "" and fast["mission_time_s"] == pytest.approx(6.0), fast
    slow = worker.run_tasks(parse_spec(MANEUVER_SPEC), list(range(8)))
    assert any(r["status"] == "diverged" for r in slow), slow
    assert not any("substeps" in r["message"] for r in slow), slow


def test_chunks_are_equal_batches_to_the_end():
    """The engines cut a campaign into equal chunks of at most --batch, a multiple of the workers in number, from the
    campaign's size (a share recomputed from the runs left shrank the last chunks below BATCH_MIN: 64 runs on two
    workers flew as 32 + 16 together and 16 one by one)."""
    from bb2_tools.campaign.engines import _take, chunk_size
    from bb2_tools.campaign.worker import BATCH_MIN

    spec = parse_spec(MISSION_BATCH_SPEC)
    for total, workers, batch, want in ((64, 2, 128, 32), (1000, 2, 128, 125), (1000, 4, 128, 125), (300, 2, 128, 75),
                                        (40, 2, 128, 20), (20, 2, 128, 1), (64, 2, 1, 1), (256, 2, 128, 128)):
        size = chunk_size(spec, total, workers, batch)
        assert size == want, (total, workers, batch, size)
        pending = collections.deque(range(total))
        chunks = []
        while pending:
            chunks.append(_take(pending, size))
        assert sorted(i for c in chunks for i in c) == list(range(total))
        if size > 1:   # every chunk a full batch (the last within one run of the others)
            assert len(chunks) % workers == 0 and min(map(len, chunks)) >= max(BATCH_MIN, size - len(chunks))
    assert chunk_size(spec, 0, 2) == 1


def test_runs_that_cannot_fly_in_a_batch_go_out_one_by_one():
    """A campaign none of whose runs can fly in a batch (missions on their navigation estimate) was cut into chunks
    of up to --batch runs like any other, and each worker flew its chunk's runs one after the other and handed them
    over together: they landed, and counted in the progress bar, all at once, and a SIGKILL before that lost every
    finished one.  Such runs go out one by one; a campaign whose runs can batch, or some of them can, keeps its
    chunks.  Spectrum seas and currents fly in the batch ROM (each boat its own): their campaigns keep chunks."""
    from bb2_tools.campaign.engines import chunk_size

    vary = MISSION_BATCH_SPEC["vary"]
    assert chunk_size(parse_spec(MISSION_BATCH_SPEC), 64, 2, 128) == 32
    sensors = {**MISSION_BATCH_SPEC, "vary": {**vary, "sensors.suite": "tactical", "navigation": "sensors"}}
    assert chunk_size(parse_spec(sensors), 64, 2, 128) == 1
    mixed = parse_spec({**MISSION_BATCH_SPEC, "vary": {**vary, "sensors.suite": "tactical",
                                                       "navigation": ["truth", "sensors"]}})
    assert chunk_size(mixed, 64, 2, 128) == 32
    assert chunk_size(parse_spec({**MISSION_BATCH_SPEC, "vary": {**vary, "current.speed_mps": 0.3}}), 64, 2, 128) == 32
    sea = {**MISSION_BATCH_SPEC, "vary": {**{k: v for k, v in vary.items() if k != "sea_state"},
                                         "sea.hs": {"uniform": [1.0, 3.0]}}}      # the default PM sea
    assert chunk_size(parse_spec(sea), 64, 2, 128) == 32
    man = {"maneuver": {"name": "turning-circle", "options": {"duration": 5}}, "samples": 64,
           "vary": {"rudder_deg": {"uniform": [10, 30]}}}
    assert chunk_size(parse_spec(man), 64, 2, 128) == 32
    man_sea = {**man, "vary": {**man["vary"], "sea.hs": {"uniform": [1, 2]}}}
    assert chunk_size(parse_spec(man_sea), 64, 2, 128) == 32


def test_the_progress_bar_counts_what_the_batches_in_flight_have_flown():
    """Runs flown together land together, when their chunk ends: a 1,000-run calm canyon campaign showed 0/1000 and
    no ETA for over two minutes, then jumped by 125.  The local engine's workers now tell the driver what their
    chunk has flown (a batch's boats by their ticks), the bar, rate and ETA count it, and the line says it."""
    import io

    from bb2_tools.campaign.engines import LocalEngine
    from bb2_tools.campaign.progress import Progress

    bar = Progress(10, stream=io.StringIO())
    bar.flying_now(2.5)
    assert "0/10 (+2.5 in flight)  25.0%" in bar.line()
    bar.update("ok")                     # a run landed: it was in flight, the count moves from there to the results
    assert "1/10 (+1.5 in flight)  25.0%" in bar.line() and bar.rate > 0

    spec = parse_spec({"mission": "canyon", "seed": 5, "samples": 16,
                       "vary": {"duration_s": 60, "stack.guidance.d_m": {"uniform": [150.0, 350.0]}},
                       "collect": ["rms_vertical"]})
    ticks: list[tuple[int, float]] = []
    rows: list[dict] = []
    LocalEngine(1).run(spec, range(16), rows.append, lambda flying=0.0: ticks.append((len(rows), flying)))
    assert sorted(r["index"] for r in rows) == list(range(16)) and {r["status"] for r in rows} == {"ok"}
    before = [f for n, f in ticks if n == 0]              # one chunk of 16, flown together: before it lands
    assert any(0 < f < 16 for f in before), ticks
    assert before == sorted(before) and all(f == 0 for n, f in ticks if n == 16), ticks


def test_a_chunk_of_missions_flies_as_one_batch(monkeypatch):
    """``run_tasks``: the missions of a chunk fly together (no single run), rows as the single runs give them."""
    from bb2_tools.campaign import worker

    spec = parse_spec(MISSION_BATCH_SPEC)
    alone, single = _spy_single_runs(monkeypatch, worker)
    rows = worker.run_tasks(spec, list(range(worker.BATCH_MIN)))
    assert [r["index"] for r in rows] == list(range(worker.BATCH_MIN)) and alone == []
    assert [r for r in rows if r["status"] == "grounded"], rows
    def same(row):
        return {k: v for k, v in row.items() if k != "wall_time_s"}

    assert [same(single(spec, i)) for i in (0, 1)] == [same(r) for r in rows[:2]]


def test_a_maneuver_run_started_at_rest_under_iowa_says_why_in_its_message():
    """A campaign varying the start speed down to 0 m/s: the iowa run diverges at t = 0 (the authors' model
    divides by the relative speed) and its row says so, with the profiles that start from rest; the corrected
    profile flies it."""
    from bb2_tools.campaign.worker import run_one

    spec = parse_spec({"maneuver": {"name": "self-propulsion", "options": {"duration": 2}}, "seed": 1,
                       "vary": {"speed_mps": [0.0], "profile": ["iowa", "corrected"]}})
    rows = [run_one(spec, i)[0] for i in range(spec.n_runs)]
    by_profile = {r["profile"]: r for r in rows}
    assert by_profile["iowa"]["status"] == "diverged", by_profile
    assert "it started at rest: the iowa profile is singular at zero relative speed" in by_profile["iowa"]["message"]
    assert by_profile["corrected"]["status"] == "ok", by_profile["corrected"]["message"]
