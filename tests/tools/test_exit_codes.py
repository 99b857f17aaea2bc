"""Issue 10: runs that cannot collide, errors as documented exit codes, no silent overwrite, impossible inputs
refused.

Exit-code contract of every CLI: 0 done, 1 diverged / mission failed, 2 bad input or an OS error (one line naming
the file), 130 Ctrl-C.  Read-only and full devices are real: a tmpfs mounted inside ``unshare -rm`` (a user and
mount namespace, no root needed), read-only or filled to the last byte; the tests skip where the kernel does not
allow it.
"""
from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import re
import threading
import time
from pathlib import Path

import pytest

from bb2_sim import outputs as O

from rosenv import ros_env  # noqa: E402  (tests/rosenv.py)

REPO = Path(__file__).resolve().parents[2]
PY = sys.executable


# ------------------------------------------------------------------------------------------ helpers
def _unshare_works() -> bool:
    if shutil.which("unshare") is None:
        return False
    try:
        return subprocess.run(["unshare", "-rm", "true"], capture_output=True, timeout=20).returncode == 0
    except (OSError, subprocess.TimeoutExpired):
        return False


needs_unshare = pytest.mark.skipif(not _unshare_works(), reason="unshare -rm (user + mount namespace) not allowed")


def run_on_mount(cmd: list[str], mnt: Path, *, state: str, timeout: float = 300, cwd: Path | None = None,
                 env: dict | None = None) -> subprocess.CompletedProcess:
    """Run ``cmd`` with a small tmpfs on ``mnt`` that is ``ro`` (read-only) or ``full`` (no byte left)."""
    mnt.mkdir(parents=True, exist_ok=True)
    script = f"mount -t tmpfs -o size=256k tmpfs '{mnt}' || exit 99; "
    if state == "full":
        script += f"head -c 1000000 /dev/zero > '{mnt}/fill' 2>/dev/null; "
    elif state == "ro":
        script += f"mkdir -p '{mnt}/sub'; mount -o remount,ro '{mnt}' || exit 99; "
    script += 'exec "$@"'
    p = subprocess.run(["unshare", "-rm", "sh", "-c", script, "sh", *cmd], capture_output=True, text=True,
                       timeout=timeout, cwd=cwd, env=env)
    if p.returncode == 99:
        pytest.skip(f"cannot mount a tmpfs here: {p.stderr.strip()}")
    return p


def one_error_line(stderr: str, prog: str) -> str:
    """The single ``prog: error: ...`` line; no traceback anywhere."""
    assert "Traceback" not in stderr, stderr
    lines = [ln for ln in stderr.splitlines() if ln.startswith(f"{prog}: error:")]
    assert len(lines) == 1, stderr
    return lines[0]


def bb2(tool: str, *args: str, **kw) -> subprocess.CompletedProcess:
    mod = {"bb2-sim": "bb2_tools.sim_cli", "bb2-launch": "bb2_tools.launcher", "bb2-analyze": "bb2_tools.analyze",
           "bb2-replay": "bb2_tools.replay"}[tool]
    kw.setdefault("timeout", 300)
    return subprocess.run([PY, "-m", mod, *args], capture_output=True, text=True, env=kw.pop("env", ros_env()),
                          **kw)


# ------------------------------------------------------------------------------------------ point 2: claims
def test_run_dir_claims_never_collide_whatever_the_timing(tmp_path):
    """Sixteen threads claim the same stem at the same instant: sixteen different directories."""
    barrier = threading.Barrier(16)
    got: list[Path] = []
    lock = threading.Lock()

    def claim():
        barrier.wait()
        d = O.claim_run_dir(tmp_path, "canyon_20261201_120000")
        with lock:
            got.append(d)

    threads = [threading.Thread(target=claim) for _ in range(16)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(set(got)) == 16
    assert sorted(p.name for p in tmp_path.iterdir())[0] == "canyon_20261201_120000"
    assert all((d / O.CLAIM_FILE).is_file() for d in got)


@pytest.mark.parametrize("value, said", [
    ("../escape", "must be a plain name"), ("a/b", "must be a plain name"), ("..", "must be a plain name"),
    ("", "must be a plain name"), ("tab\there", "must be a plain name"), ("x" * 201, "at most 200 characters"),
    (1000.0, "must be a text, got 1000.0 (YAML read a float: put the name in quotes)"), (None, "must be a text"),
    (["a"], "must be a text, got ['a']")])
def test_a_name_that_becomes_a_file_name_is_one_plain_name(tmp_path, value, said):
    """A mission's, a fleet's or a campaign's name names its files: ``../escape`` wrote a fleet's bag outside
    --bag-dir; a float or a boolean (YAML's reading of ``1e3``, ``yes``) is refused, an integer taken as its digits,
    and claim_run_dir makes no directory of a stem that is a path."""
    with pytest.raises(ValueError, match=re.escape(said)):
        O.plain_name(value, "name")
    if isinstance(value, str):
        with pytest.raises(ValueError, match="claim_run_dir: stem"):
            O.claim_run_dir(tmp_path / "runs", value or "x/")
    assert O.plain_name(2024, "name") == "2024" and O.plain_name("canyon pair-1.2", "name") == "canyon pair-1.2"
    assert not (tmp_path / "escape").exists()


def test_claim_of_an_explicit_dir(tmp_path):
    d = O.claim_run_dir(path=tmp_path / "run")
    assert d.is_dir() and (d / O.CLAIM_FILE).is_file()
    with pytest.raises(O.OutputError, match="not empty"):
        O.claim_run_dir(path=tmp_path / "run")           # the second claimant is refused
    (tmp_path / "empty").mkdir()
    assert O.claim_run_dir(path=tmp_path / "empty") == tmp_path / "empty"   # an empty one is claimed once
    with pytest.raises(O.OutputError):
        O.claim_run_dir(path=tmp_path / "empty")
    (tmp_path / "file").write_text("x")
    with pytest.raises(O.OutputError, match="not a directory"):
        O.claim_run_dir(path=tmp_path / "file")


def test_check_output_file_refuses_existing_and_directories(tmp_path):
    f = tmp_path / "a" / "b.csv"
    assert O.check_output_file(f) == f and not f.parent.exists()   # nothing created before the run
    f.parent.mkdir()
    f.write_text("keep me")
    with pytest.raises(O.OutputError, match="exists .give --overwrite"):
        O.check_output_file(f)
    assert O.check_output_file(f, overwrite=True) == f and f.read_text() == "keep me"
    with pytest.raises(O.OutputError, match="is a directory"):
        O.check_output_file(tmp_path / "a")


@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="needs procfs: a folder that refuses new files")
@pytest.mark.parametrize("target, which", [("x/sub/a.csv", "its nearest existing folder /proc"),
                                           ("x.csv", "its folder /proc")])
def test_an_output_under_a_folder_that_takes_no_files_names_the_file_and_the_folder(target, which):
    """/proc refuses a new file with 'No such file or directory': said of /proc alone, it read as if /proc were
    missing.  The message names the file asked for, and the folder that refused it."""
    with pytest.raises(O.OutputError) as e:
        O.check_output_file(Path("/proc") / target)
    assert str(e.value) == f"cannot write /proc/{target}: {which} takes no files (No such file or directory)"


@needs_unshare
@pytest.mark.parametrize("state", ["ro", "full"])
def test_check_writable_dir_fails_now_on_read_only_and_full_devices(tmp_path, state):
    code = ("import sys\nfrom bb2_sim.outputs import check_writable_dir, OutputError\n"
            "try:\n    check_writable_dir(sys.argv[1])\nexcept OutputError as e:\n    print(e); sys.exit(2)\n")
    p = run_on_mount([PY, "-c", code, str(tmp_path / "m" / "sub")], tmp_path / "m", state=state)
    assert p.returncode == 2, p.stdout + p.stderr
    assert str(tmp_path / "m" / "sub") in p.stdout
    assert ("Read-only" in p.stdout) if state == "ro" else ("No space" in p.stdout)


# ------------------------------------------------------------------------------------------ bb2-launch input
@needs_unshare
def test_launch_read_only_bag_dir_is_exit_2_before_anything_starts(tmp_path):
    p = run_on_mount([PY, "-m", "bb2_tools.launcher", str(REPO / "missions" / "straight.yaml"),
                      "--bag-dir", str(tmp_path / "m" / "sub")], tmp_path / "m", state="ro", env=ros_env())
    assert p.returncode == 2, p.stderr
    line = one_error_line(p.stderr, "bb2-launch")
    assert str(tmp_path / "m" / "sub") in line and "Read-only" in line
    assert "[bb2-launch] mission" not in p.stderr   # no node was started


def test_launch_refuses_bad_input_with_one_line(tmp_path):
    bad = tmp_path / "latin1.yaml"
    bad.write_bytes(b"path: straight\nname: caf\xe9\n")
    mission = str(REPO / "missions" / "straight.yaml")
    cases = {
        (str(bad), "--bag-dir", str(tmp_path)): "not UTF-8",
        (mission, "--bag-dir", str(tmp_path), "--restart", "simulator=restart:1"): "restarting the simulator is refused",
        (mission, "--bag-dir", str(tmp_path), "--restart", "all=restart"): "restarting the simulator is refused",
        (mission, "--bag-dir", str(tmp_path), "--stall-timeout", "nan"): "--stall-timeout",
        (mission, "--bag-dir", str(tmp_path), "--timeout", "inf"): "--timeout",
        (mission, "--bag-dir", str(tmp_path), "--status-period", "0"): "--status-period",
        # --max-restarts counts only a NODE=restart without its own count: alone it did nothing, without a word
        (mission, "--bag-dir", str(tmp_path), "--max-restarts", "-1"): "--max-restarts must be >= 0, got -1",
        (mission, "--bag-dir", str(tmp_path), "--max-restarts", "5"): "--max-restarts 5 applies to no node",
        (mission, "--bag-dir", str(tmp_path), "--max-restarts", "5", "--restart", "mixer=restart:2"):
            "--max-restarts 5 applies to no node",
    }
    for args, text in cases.items():
        p = bb2("bb2-launch", *args, timeout=120)
        assert p.returncode == 2, (args, p.stderr)
        assert text in one_error_line(p.stderr, "bb2-launch"), (args, p.stderr)
    fleet = subprocess.run([PY, "-m", "bb2_tools.launch_cli", str(REPO / "missions" / "fleets" / "canyon_pair.yaml"),
                            "--bag-dir", str(tmp_path), "--max-restarts", "5"], capture_output=True, text=True,
                           timeout=120, cwd=tmp_path)   # a fleet's launch says it once, before any boat starts
    assert fleet.returncode == 2 and "--max-restarts 5 applies to no node" in one_error_line(fleet.stderr,
                                                                                            "bb2-launch"), fleet.stderr
    assert sorted(tmp_path.iterdir()) == [bad]   # nothing claimed for a refused launch


# ------------------------------------------------------------------------------------------ bb2-launch graphs
def _short_mission(tmp_path: Path, duration_s: float) -> Path:
    f = tmp_path / f"straight_{duration_s:g}s.yaml"
    f.write_text(f"extends: {REPO / 'missions' / 'straight.yaml'}\nname: straight_short\nduration_s: {duration_s}\n")
    return f


@pytest.mark.ros
def test_two_launches_in_the_same_second_get_their_own_run_dirs_and_valid_bags(tmp_path):
    """Issue 10, point 2, on the real graph: two bb2-launch with the same mission and bag folder started at once
    write two run directories (the second claims ``<stem>_2``), both exit 0 and both bags are complete."""
    pytest.importorskip("rclpy")
    from bb2_tools.bagfile import BagReader

    mission = _short_mission(tmp_path, 5.0)
    cmd = [PY, "-m", "bb2_tools.launcher", str(mission), "--bag-dir", str(tmp_path / "bags"),
           "--end-at", "simulator", "--timeout", "240"]
    env = ros_env()
    ps = [subprocess.Popen(cmd, cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
          for _ in range(2)]
    outs = [p.communicate(timeout=300)[1] for p in ps]
    for p, err in zip(ps, outs):
        assert p.returncode == 0, err[-3000:]
    runs = sorted(d for d in (tmp_path / "bags").iterdir() if d.is_dir())
    stems = {d.name.rsplit("_2", 1)[0] if d.name.endswith("_2") else d.name for d in runs}
    assert len(runs) == 2, runs
    if len(stems) == 1:  # same second: the second claimant got <stem>_2
        assert runs[1].name == runs[0].name + "_2"
    for d in runs:
        assert (d / "metadata.yaml").is_file()
        counts = BagReader(d).message_counts
        assert counts.get("/bb2/state_native", 0) >= round(5.0 / 0.05), counts
        assert any(f"bag:   {d}" in err for err in outs)


@pytest.mark.ros
def test_a_graph_whose_sim_time_stops_is_reported_stalled_and_stopped(tmp_path):
    """Issue 10, point 3: the simulator frozen (SIGSTOP) mid-run: after --stall-timeout the launcher says the graph
    stalled at which sim time, stops it and exits 1 — it is never left at 0x."""
    pytest.importorskip("rclpy")
    mission = _short_mission(tmp_path, 400.0)
    out = tmp_path / "bags" / "run"
    p = subprocess.Popen([PY, "-m", "bb2_tools.launcher", str(mission), "--out", str(out), "--stall-timeout", "4",
                          "--timeout", "200"], cwd=tmp_path, env=ros_env(), stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    sim_pid = None
    try:
        seen = ""
        t0 = time.monotonic()
        while time.monotonic() - t0 < 120:
            line = p.stderr.readline()
            seen += line
            if "RTF" in line and "sim --" not in line and "sim     0.00" not in line:
                break
        logs = out / "logs"
        import re
        for stat in Path("/proc").glob("[0-9]*/cmdline"):
            try:
                cmd = stat.read_bytes().replace(b"\0", b" ").decode(errors="replace")
            except OSError:
                continue
            if re.search(r"\bsimulator\b", cmd) and "launcher" not in cmd and str(mission) in cmd:
                sim_pid = int(stat.parent.name)
        assert sim_pid is not None, seen
        os.kill(sim_pid, signal.SIGSTOP)
        t_stop = time.monotonic()
        while time.monotonic() - t_stop < 60:
            line = p.stderr.readline()
            seen += line
            if "stalled" in line:
                break
        os.kill(sim_pid, signal.SIGCONT)   # let it take the SIGINT that stops it
        _, err = p.communicate(timeout=90)
    finally:
        if sim_pid is not None:
            try:
                os.kill(sim_pid, signal.SIGCONT)
            except ProcessLookupError:
                pass
        if p.poll() is None:
            p.kill()
            p.wait()
    err = seen + err
    assert p.returncode == 1, err[-3000:]
    assert "stopping: stalled: sim time stuck at" in err and "--stall-timeout 4" in err, err[-3000:]
    assert (out / "metadata.yaml").is_file() and logs.is_dir()


# ------------------------------------------------------------------------------------------ bb2-sim
def test_maneuver_refuses_impossible_inputs_with_exit_2(tmp_path):
    cases = {
        ("--depth", "-5"): "above the calm surface",
        ("--depth", "5"): "sail top 6.40 m above the calm surface",
        ("--duration", "1e9"): "in memory",
    }
    for args, text in cases.items():
        p = bb2("bb2-sim", "maneuver", "turning-circle", *args, "--quiet", cwd=tmp_path)
        assert p.returncode == 2, (args, p.stderr)
        assert text in one_error_line(p.stderr, "bb2-sim"), (args, p.stderr)


def test_maneuver_outputs_never_overwritten_silently_and_os_errors_are_exit_2(tmp_path):
    csv = tmp_path / "tc.csv"
    csv.write_text("keep me\n")
    p = bb2("bb2-sim", "maneuver", "turning-circle", "--duration", "1", "--out", str(csv), cwd=tmp_path)
    assert p.returncode == 2 and "--overwrite" in one_error_line(p.stderr, "bb2-sim")
    assert csv.read_text() == "keep me\n"
    png = tmp_path / "tc.png"
    png.write_bytes(b"x")
    p = bb2("bb2-sim", "maneuver", "turning-circle", "--duration", "1", "--plot", str(png), cwd=tmp_path)
    assert p.returncode == 2 and str(png) in one_error_line(p.stderr, "bb2-sim")
    p = bb2("bb2-sim", "maneuver", "turning-circle", "--duration", "1", "--out", str(csv), "--overwrite",
            cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    assert csv.read_text().startswith("t_s,")
    if Path("/dev/full").exists():   # a full device: one line naming the file, exit 2 (not 1: nothing diverged)
        p = bb2("bb2-sim", "maneuver", "turning-circle", "--duration", "1", "--out", "/dev/full", "--overwrite",
                cwd=tmp_path)
        assert p.returncode == 2 and "/dev/full: No space left" in one_error_line(p.stderr, "bb2-sim")


@needs_unshare
@pytest.mark.parametrize("state", ["ro", "full"])
def test_maneuver_and_mission_on_read_only_or_full_folder_fail_before_the_run(tmp_path, state):
    mnt = tmp_path / "m"
    p = run_on_mount([PY, "-m", "bb2_tools.sim_cli", "maneuver", "turning-circle", "--duration", "30",
                      "--out", str(mnt / "sub" / "tc.csv")], mnt, state=state, cwd=tmp_path)
    assert p.returncode == 2, p.stderr
    assert str(mnt) in one_error_line(p.stderr, "bb2-sim") and "maneuver turning-circle" not in p.stdout
    p = run_on_mount([PY, "-m", "bb2_tools.sim_cli", "mission", str(REPO / "missions" / "straight.yaml"),
                      "--out", str(mnt / "sub")], mnt, state=state, cwd=tmp_path)
    assert p.returncode == 2, p.stderr
    assert str(mnt) in one_error_line(p.stderr, "bb2-sim") and "mission straight" not in p.stdout


def test_mission_refuses_impossible_starts_and_bad_files(tmp_path):
    base = REPO / "missions"
    files = {
        "up.yaml": (f"extends: {base / 'straight.yaml'}\ninitial: {{offset_m: [0, 0, 300]}}\n",
                    "above the calm surface"),
        "floor.yaml": (f"extends: {base / 'canyon.yaml'}\ninitial: {{offset_m: [0, 0, -48]}}\n",
                       "inside the sea floor"),
        "long.yaml": (f"extends: {base / 'straight.yaml'}\nduration_s: 1.0e+9\n", "in memory"),
        "twice.yaml": (f"extends: {base / 'straight.yaml'}\nduration_s: 2\nduration_s: 5\n",   # one line
                       "twice.yaml: not valid YAML (line 3, column 1: found the key 'duration_s' twice (first on line 2))"),
    }
    for name, (text, why) in files.items():
        (tmp_path / name).write_text(text)
        p = bb2("bb2-sim", "mission", str(tmp_path / name), cwd=tmp_path)
        assert p.returncode == 2, (name, p.stderr)
        assert why in one_error_line(p.stderr, "bb2-sim"), (name, p.stderr)
    (tmp_path / "latin1.yaml").write_bytes(b"path: straight\nname: caf\xe9\n")
    for tool, args in (("bb2-sim", ["mission", str(tmp_path / "latin1.yaml")]),
                       ("bb2-launch", [str(tmp_path / "up.yaml"), "--bag-dir", str(tmp_path / "bags")])):
        p = bb2(tool, *args, cwd=tmp_path)
        assert p.returncode == 2, p.stderr
        line = one_error_line(p.stderr, tool)
        assert ("not UTF-8" in line) if "latin1" in args[-1] else ("above the calm surface" in line), line
    assert not (tmp_path / "bags").exists()


def _sigint_as_from_a_terminal() -> None:
    """The child's SIGINT at its default action, as in a terminal: a test run started as a background job (``&``
    in a script, as CI harnesses do) hands its children SIGINT ignored, and Python then installs no
    KeyboardInterrupt handler: the Ctrl-C under test would not reach the program at all."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def test_ctrl_c_exits_130_after_flushing_the_csv(tmp_path):
    csv = tmp_path / "tc.csv"
    p = subprocess.Popen([PY, "-m", "bb2_tools.sim_cli", "maneuver", "turning-circle", "--duration", "5000",
                          "--out", str(csv)], cwd=tmp_path, env=ros_env(), stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, preexec_fn=_sigint_as_from_a_terminal)
    t0 = time.monotonic()  # Ctrl-C while the run writes rows (a slow start on a loaded machine: wait for it)
    while time.monotonic() - t0 < 300 and p.poll() is None and (not csv.exists() or csv.stat().st_size < 20000):
        time.sleep(0.2)
    assert p.poll() is None and csv.exists() and csv.stat().st_size >= 20000, "the maneuver never wrote its rows"
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=120)
    assert p.returncode == 130, err
    assert "Traceback" not in err and "interrupted" in err
    lines = csv.read_text().splitlines()
    assert lines[0].startswith("t_s,") and len(lines) > 10
    assert all(len(ln.split(",")) == len(lines[0].split(",")) for ln in lines[:-1])


# ------------------------------------------------------------------------------------------ bb2-analyze
@needs_unshare
def test_analyze_read_only_out_fails_before_the_analysis(tmp_path):
    """A bag written by the in-process graph-free writer is enough: the failure must come before reading it."""
    from bb2_tools.bagfile import BagWriter

    bag = tmp_path / "bag"
    with BagWriter(bag) as w:
        w.add_topic("/clock", "rosgraph_msgs/msg/Clock")
    mnt = tmp_path / "m"
    p = run_on_mount([PY, "-m", "bb2_tools.analyze", str(bag), "--out", str(mnt / "sub")], mnt, state="ro")
    assert p.returncode == 2, p.stderr
    line = one_error_line(p.stderr, "bb2-analyze")
    assert str(mnt / "sub") in line and "Read-only" in line   # not "no usable topics": checked first
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "report.html").write_text("keep")
    p = bb2("bb2-analyze", str(bag), "--out", str(tmp_path / "out"))
    assert p.returncode == 2 and "--overwrite" in one_error_line(p.stderr, "bb2-analyze")
    assert (tmp_path / "out" / "report.html").read_text() == "keep"


@needs_unshare
@pytest.mark.ros
def test_record_on_a_read_only_folder_is_exit_2_with_one_line(tmp_path):
    """bb2-record (the recorder node) told to write where it cannot: one line naming the folder, exit 2."""
    mnt = tmp_path / "m"
    p = run_on_mount([PY, "-m", "bb2_tools.recorder", "--out", str(mnt / "sub" / "rec")], mnt, state="ro",
                     env=ros_env(), timeout=120)
    assert p.returncode == 2, p.stdout + p.stderr
    line = one_error_line(p.stderr, "bb2-record")
    assert str(mnt / "sub") in line and "Read-only" in line, line


@pytest.mark.ros
def test_replay_of_a_bag_with_a_non_utf8_metadata_file_is_exit_2_with_one_line(tmp_path):
    """bb2-replay on a bag whose metadata.yaml is not text: one line naming the file, exit 2, no traceback."""
    from bb2_tools.bagfile import BagWriter

    bag = tmp_path / "bag"
    with BagWriter(bag) as w:
        w.add_topic("/clock", "rosgraph_msgs/msg/Clock")
    (bag / "metadata.yaml").write_bytes(b"rosbag2_bagfile_information:\n  version: \xff\xfe 9\n")
    p = bb2("bb2-replay", str(bag))
    assert p.returncode == 2, p.stdout + p.stderr
    line = one_error_line(p.stderr, "bb2-replay")
    assert "metadata.yaml" in line and "UTF-8" in line, line


# ------------------------------------------------------------------------------------------ node parameters
@pytest.mark.ros
@pytest.mark.parametrize("bad", ["lockstep_timeout_s:=abc", "lockstep_timeout_s:=.nan", "wait_for_readers:=maybe"])
def test_node_refuses_an_invalid_command_line_value_after_the_params_file(bad):
    """rclpy keeps the params file's value (or the default) for a -p value of the wrong type: the node must
    refuse it, exit 2 with one line naming the parameter (the launcher passes its -p after --params-file)."""
    pytest.importorskip("rclpy")
    from rosenv import spawn_node

    p = spawn_node("bb2_ros.simulator", 199, "--params-file", str(REPO / "config" / "bb2_graph.yaml"),
                   "-p", f"mission_file:={REPO / 'missions' / 'straight.yaml'}", "-p", bad)
    try:
        out, _ = p.communicate(timeout=120)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
    assert p.returncode == 2, out
    name = bad.split(":=")[0]
    errors = [ln for ln in out.splitlines() if ": error:" in ln]
    assert len(errors) == 1 and f"parameter {name!r}" in errors[0], out
    assert "Traceback" not in out


def test_run_hil_refuses_a_negative_duration(tmp_path):
    """Bad input is one line and exit 2 before any process starts: a priority or sensor suite the autopilot would
    refuse, or a mission it could not load, came out as "the autopilot or the monitor did not come up"."""
    bad_mission = tmp_path / "bad.yaml"
    bad_mission.write_text("path: no_such_path\n")
    for args, text in ((["--duration", "-5"], "--duration must be > 0"), (["--rate-hz", "nan"], "--rate-hz"),
                       (["--mission", "/nonexistent.yaml"], "does not exist"),
                       (["--autopilot-priority", "200"], "--autopilot-priority must be in 0..99, got 200"),
                       (["--sensors", "nope"], "--sensors: no suite 'nope' (one of tactical, mems, or a suite file)"),
                       (["--mission", str(bad_mission)], "path: no such path file or shipped path 'no_such_path'")):
        p = subprocess.run([PY, str(REPO / "examples" / "hil" / "run_hil.py"), *args], capture_output=True,
                           text=True, timeout=60, env=ros_env())
        assert p.returncode == 2 and text in one_error_line(p.stderr, "run_hil.py"), p.stderr
    # the autopilot template alone says the same of the mission (it stopped with a traceback, exit 1)
    p = subprocess.run([PY, str(REPO / "examples" / "hil" / "external_autopilot.py"), "--mission", str(bad_mission)],
                       capture_output=True, text=True, timeout=60, env=ros_env())
    assert p.returncode == 2 and "no_such_path" in one_error_line(p.stderr, "external_autopilot.py"), p.stderr
