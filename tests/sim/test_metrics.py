"""Maneuver key figures: reference runs of the authors' compiled model (REFERENCE.md section 4) and
synthetic trajectories with known answers."""
from __future__ import annotations

import math

import numpy as np
import pytest

from bb2_sim import metrics
from bb2_sim.metrics import (TrajectoryError, figures_for, load_csv, open_loop_figures,
                             self_propulsion_figures, turning_circle_figures, zigzag_figures)

DEG = math.degrees


def ref(shared, name):
    return load_csv(shared("bb2_reference", f"{name}.csv"))


# --------------------------------------------------------------------------- reference runs (../shared)
def test_turning_circle_ref_tc20(shared):
    f = turning_circle_figures(ref(shared, "ref_tc20"))
    assert f.turn_direction == "starboard"
    assert f.advance_90_m == pytest.approx(193.2, abs=0.05)
    assert f.transfer_90_m == pytest.approx(103.3, abs=0.05)
    assert f.tactical_diameter_m == pytest.approx(217.6, abs=0.05)
    assert f.advance_180_m == pytest.approx(114.3, abs=0.05)
    assert f.advance_90_m / f.length_m == pytest.approx(2.75, abs=0.005)
    assert f.tactical_diameter_m / f.length_m == pytest.approx(3.10, abs=0.005)
    assert (f.time_90_s, f.time_180_s, f.time_360_s) == pytest.approx((47.6, 80.8, 147.6), abs=0.05)
    assert f.steady_window_s[0] == pytest.approx(466, abs=0.5)
    assert f.steady_radius_m == pytest.approx(88.69, abs=0.005)
    assert f.steady_diameter_m == pytest.approx(177.4, abs=0.05)
    assert f.circle_fit_max_residual_m < 2e-4
    assert f.circle_centre_drift_m == pytest.approx(1.4e-3, abs=0.2e-3)
    assert f.u_over_r_m == pytest.approx(89.0, abs=0.05)
    assert DEG(f.steady_yaw_rate_rad_s) == pytest.approx(-2.682, abs=0.0005)
    assert f.steady_speed_m_s == pytest.approx(4.166, abs=0.0005)
    assert f.speed_ratio == pytest.approx(0.810, abs=0.0005)
    assert DEG(f.drift_angle_rad) == pytest.approx(9.8, abs=0.05)
    assert DEG(f.steady_roll_rad) == pytest.approx(-4.19, abs=0.005)
    assert DEG(f.peak_roll_rad) == pytest.approx(-6.07, abs=0.005)
    assert DEG(f.steady_pitch_rad) == pytest.approx(-2.11, abs=0.005)
    assert (f.initial_z_m, f.final_z_m) == pytest.approx((-35.06, -32.10), abs=0.005)
    assert np.degrees(f.steady_planes_rad) == pytest.approx([-21.31, 18.69, 21.31, -18.69, 1.31], abs=0.005)
    assert f.steady_thrust_N == pytest.approx(220e3, abs=0.5e3)
    assert f.steady_torque_Nm == pytest.approx(184e3, abs=0.5e3)


def test_hzz_ref_hzz20(shared):
    f = zigzag_figures(ref(shared, "ref_hzz20"), "psi_deg", 20.0, 20.0, settled_from_s=150.0)
    assert f.reversal_times_s == pytest.approx(
        [18.75, 63.75, 112.75, 172.90, 224.15, 283.55, 334.80, 394.15], abs=0.005)
    assert f.time_to_first_check_s == pytest.approx(18.75, abs=0.005)
    assert DEG(f.first_overshoot_rad) == pytest.approx(13.16, abs=0.005)
    assert DEG(f.peak_angles_rad[0]) == pytest.approx(33.16, abs=0.005)
    assert f.peak_times_s[:2] == pytest.approx([30.2, 77.2], abs=0.05)
    assert DEG(f.second_overshoot_rad) == pytest.approx(18.41, abs=0.005)
    assert DEG(f.peak_angles_rad[1]) == pytest.approx(-38.41, abs=0.005)
    assert np.degrees(f.later_overshoots_positive_rad) == pytest.approx([23.3, 22.7, 22.7], abs=0.05)
    assert np.degrees(f.later_overshoots_negative_rad) == pytest.approx([19.1, 19.1], abs=0.05)
    assert f.first_period_s == pytest.approx(94.0, abs=0.05)
    assert all(109 <= p <= 111.5 for p in f.periods_s[1:])
    assert f.settled_period_s == pytest.approx(110.6, abs=0.05)
    assert f.settled_forward_speed_range_m_s == pytest.approx((4.24, 4.77), abs=0.005)
    assert f.min_speed_m_s == pytest.approx(4.36, abs=0.005)
    assert f.z_range_m == pytest.approx((-111.6, -99.0), abs=0.05)
    assert np.degrees(f.theta_range_rad) == pytest.approx((-1.9, 14.3), abs=0.05)
    assert np.degrees(f.phi_range_rad) == pytest.approx((-5.7, 8.1), abs=0.05)
    assert f.saturated_planes == ("dX2", "dX4")


def test_hzz_reversals_without_command_columns(shared):
    """The fallback (angle reaching +-check) finds the same reversals to within one output row."""
    traj = {k: v for k, v in ref(shared, "ref_hzz20").items() if not k.startswith("cmd_")}
    f = zigzag_figures(traj, "psi_deg", 20.0, 20.0)
    assert len(f.reversal_times_s) == 8
    assert f.reversal_times_s == pytest.approx(
        [18.75, 63.75, 112.75, 172.90, 224.15, 283.55, 334.80, 394.15], abs=0.1)
    assert DEG(f.first_overshoot_rad) == pytest.approx(13.16, abs=0.005)


def test_vzz_ref_mode4(shared):
    f = zigzag_figures(ref(shared, "ref_vzz10_mode4"), "theta_deg", 10.0, 10.0)
    assert f.time_to_first_check_s == pytest.approx(21.75, abs=0.005)
    assert f.first_peak_time_s == pytest.approx(26.2, abs=0.05)
    assert DEG(f.first_overshoot_rad) == pytest.approx(1.55, abs=0.005)
    assert DEG(f.second_overshoot_rad) == pytest.approx(2.58, abs=0.005)
    assert f.first_period_s == pytest.approx(65.5, abs=0.051)
    assert f.settled_period_s == pytest.approx(66.8, abs=0.05)
    assert (f.initial_speed_m_s, f.min_speed_m_s) == pytest.approx((4.72, 4.72), abs=0.005)
    assert f.max_speed_m_s == pytest.approx(4.84, abs=0.006)
    assert f.z_range_m == pytest.approx((-100.0, -77.4), abs=0.05)
    assert DEG(f.max_abs_pitch_rate_rad_s) == pytest.approx(1.03, abs=0.005)
    assert f.saturated_planes == ()


def test_self_propulsion_ref_sp_calm(shared):
    f = figures_for("self-propulsion", ref(shared, "ref_sp_calm"), depth=15.3724, sea_state=0)
    assert isinstance(f, metrics.SelfPropulsionFigures)
    assert -f.forward_speed_m_s == pytest.approx(-5.533, abs=0.0005)
    assert f.speed_m_s == pytest.approx(5.535, abs=0.0005)
    assert f.speed_m_s / metrics.KNOT_M_S == pytest.approx(10.76, abs=0.005)
    assert f.advance_coefficient == pytest.approx(0.860, abs=0.0005)
    assert (f.KT, f.KQ) == pytest.approx((0.0960, 0.0204), abs=0.00006)
    assert f.thrust_N == pytest.approx(101.8e3, abs=50)
    assert f.thrust_deduction == pytest.approx(0.2513, abs=0.00005)
    assert f.net_thrust_N == pytest.approx(76.2e3, abs=50)
    assert f.torque_Nm == pytest.approx(108.3e3, abs=50)
    assert f.z_m == pytest.approx(-13.37, abs=0.005)
    assert f.z_error_m == pytest.approx(2.01, abs=0.005)
    assert DEG(f.pitch_rad) == pytest.approx(-1.43, abs=0.005)
    assert DEG(f.roll_rad) == pytest.approx(0.33, abs=0.005)
    assert f.heave_velocity_m_s == pytest.approx(0.138, abs=0.0005)
    assert np.degrees(f.planes_rad) == pytest.approx([-1.11, -1.32, 1.11, 1.32, 1.21], abs=0.005)
    assert f.speed_drift_m_s == pytest.approx(-0.002, abs=0.0005)
    assert f.z_drift_m == pytest.approx(0.001, abs=0.0005)


def test_open_loop_refs(shared):
    f0 = open_loop_figures(ref(shared, "ref_openloop_planes0"))
    assert f0.final_forward_speed_m_s == pytest.approx(5.540, abs=0.001)
    assert f0.final_z_m == pytest.approx(-98.85, abs=0.005)
    assert DEG(f0.final_pitch_rad) == pytest.approx(-0.48, abs=0.005)
    assert DEG(f0.final_roll_rad) == pytest.approx(0.30, abs=0.005)
    assert DEG(f0.final_yaw_rate_rad_s) == pytest.approx(-0.0038, abs=0.00005)
    f = figures_for("open-loop", ref(shared, "ref_openloop_rudder20_stbd"))
    assert DEG(f.steady_yaw_rate_rad_s) == pytest.approx(-2.654, abs=0.0005)
    assert f.steady_speed_m_s == pytest.approx(4.17, abs=0.005)
    assert DEG(f.final_roll_rad) == pytest.approx(-4.13, abs=0.005)
    assert DEG(f.final_pitch_rad) == pytest.approx(-3.26, abs=0.005)
    assert f.dive_rate_m_s == pytest.approx(-0.10, abs=0.005)
    assert f.final_z_m == pytest.approx(-135.5, abs=0.05)


def test_csv_roundtrip_matches_reference_header(shared, tmp_path):
    traj = ref(shared, "ref_vzz10_mode4")
    names = list(traj)
    assert names[:4] == ["t_s", "x_m", "y_m", "z_m"] and names[-1] == "dmass_kg"
    p = tmp_path / "t.csv"
    np.savetxt(p, np.column_stack([traj[n] for n in names]), delimiter=",", header=",".join(names),
               comments="")
    again = load_csv(p)
    assert list(again) == names and np.allclose(again["theta_deg"], traj["theta_deg"])


# ------------------------------------------------------------------------------ synthetic trajectories
def circle_traj(radius=100.0, speed=5.0, psi0_deg=30.0, turns=2.3, side=+1, dt=0.1, t0_straight=0.0):
    """Exact turn from t = 0 (side +1 starboard, -1 port) in native axes; optional straight approach."""
    omega = speed / radius
    t = np.arange(0.0, t0_straight + turns * 2 * math.pi / omega + dt / 2, dt)
    tt = np.clip(t - t0_straight, 0.0, None)
    chi = omega * tt
    psi0 = math.radians(psi0_deg)
    e_bow = np.array([-math.cos(psi0), -math.sin(psi0)])
    e_stb = np.array([-math.sin(psi0), math.cos(psi0)])
    s_along = radius * np.sin(chi) + speed * np.minimum(t, t0_straight)
    s_across = side * radius * (1 - np.cos(chi))
    xy = np.outer(s_along, e_bow) + np.outer(s_across, e_stb) + np.array([12.0, -7.0])
    n = t.size
    r = np.where(t >= t0_straight, -side * omega, 0.0)
    return {
        "t_s": t, "x_m": xy[:, 0], "y_m": xy[:, 1], "z_m": np.full(n, -50.0),
        "phi_deg": np.full(n, -3.0 * side), "theta_deg": np.zeros(n),
        "psi_deg": np.degrees(psi0 - side * chi), "u_m_s": np.full(n, -speed), "v_m_s": np.zeros(n),
        "w_m_s": np.zeros(n), "r_deg_s": np.degrees(r), "U_m_s": np.full(n, speed),
    }


@pytest.mark.parametrize("side", [+1, -1])
def test_exact_circle_gives_known_figures(side):
    R, U = 100.0, 5.0
    f = turning_circle_figures(circle_traj(R, U, side=side), length_m=70.2)
    assert f.turn_direction == ("starboard" if side > 0 else "port")
    assert f.advance_90_m == pytest.approx(R, abs=1e-3)
    assert f.transfer_90_m == pytest.approx(R, abs=1e-3)
    assert f.tactical_diameter_m == pytest.approx(2 * R, abs=1e-3)
    assert f.advance_180_m == pytest.approx(0.0, abs=1e-3)
    omega = U / R
    assert f.time_90_s == pytest.approx(math.pi / 2 / omega, abs=1e-6)
    assert f.time_360_s == pytest.approx(2 * math.pi / omega, abs=1e-6)
    assert f.steady_radius_m == pytest.approx(R, rel=1e-9)
    assert f.circle_fit_max_residual_m < 1e-8
    assert f.u_over_r_m == pytest.approx(R, rel=1e-9)
    assert f.steady_yaw_rate_rad_s == pytest.approx(-side * omega, rel=1e-9)
    assert f.speed_ratio == pytest.approx(1.0)
    assert f.steady_window_s[1] - f.steady_window_s[0] == pytest.approx(2 * math.pi / omega, abs=0.11)


def test_port_turn_mirrors_starboard_turn_with_approach():
    kw = dict(radius=80.0, speed=4.0, psi0_deg=-75.0, turns=1.5, t0_straight=20.0, dt=0.05)
    s = turning_circle_figures(circle_traj(side=+1, **kw), length_m=70.2)
    p = turning_circle_figures(circle_traj(side=-1, **kw), length_m=70.2)
    assert s.advance_90_m == pytest.approx(80.0 + 4.0 * 20.0, abs=1e-3)   # approach run + R
    for name in ("advance_90_m", "transfer_90_m", "tactical_diameter_m", "advance_180_m", "time_90_s",
                 "time_180_s", "steady_radius_m"):
        assert getattr(p, name) == pytest.approx(getattr(s, name), rel=1e-9, abs=1e-9), name
    assert p.steady_roll_rad == pytest.approx(-s.steady_roll_rad)


def test_short_turn_leaves_steady_figures_nan():
    f = turning_circle_figures(circle_traj(turns=0.6), length_m=70.2)
    assert f.tactical_diameter_m == pytest.approx(200.0, abs=1e-3)
    assert math.isnan(f.time_360_s) and math.isnan(f.steady_radius_m)
    unreached = f.unreached()   # the figures past 216 deg, and the steady turn (a tuple of NaN is one of them)
    assert "Time to 360 deg" in unreached and "Steady window (last 360 deg)" in unreached
    assert "Steady planes dX1..dX5" in unreached
    assert "Tactical diameter (180 deg)" not in unreached and "Peak roll phi" not in unreached
    assert turning_circle_figures(circle_traj(turns=2.2), length_m=70.2).unreached() == ["Steady planes dX1..dX5",
                                                                                        "Steady propeller n",
                                                                                        "Steady thrust (open water)",
                                                                                        "Steady torque"]


def test_unreached_leaves_out_what_no_order_asked_for():
    t = np.arange(0.0, 60.0, 0.1)
    traj = {"t_s": t, "z_m": np.full(t.size, -20.0), "U_m_s": np.full(t.size, 5.0), "psi_deg": 0.5 * t,
            "theta_deg": np.zeros(t.size), "phi_deg": np.zeros(t.size),
            **{c: np.full(t.size, 3.0) for c in metrics.PLANE_COLUMNS}}
    held = metrics.depth_heading_figures(traj, z_ref_m=-20.0, psi_ref_rad=math.radians(20.0))
    assert math.isnan(held.z_rise_time_s)           # no depth change ordered: no rise time, and none missed
    assert held.psi_rise_time_s == pytest.approx(36.0, abs=0.1)
    assert held.unreached() == []
    short = metrics.depth_heading_figures(traj, z_ref_m=-30.0, psi_ref_rad=math.radians(40.0))
    assert short.unreached() == ["Time to 90 % of the depth change", "Time to 90 % of the heading change"]
    no_order = metrics.depth_heading_figures(traj)
    assert no_order.unreached() == []


def test_synthetic_zigzag_from_angle_crossings():
    t = np.arange(0.0, 400.0, 0.1)
    psi = 30.0 * np.sin(2 * math.pi * t / 100.0)
    n = t.size
    traj = {"t_s": t, "psi_deg": psi, "theta_deg": np.zeros(n), "phi_deg": np.zeros(n),
            "U_m_s": np.full(n, 5.0), "u_m_s": np.full(n, -5.0), "z_m": np.full(n, -100.0),
            "q_deg_s": np.zeros(n), "r_deg_s": np.gradient(psi, t)}
    f = zigzag_figures(traj, "psi_deg", 20.0, 20.0)
    t1 = math.asin(2 / 3) * 100 / (2 * math.pi)
    assert f.reversal_times_s[:3] == pytest.approx([t1, 50 + t1, 100 + t1], abs=1e-3)
    assert np.degrees(f.overshoots_rad) == pytest.approx(np.full(len(f.overshoots_rad), 10.0), abs=1e-3)
    assert f.peak_times_s[0] == pytest.approx(25.0, abs=1e-3)
    assert f.periods_s == pytest.approx(np.full(len(f.periods_s), 100.0), abs=1e-3)


def test_bad_input_raises_one_clear_error():
    traj = circle_traj()
    with pytest.raises(TrajectoryError, match="psi_deg"):
        turning_circle_figures({k: v for k, v in traj.items() if k != "psi_deg"}, length_m=70.0)
    straight = dict(traj, psi_deg=np.zeros_like(traj["t_s"]))
    with pytest.raises(TrajectoryError, match="not a turning circle"):
        turning_circle_figures(straight, length_m=70.0)
    with pytest.raises(TrajectoryError, match="angle"):
        zigzag_figures(traj, "phi_deg", 20.0)
    with pytest.raises(TrajectoryError, match="unknown maneuver"):
        figures_for("barrel-roll", traj)
    with pytest.raises(TrajectoryError, match=r"unknown maneuver 'turnng-circle' \(did you mean 'turning-circle'\?\)"):
        figures_for("turnng-circle", traj)  # bb2-analyze --maneuver's typo: the likely name
    with pytest.raises(TrajectoryError, match="rows"):
        self_propulsion_figures(dict(traj, u_m_s=traj["u_m_s"][:5]))
    assert issubclass(TrajectoryError, ValueError)


def test_as_rows_converts_to_display_units():
    f = turning_circle_figures(circle_traj(), length_m=50.0)
    rows = {(label, unit): value for label, value, unit in f.as_rows()}
    assert rows[("Steady yaw rate r", "deg/s")] == pytest.approx(math.degrees(f.steady_yaw_rate_rad_s))
    assert rows[("Advance (90 deg) / L", "-")] == pytest.approx(f.advance_90_m / 50.0)
    assert rows[("Steady speed U", "kt")] == pytest.approx(5.0 / metrics.KNOT_M_S)
    assert f.to_dict()["steady_radius_m"] == f.steady_radius_m
    assert "Tactical diameter" in f.format()
