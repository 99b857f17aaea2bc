"""`bb2-sim maneuver` as a user runs it: output files, printed figures, exit status 2 for bad input, and a
diverging run that stops with a clear message and keeps its CSV."""
import csv
import os
import subprocess
import sys

import pytest

from bb2_sim.maneuvers import CSV_COLUMNS


def run(*args, cwd=None):
    env = dict(os.environ, MPLBACKEND="Agg")
    return subprocess.run([sys.executable, "-m", "bb2_sim", *args], capture_output=True, text=True, env=env,
                          cwd=cwd, timeout=300)


def test_short_turning_circle_writes_csv_plot_and_figures(tmp_path):
    out, png = tmp_path / "tc.csv", tmp_path / "tc.png"
    p = run("maneuver", "turning-circle", "--duration", "100", "--out", str(out), "--plot", str(png))
    assert p.returncode == 0, p.stderr
    assert "Advance" in p.stdout and "Transfer" in p.stdout and "real time" in p.stdout
    rows = list(csv.reader(out.open()))
    assert rows[0] == CSV_COLUMNS
    assert len(rows) == 1 + 1001                     # every 0.1 s from 0 to 100 s
    assert float(rows[-1][0]) == pytest.approx(100.0)
    assert float(rows[1][19]) == -20.0               # cmd_dX1 = -rudder for a starboard turn (dh = -20)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 20_000


@pytest.mark.parametrize("args,needle", [
    (["maneuver", "zigzag"], "invalid choice"),
    (["maneuver", "hzz", "--sea-state", "9"], "sea state"),
    (["maneuver", "hzz", "--sea-state", "2.5"], "sea state"),
    (["maneuver", "open-loop", "--planes-deg", "1,2,3,4"], "exactly 5"),
    (["maneuver", "open-loop", "--planes-deg", "1,2,3,4,nan"], "finite"),
    (["maneuver", "hzz", "--duration", "-5"], "duration must be positive"),
    (["maneuver", "hzz", "--duration", "0"], "duration must be positive"),
    (["maneuver", "hzz", "--depth", "inf"], "finite"),
    (["maneuver", "vzz", "--speed-mps", "nan"], "finite"),
    (["maneuver", "hzz", "--rps", "-1"], "rps must be >= 0"),
    (["maneuver", "hzz", "--profile", "matlab"], "invalid choice"),
    (["maneuver", "hzz", "--sail-planes", "half"], "invalid choice"),
])
def test_bad_input_one_clear_error_exit_2(args, needle):
    p = run(*args)
    assert p.returncode == 2
    assert needle in p.stderr
    assert "Traceback" not in p.stderr and len(p.stderr.strip().splitlines()) <= 3


def test_unreadable_mesh_exit_2(tmp_path):
    (tmp_path / "Hull.stl").write_text("solid junk\n this is not an stl\nendsolid\n")
    p = run("maneuver", "hzz", "--hull-mesh", str(tmp_path), "--duration", "1")
    assert p.returncode == 2 and "Traceback" not in p.stderr and "error" in p.stderr
    p = run("maneuver", "hzz", "--hull-mesh", str(tmp_path / "missing"), "--duration", "1")
    assert p.returncode == 2 and "Traceback" not in p.stderr


def test_diverging_run_stops_with_a_message_and_keeps_the_csv(tmp_path):
    """The iowa model diverges in a 20 deg port turning circle (REFERENCE.md 5)."""
    out = tmp_path / "port.csv"
    p = run("maneuver", "turning-circle", "--rudder-deg", "-20", "--duration", "300", "--out", str(out))
    assert p.returncode == 1
    assert "diverged at t =" in p.stderr and "non-finite" in p.stderr and "Traceback" not in p.stderr
    rows = list(csv.reader(out.open()))
    t_last = float(rows[-1][0])
    assert 60.0 < t_last < 300.0
    assert all(all(v not in ("nan", "inf", "-inf") for v in r) for r in rows[1:])


def test_authors_surfaces_accepted_as_user_mesh(shared, tmp_path):
    surf = shared("bb2_rom", "surface")
    out = tmp_path / "ol.csv"
    p = run("maneuver", "open-loop", "--hull-mesh", str(surf), "--duration", "10", "--out", str(out))
    assert p.returncode == 0, p.stderr
    assert "7764 triangles" in p.stdout and "trimmed" not in p.stdout
