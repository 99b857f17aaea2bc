"""Maneuver plots: files are valid PNGs and the axes show the trajectory that was passed in."""
from __future__ import annotations

import math
import struct

import numpy as np
import pytest

from bb2_sim.metrics import TrajectoryError, load_csv, turning_circle_figures
from bb2_sim.plots import maneuver_figure, plot_maneuver, track_in_approach_axes


def png_size(path):
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", "not a PNG signature"
    assert data[12:16] == b"IHDR"
    width, height = struct.unpack(">II", data[16:24])
    assert data[-8:-4] == b"IEND"
    return width, height, len(data)


def synthetic_turn(radius=60.0, speed=4.0, psi0_deg=0.0, side=+1, turns=1.6, dt=0.2):
    """An exact starboard (side=+1) or port turn from t = 0 with every CSV column present."""
    omega = speed / radius
    t = np.arange(0.0, turns * 2 * math.pi / omega, dt)
    chi = omega * t
    psi0 = math.radians(psi0_deg)
    along, across = radius * np.sin(chi), side * radius * (1 - np.cos(chi))
    x = -math.cos(psi0) * along - math.sin(psi0) * across
    y = -math.sin(psi0) * along + math.cos(psi0) * across
    n = t.size
    z = np.zeros(n)
    traj = {"t_s": t, "x_m": x, "y_m": y, "z_m": z - 40.0 + 0.01 * t, "phi_deg": -2.0 * side + z,
            "theta_deg": 0.5 * np.sin(chi), "psi_deg": np.degrees(psi0 - side * chi),
            "u_m_s": z - speed, "v_m_s": z, "w_m_s": z, "p_deg_s": z, "q_deg_s": z,
            "r_deg_s": z - side * math.degrees(omega), "U_m_s": z + speed, "n_rps": z + 1.2,
            "thrust_N": z + 1e5, "thrust_net_N": z + 7.5e4, "torque_Nm": z + 9e4}
    for i, d in enumerate((-20, 20, 20, -20, 0), start=1):
        traj[f"dX{i}_deg"] = z + side * d
        traj[f"cmd_dX{i}_deg"] = z + side * d
    return traj


def lines_of(ax):
    return [ln for ln in ax.get_lines() if len(ln.get_xdata()) > 2]


@pytest.mark.parametrize("side", [+1, -1])
def test_turning_circle_plan_view_shows_the_track(side):
    traj = synthetic_turn(psi0_deg=40.0, side=side)
    figs = turning_circle_figures(traj, length_m=70.2)
    fig = maneuver_figure("turning-circle", traj, figures=figs)
    (plan,) = [a for a in fig.axes if a.get_gid() == "plan"]
    track = lines_of(plan)[0]
    across, along = track_in_approach_axes(traj)
    assert np.allclose(track.get_xdata(), across / 70.2) and np.allclose(track.get_ydata(), along / 70.2)
    # a starboard turn goes to + across, a port turn to - across; advance is always ahead
    assert side * np.max(side * track.get_xdata()) == pytest.approx(side * 2 * 60.0 / 70.2, rel=1e-3)
    assert np.max(track.get_ydata()) == pytest.approx(60.0 / 70.2, rel=1e-3)
    assert plan.get_aspect() == 1.0
    texts = " ".join(t.get_text() for t in plan.texts)
    assert f"{figs.tactical_diameter_m:.1f} m" in texts and f"{figs.advance_90_m:.1f} m" in texts
    # time histories span the run
    (summary,) = [a for a in fig.axes if a.get_gid() == "summary"]
    assert f"Steady turning radius (circle fit): {figs.steady_radius_m:.4g} m" in summary.texts[0].get_text()
    others = [a for a in fig.axes if a not in (plan, summary)]
    assert len(others) == 5
    assert others[-1].get_xlim() == pytest.approx((traj["t_s"][0], traj["t_s"][-1]))


def test_reference_overlay_is_dashed_and_carries_the_reference_data():
    traj, ref = synthetic_turn(radius=60.0), synthetic_turn(radius=75.0)
    fig = maneuver_figure("turning-circle", traj, reference=ref)
    (plan,) = [a for a in fig.axes if a.get_gid() == "plan"]
    dashed = [ln for ln in lines_of(plan) if ln.get_linestyle() == "--"]
    assert len(dashed) == 1
    assert np.max(dashed[0].get_ydata()) == pytest.approx(75.0 / 70.2, rel=1e-3)


def test_plot_maneuver_writes_a_png(tmp_path):
    out = plot_maneuver("turning-circle", synthetic_turn(), tmp_path / "sub" / "tc.png")
    assert out == tmp_path / "sub" / "tc.png"
    w, h, nbytes = png_size(out)
    assert 1000 <= w <= 2500 and 700 <= h <= 1800
    assert nbytes > 30_000


@pytest.mark.parametrize("name", ["self-propulsion", "depth-heading", "open-loop"])
def test_straight_run_plots(tmp_path, name):
    traj = synthetic_turn(turns=0.3)
    fig = maneuver_figure(name, traj, settings={"depth": 40.0, "depth_ref": 45.0, "heading_ref_deg": -10})
    (depth_ax,) = [a for a in fig.axes if a.get_gid() == "depth"]
    ln = lines_of(depth_ax)[0]
    assert np.allclose(ln.get_ydata(), -traj["z_m"])           # depth is plotted positive down
    assert depth_ax.yaxis_inverted()
    w, h, _ = png_size(plot_maneuver(name, traj, tmp_path / f"{name}.png"))
    assert w > 800 and h > 600


def test_zigzag_plot_from_reference_run(shared, tmp_path):
    traj = load_csv(shared("bb2_reference", "ref_vzz10_mode4.csv"))
    fig = maneuver_figure("vzz", traj)                          # amplitude inferred from the commands
    (ax,) = [a for a in fig.axes if a.get_gid() == "zigzag"]
    theta, dv = lines_of(ax)[:2]
    assert np.max(theta.get_ydata()) == pytest.approx(np.max(traj["theta_deg"]), abs=1e-9)
    assert np.max(np.abs(dv.get_ydata())) == pytest.approx(10.0, abs=1e-6)   # stern planes +-10
    notes = [t.get_text() for t in ax.texts]
    assert notes[0] == "1.55°"                                  # first overshoot annotated at its peak
    w, h, _ = png_size(plot_maneuver("vzz", traj, tmp_path / "vzz.png"))
    assert w > 800 and h > 600


def test_unknown_maneuver_is_rejected(tmp_path):
    with pytest.raises(TrajectoryError, match="unknown maneuver"):
        plot_maneuver("loop-the-loop", synthetic_turn(), tmp_path / "x.png")
    assert not (tmp_path / "x.png").exists()


def test_the_plot_is_written_in_the_format_of_its_extension(tmp_path):
    """``--plot x.pdf`` wrote a PNG into x.pdf (and x.svg); the extension now names the format (none: PNG), and
    one matplotlib does not write is refused before anything is drawn."""
    from bb2_sim.plots import plot_format

    heads = {"pdf": b"%PDF", "svg": b"<?xml", "png": b"\x89PNG"}
    for ext, head in heads.items():
        out = plot_maneuver("turning-circle", synthetic_turn(), tmp_path / f"tc.{ext.upper()}")
        assert out.read_bytes()[:len(head)] == head, ext
    assert plot_maneuver("turning-circle", synthetic_turn(), tmp_path / "tc").read_bytes()[:4] == b"\x89PNG"
    with pytest.raises(ValueError, match=r"tc.txt: a plot is written as png, pdf, svg, eps, ps \(by its extension\), "
                                         r"not 'txt'"):
        plot_maneuver("turning-circle", synthetic_turn(), tmp_path / "tc.txt")
    assert not (tmp_path / "tc.txt").exists() and plot_format("a.Eps") == "eps"
