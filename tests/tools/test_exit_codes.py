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
    assert O.check_output_file(f) == f and f.parent.is_dir() and not f.exists()
    f.write_text("keep me")
    with pytest.raises(O.OutputError, match="exists .give --overwrite"):
        O.check_output_file(f)
    assert O.check_output_file(f, overwrite=True) == f and f.read_text() == "keep me"
    with pytest.raises(O.OutputError, match="is a directory"):
        O.check_output_file(tmp_path / "a")


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
    }
    for args, text in cases.items():
        p = bb2("bb2-launch", *args, timeout=120)
        assert p.returncode == 2, (args, p.stderr)
        assert text in one_error_line(p.stderr, "bb2-launch"), (args, p.stderr)
    assert sorted(tmp_path.iterdir()) == [bad]   # nothing claimed for a refused launch
