"""`bb2-sim maneuver` as a user runs it: output files, printed figures, exit status 2 for bad input, and a
diverging run that stops with a clear message and keeps its CSV."""
import csv
import os
import re
import subprocess
import sys

import pytest

from bb2_sim.maneuvers import CSV_COLUMNS, OUTPUT_COLUMNS


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
    assert rows[0] == OUTPUT_COLUMNS and rows[0][:len(CSV_COLUMNS)] == CSV_COLUMNS  # eta_cg_m last
    assert all(float(r[-1]) == 0.0 for r in rows[1:])   # calm water: no elevation
    assert len(rows) == 1 + 1001                     # every 0.1 s from 0 to 100 s
    assert float(rows[-1][0]) == pytest.approx(100.0)
    assert float(rows[1][19]) == -20.0               # cmd_dX1 = -rudder for a starboard turn (dh = -20)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 20_000


def test_figures_a_short_run_did_not_reach_are_said_with_the_maneuvers_own_duration():
    p = run("maneuver", "hzz", "--duration", "60", "--quiet")
    assert p.returncode == 0, p.stderr
    said = [line for line in p.stdout.splitlines() if line.startswith("  nan:")]
    assert said == ["  nan: not reached in this 60.0 s run: Second overshoot, First full period, Settled period "
                    "(last) (--duration 60 is shorter than maneuver hzz's own 400 s)"]
    # an order equal to the start asks for no step response: its NaN figures are not missed ones
    p = run("maneuver", "depth-heading", "--depth-ref", "20", "--heading-ref-deg", "0", "--duration", "20",
            "--quiet")
    assert p.returncode == 0, p.stderr
    assert re.search(r"Time to 90 % of the depth change +nan s", p.stdout)
    assert not [line for line in p.stdout.splitlines() if line.startswith("  nan:")], p.stdout


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
    # an option the maneuver does not read (it was ignored without a word)
    (["maneuver", "hzz", "--rudder-deg", "20"],
     "--rudder-deg does not apply to maneuver hzz (vertical pid, horizontal zigzag): it would fly without it"),
    (["maneuver", "turning-circle", "--planes-deg", "1,2,3,4,5"], "--planes-deg does not apply to maneuver turning"),
    (["maneuver", "open-loop", "--amplitude-deg", "20", "--check-deg", "5"],
     "--amplitude-deg, --check-deg do not apply to maneuver open-loop"),
    (["maneuver", "turning-circle", "--heading-ref-deg", "10"], "--heading-ref-deg does not apply"),
    (["maneuver", "vzz", "--depth-ref", "50"], "--depth-ref does not apply to maneuver vzz"),
    (["maneuver", "hzz", "--sail-planes", "pid"], "--sail-planes does not apply to maneuver hzz"),
    (["maneuver", "hzz", "--sail-planes", "half"], "invalid choice"),
    (["maneuver", "hzz", "--substeps", "0"], "--substeps: must be >= 1"),
    (["maneuver", "hzz", "--substeps", "1.5"], "--substeps: not an integer"),
    (["maneuver", "hzz", "--plot", "/nonexistent_dir/hzz.txt"], "a plot is written as png, pdf, svg, eps, ps"),
])
def test_bad_input_one_clear_error_exit_2(args, needle):
    p = run(*args)
    assert p.returncode == 2
    assert needle in p.stderr
    assert "Traceback" not in p.stderr and len(p.stderr.strip().splitlines()) <= 3


@pytest.mark.parametrize("args, asked", [
    (["turning-circle", "--rudder-deg", "35"], "35 deg (its rudder of 35 deg)"),
    (["turning-circle", "--rudder-deg", "-95"], "95 deg (its rudder of -95 deg)"),
    (["hzz", "--amplitude-deg", "40"], "40 deg (its zigzag amplitude of 40 deg)"),
    (["vzz", "--amplitude-deg", "31"], "31 deg (its zigzag amplitude of 31 deg)"),
    (["open-loop", "--planes-deg", "0,0,0,0,40"], "40 deg (its imposed planes 0,0,0,0,40 deg)"),
    (["turning-circle", "--rudder-deg", "30"], None),  # at the limit: nothing to say
    (["hzz", "--amplitude-deg", "20"], None),
    (["open-loop", "--planes-deg", "10,10,-10,-10,0"], None),
])
def test_a_plane_command_beyond_the_planes_limit_is_warned_and_flown_at_the_limit(args, asked, tmp_path):
    """The planes stop at their 30 deg limit (the authors' saturation); a maneuver asking more of them is flown
    (exit 0) and says, before the run, that it is the limit's run, not the command's."""
    out = tmp_path / "m.csv"
    p = run("maneuver", *args, "--duration", "6", "--out", str(out))
    assert p.returncode == 0, p.stderr
    said = [ln for ln in p.stderr.splitlines() if "beyond their limit" in ln]
    if asked is None:
        assert not said, p.stderr
        return
    assert said == [f"bb2-sim: warning: maneuver {args[0]}: the planes are asked for up to {asked}, beyond their "
                    f"limit of 30 deg, where they stop: the run is that of the limit, not of the command"], p.stderr
    rows = list(csv.DictReader(out.open()))
    commanded = max(abs(float(r[f"cmd_dX{i}_deg"])) for r in rows for i in range(1, 6))
    applied = max(abs(float(r[f"dX{i}_deg"])) for r in rows for i in range(1, 6))
    assert commanded > 30.0 and applied == 30.0  # asked beyond the limit, stopped at it


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
    assert "--substeps" not in p.stderr  # a slow boat: not the step's numerical limit


def test_a_fast_boat_diverging_at_the_authors_step_is_told_of_substeps_which_fly_it(tmp_path):
    """15 m/s at 4 rps: the authors' 0.05 s step goes numerically unstable within seconds; the message says so
    and names ``--substeps K`` for that speed, which flies the same maneuver to the end (rows still every 0.1 s)."""
    args = ["maneuver", "open-loop", "--speed-mps", "15", "--rps", "4", "--duration", "20", "--quiet"]
    p = run(*args)
    assert p.returncode == 1 and "diverged at t =" in p.stderr, p.stderr
    advice = re.search(r"--substeps (\d+) integrates it in \1$", p.stderr, re.MULTILINE)
    assert "numerically unstable" in p.stderr and advice and int(advice.group(1)) >= 2, p.stderr
    warned = re.search(r"^bb2-sim: warning: maneuver open-loop at about [0-9.]+ m/s is faster than the ROM's 0.05 s "
                       r"step in 1 ode3 step\(s\) flies steadily .* --substeps (\d+) flies to about", p.stderr, re.M)
    assert warned and int(warned.group(1)) >= 2, p.stderr
    out = tmp_path / "fast.csv"
    p = run(*args, "--substeps", advice.group(1), "--out", str(out))
    assert p.returncode == 0 and "diverged" not in p.stderr and "warning" not in p.stderr, p.stderr
    rows = list(csv.reader(out.open()))
    assert len(rows) == 1 + 201 and float(rows[-1][0]) == pytest.approx(20.0)
    assert float(rows[-1][rows[0].index("U_m_s")]) > 15.0


def test_a_boat_diverging_while_it_speeds_up_is_advised_for_the_speed_it_was_heading_for():
    """``--rps 100`` (a steady cruise of about 431 m/s) diverges within 5 s, at about 15 m/s: the advice was
    ``--substeps 3`` (for 15 m/s), which diverged again, a little later, while the warning before the run had
    said 8.  It now names where the boat was heading and the sub-steps for it, beyond the measured table."""
    p = run("maneuver", "turning-circle", "--rps", "100", "--quiet")
    assert p.returncode == 1 and "diverged at t =" in p.stderr, p.stderr
    hint = next(line for line in p.stderr.splitlines() if "numerically unstable" in line)
    assert re.match(r"bb2-sim: the boat held [0-9.]+ m/s on its way to about 431\.0 m/s \(the steady cruise of its "
                    r"propeller command\)", hint) and hint.endswith(
        "--substeps 8 integrates it in 8 or more (faster than measured: benchmarks/substeps_stability.py)"), hint
    assert "--substeps 8 flies faster than measured" in p.stderr  # the warning before the run: the same advice


def test_authors_surfaces_accepted_as_user_mesh(shared, tmp_path):
    surf = shared("bb2_rom", "surface")
    out = tmp_path / "ol.csv"
    p = run("maneuver", "open-loop", "--hull-mesh", str(surf), "--duration", "10", "--out", str(out))
    assert p.returncode == 0, p.stderr
    assert "7764 triangles" in p.stdout and "trimmed" not in p.stdout


# ------------------------------------------------------------------------------------------- the sea options
def _read(path):
    rows = list(csv.reader(open(path)))
    return rows[0], [[float(v) for v in r] for r in rows[1:]]


def test_sea_command_writes_the_elevation_record_and_prints_hs_tp(tmp_path):
    out = tmp_path / "eta.csv"
    p = run("sea", "--spectrum", "jonswap", "--hs", "3.25", "--tp", "9.7", "--duration", "1200", "--dt", "0.2",
            "--seed", "3", "--out", str(out))
    assert p.returncode == 0, p.stderr
    head, rows = _read(out)
    assert head == ["t_s", "eta_m"] and len(rows) == 6001
    assert rows[1][0] == pytest.approx(0.2) and rows[-1][0] == pytest.approx(1200.0)
    import re
    hs = [float(v) for v in re.findall(r"Hs = ([0-9.]+) m", p.stdout)]
    tp = [float(v) for v in re.findall(r"Tp = ([0-9.]+) s", p.stdout)]
    assert hs[0] == 3.25 and abs(hs[1] - 3.25) < 0.05 * 3.25      # target, realisation 4 sqrt(m0)
    assert tp[0] == 9.7 and abs(tp[1] - 9.7) < 0.05 * 9.7
    eta = [r[1] for r in rows]
    m = sum(eta) / len(eta)
    assert abs(4 * (sum((e - m) ** 2 for e in eta) / len(eta)) ** 0.5 - 3.25) < 0.1 * 3.25
    # the same sea at another point differs; the same seed gives the same record
    out2 = tmp_path / "eta2.csv"
    assert run("sea", "--spectrum", "jonswap", "--hs", "3.25", "--tp", "9.7", "--duration", "1200", "--dt", "0.2",
               "--seed", "3", "--at", "100,50", "--out", str(out2)).returncode == 0
    assert _read(out2)[1] != rows


@pytest.mark.parametrize("duration, coarse", [(10, True), (100, True), (600, False)])
def test_sea_command_says_when_the_records_welch_tp_is_coarse(tmp_path, duration, coarse):
    """A record's Welch Tp is resolved to about Tp / segment: a 10-s record's says 1.6 s for an 8-s sea.  Said as
    coarse, with the record length that resolves it, while its segments hold fewer than ten peak periods."""
    import re

    p = run("sea", "--spectrum", "jonswap", "--hs", "2", "--tp", "8", "--duration", str(duration),
            "--out", str(tmp_path / "eta.csv"))
    assert p.returncode == 0, p.stderr
    line = next(ln for ln in p.stdout.splitlines() if "Welch" in ln)
    assert ("coarse" in line) == coarse, line
    if coarse:
        need = float(re.search(r"a record of about ([0-9]+) s resolves Tp to 10 %", line).group(1))
        assert need > duration
        segment = float(re.search(r"its segments of ([0-9.]+) s hold", line).group(1))
        assert segment < 10 * 8


def test_sea_command_regular_wave_is_the_cosine(tmp_path):
    import math
    out = tmp_path / "reg.csv"
    p = run("sea", "--spectrum", "regular", "--amplitude-m", "1.5", "--period-s", "8", "--heading-deg", "90",
            "--at", "0,20", "--duration", "16", "--out", str(out))
    assert p.returncode == 0, p.stderr
    _, rows = _read(out)
    k = (2 * math.pi / 8) ** 2 / 9.81
    for t, eta in rows:
        assert eta == pytest.approx(1.5 * math.cos(k * 20 - 2 * math.pi / 8 * t), abs=1e-9)


def test_sea_command_refuses_an_existing_out_file_unless_overwrite(tmp_path):
    """Issue 10, point 5: an existing record is kept (exit 2, one line, before the work) unless --overwrite."""
    out = tmp_path / "eta.csv"
    out.write_text("keep me\n")
    args = ("sea", "--spectrum", "regular", "--amplitude-m", "1", "--period-s", "8", "--duration", "4", "--out",
            str(out))
    p = run(*args)
    assert p.returncode == 2 and "exists (give --overwrite to replace it)" in p.stderr, p.stderr
    assert len(p.stderr.strip().splitlines()) == 1 and out.read_text() == "keep me\n"
    p = run(*args, "--overwrite")
    assert p.returncode == 0, p.stderr
    assert _read(out)[0] == ["t_s", "eta_m"]


def test_sea_command_reads_a_component_file(tmp_path):
    f = tmp_path / "comps.csv"
    f.write_text("amplitude_m,omega_rad_s,direction_deg,phase_deg\n1.0,0.6,0,0\n0.5,0.9,90,45\n")
    out = tmp_path / "eta.csv"
    p = run("sea", "--components", str(f), "--duration", "10", "--out", str(out))
    assert p.returncode == 0, p.stderr
    assert _read(out)[1][0][1] == pytest.approx(1.0 + 0.5 * 0.5 ** 0.5)


@pytest.mark.parametrize("args,needle", [
    (["--spectrum", "jonswap", "--hs", "-1", "--tp", "9"], "hs must be >= 0"),
    (["--spectrum", "jonswap", "--hs", "3", "--tp", "0"], "tp must be > 0"),
    (["--spectrum", "jonswap", "--hs", "3", "--tp", "-2"], "tp must be > 0"),
    (["--spectrum", "jonswap", "--hs", "3", "--tp", "9", "--gamma", "0.9"], "gamma must be >= 1"),
    (["--spectrum", "jonswap", "--hs", "3", "--tp", "9", "--components", "0"], "components"),
    (["--spectrum", "jonswap", "--hs", "nan", "--tp", "9"], "finite"),
    (["--spectrum", "jonswap", "--hs", "3", "--tp", "inf"], "finite"),
    (["--spectrum", "jonswap", "--hs", "3", "--tp", "9", "--spreading-s", "nan"], "finite"),
    (["--spectrum", "ittc", "--hs", "3"], "needs tp"),
    (["--spectrum", "swell", "--hs", "3", "--tp", "9"], "invalid choice"),
    (["--components", "/no/such/components.csv"], "not found"),
    (["--spectrum", "jonswap", "--hs", "3", "--tp", "9", "--dt", "0"], "dt must be > 0"),
    (["--spectrum", "jonswap", "--hs", "3", "--tp", "9", "--at", "1"], "X,Y"),
    # said up front with the size (was "out of memory", after the allocation failed)
    (["--spectrum", "regular", "--hs", "3", "--tp", "9", "--dt", "1e-9"],
     "a record of 10000000001 samples (10 s every 1e-09 s) would need about 447.0 GiB in memory"),
])
def test_sea_command_bad_input_exit_2(args, needle, tmp_path):
    p = run("sea", *args, "--duration", "10", "--out", str(tmp_path / "x.csv"))
    assert p.returncode == 2, p.stdout + p.stderr
    assert needle in p.stderr and "Traceback" not in p.stderr and len(p.stderr.strip().splitlines()) == 1


def test_sea_command_warns_of_a_sea_steeper_than_any_wave_and_writes_it(tmp_path):
    p = run("sea", "--spectrum", "jonswap", "--hs", "30", "--tp", "9", "--duration", "10", "--out",
            str(tmp_path / "x.csv"))
    assert p.returncode == 0 and (tmp_path / "x.csv").is_file(), p.stderr
    said = [ln for ln in p.stderr.splitlines() if ln.startswith("bb2-sim: warning: ")]
    assert len(said) == 1 and "Hs / Lp = 30 / 126 m = 0.237, steeper than any deep-water wave" in said[0], p.stderr
    p = run("sea", "--spectrum", "jonswap", "--hs", "3.25", "--tp", "9.7", "--duration", "10", "--out",
            str(tmp_path / "y.csv"))
    assert p.returncode == 0 and "warning" not in p.stderr, p.stderr


@pytest.mark.parametrize("dt, warned", [(0.1, False), (0.5, False), (1.0, True), (5.0, True)])
def test_sea_command_warns_when_its_dt_aliases_the_sea(tmp_path, dt, warned):
    """A record every dt holds the waves of periods over 2 dt; the shorter ones fold onto longer periods (a 4-s sea
    every 2 s gave a Welch Tp that was not the sea's, unsaid).  Warned with the share of the energy and the dt that
    resolves it; the record is written all the same."""
    import re

    p = run("sea", "--spectrum", "jonswap", "--hs", "1", "--tp", "4", "--duration", "400", "--dt", str(dt), "--out",
            str(tmp_path / "eta.csv"))
    assert p.returncode == 0 and (tmp_path / "eta.csv").is_file(), p.stderr
    said = [ln for ln in p.stderr.splitlines() if "Nyquist" in ln]
    assert bool(said) == warned, p.stderr
    if warned:
        m = re.search(rf"--dt {dt:g} s samples ([0-9]+)% of the sea's energy \(periods under {2 * dt:g} s\) below its "
                      r"Nyquist rate: .* take --dt <= ([0-9.]+) s \(a tenth of Tp ([0-9.]+) s\)", said[0])
        assert m and 1 <= int(m.group(1)) <= 100 and float(m.group(2)) < dt, said[0]
        assert abs(float(m.group(3)) - 4.0) < 0.2, said[0]


def test_a_maneuver_started_at_rest_under_iowa_says_why_it_diverged_and_what_starts_from_rest(tmp_path):
    """``--speed-mps 0``: the authors' model divides by the relative speed (Q13) and the run diverged at t = 0 with
    'float division by zero' and nothing more; it now says so and names the profiles that start from rest (and the
    corrected one does: exit 0)."""
    p = run("maneuver", "self-propulsion", "--speed-mps", "0", "--duration", "2", "--quiet")
    assert p.returncode == 1, p.stderr
    assert ("bb2-sim: it started at rest: the iowa profile is singular at zero relative speed (Q13: u/|u| and the "
            "plane incidence divide by it, as in the authors' model); the corrected profile starts from rest, as does "
            "any with zero_speed_guard: true ({base: iowa, zero_speed_guard: true})") in p.stderr.splitlines(), p.stderr
    p = run("maneuver", "self-propulsion", "--speed-mps", "0", "--duration", "2", "--quiet", "--profile", "corrected")
    assert p.returncode == 0 and "at rest" not in p.stderr, p.stderr


def test_sea_command_unreadable_component_file_exit_2(tmp_path):
    f = tmp_path / "bad.csv"
    f.write_text("amplitude_m,omega_rad_s\n1,2\n")
    p = run("sea", "--components", str(f), "--duration", "10", "--out", str(tmp_path / "x.csv"))
    assert p.returncode == 2 and "missing column" in p.stderr and "Traceback" not in p.stderr


def test_maneuver_in_an_irregular_sea_and_a_current(tmp_path):
    """Same columns as calm water plus eta_cg_m = the sea's elevation above the CG; the current drifts the
    boat towards +y over ground."""
    out = tmp_path / "sp.csv"
    p = run("maneuver", "self-propulsion", "--duration", "10", "--spectrum", "jonswap", "--hs", "2",
            "--tp", "9", "--components", "8", "--wave-heading-deg", "30", "--spreading-s", "8",
            "--current-mps", "1.0", "--current-heading-deg", "90", "--out", str(out), "--quiet")
    assert p.returncode == 0, p.stderr
    assert "jonswap Hs 2 m" in p.stdout and "current 1 m/s towards 90 deg" in p.stdout
    head, rows = _read(out)
    assert head == OUTPUT_COLUMNS and len(rows) == 101
    from bb2_sim.environment import sea_from_mapping
    sea = sea_from_mapping({"spectrum": "jonswap", "hs": 2, "tp": 9, "components": 8, "heading_deg": 30,
                            "spreading_s": 8}).build()
    for r in rows[::20]:
        assert r[-1] == pytest.approx(float(sea.elevation(r[1], r[2], r[0])), abs=1e-9)
    assert rows[-1][2] > 4.0          # y over ground: carried towards +y by the 1 m/s current (6.9 m in 10 s)


def test_maneuver_sea_state_table_elevation_column(tmp_path):
    """The authors' table (--sea-state) keeps its run bit for bit; eta_cg_m is its A sin(k x - w t)."""
    import math

    from bb2_sim.parameters import load_parameters
    from bb2_sim.waves import wave_for_sea_state
    out = tmp_path / "dh.csv"
    p = run("maneuver", "depth-heading", "--duration", "5", "--out", str(out), "--quiet")
    assert p.returncode == 0, p.stderr
    _, rows = _read(out)
    w = wave_for_sea_state(5, load_parameters())
    for r in rows:
        assert r[-1] == pytest.approx(w.amplitude * math.sin(w.wavenumber * r[1] - w.omega * r[0]), abs=1e-9)


@pytest.mark.parametrize("args,needle", [
    (["--spectrum", "jonswap", "--hs", "-1", "--tp", "9"], "hs must be >= 0"),
    (["--spectrum", "jonswap", "--hs", "3", "--tp", "0"], "tp must be > 0"),
    (["--spectrum", "jonswap", "--hs", "3", "--tp", "9", "--gamma", "0"], "gamma must be >= 1"),
    (["--spectrum", "jonswap", "--hs", "3", "--tp", "9", "--components", "-3"], "components"),
    (["--spectrum", "jonswap", "--hs", "3", "--tp", "9", "--wave-heading-deg", "nan"], "finite"),
    (["--components", "/no/such.csv"], "not found"),
    (["--current-mps", "-1"], "current"),
    (["--current-mps", "1", "--current-heading-deg", "inf"], "finite"),
    (["--current-heading-deg", "90"], "heading_deg without speed_mps"),   # it flew no current without a word
    (["--hs", "3"], "need a spectrum"),
    (["--sea-state", "5", "--components", "32"], "components need a spectrum"),   # flew the table's one wave
])
def test_maneuver_bad_sea_input_exit_2(args, needle):
    p = run("maneuver", "self-propulsion", "--duration", "1", *args)
    assert p.returncode == 2, p.stdout + p.stderr
    assert needle in p.stderr and "Traceback" not in p.stderr and len(p.stderr.strip().splitlines()) == 1
