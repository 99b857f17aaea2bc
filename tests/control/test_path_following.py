"""3-D SO(3) path-following law (SPEC 3.1/3.2) and the LOS law (SPEC 3.3)."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from bb2_control.config import load_data
from bb2_control.errors import ControlConfigError, NonFiniteInputError
from bb2_control.los import LineOfSightDepth, LOSGains, wrap_to_pi
from bb2_control.path_following import (
    PI_R,
    PFGains,
    PathFollowing3D,
    attitude_error,
    desired_frame,
    flow_frame,
    flow_to_body_rates,
    path_frame,
    prepare_steps,
    vee,
)
from bb2_sim import frames

planner = pytest.importorskip("bb2_planner.paths", reason="bb2_planner is needed for the paths")


@pytest.fixture(scope="module")
def circle_native():
    return planner.load_path("circle_r400", frame="native")


def _offset_start(path, outward_m: float, down_m: float) -> np.ndarray:
    p0 = np.asarray(path(path.t0))
    radial = np.array([p0[0], p0[1], 0.0]) / math.hypot(p0[0], p0[1])   # circle centred on the z axis
    return p0 + outward_m * radial - np.array([0.0, 0.0, down_m])


def test_sign_point_vehicle_converges_to_circle(circle_native):
    """SPEC 3.1 'expected behaviour': a point vehicle at 4.7 m/s tracking the body-rate commands perfectly,
    started 50 m off the 400 m circle (40 m outside, 30 m below), ends within 0.3 m of the path.

    The vehicle is integrated in the ROM's native frames (Euler angles, x-aft body) so the FLU/flow-frame
    conversions and the q_up/r_left signs are part of the check.
    """
    path = circle_native
    pf = PathFollowing3D(path, PFGains.from_config())
    V, Ts, sub = 4.7, pf.gains.Ts, 2
    p = _offset_start(path, 40.0, 30.0)
    t1 = path.tangent(0.0)
    euler = np.array([0.0, 0.0, math.atan2(t1[1], t1[0]) + math.pi])   # bow (-x native) along the tangent
    v_native = np.array([-V, 0.0, 0.0])
    errs, t = [], 0.0
    while not pf.finished and t < 700.0:
        R_NI = frames.rotation_native(*euler)
        out = pf.step(p, R_NI @ frames.D_FLIP, frames.body_native_to_flu(v_native))
        q_up, r_left = flow_to_body_rates(out.q_c, out.r_c, frames.body_native_to_flu(v_native))
        w_native = np.array([0.0, q_up, r_left])
        for _ in range(sub):
            R_NI = frames.rotation_native(*euler)
            p = p + Ts / sub * (R_NI @ v_native)
            euler = euler + Ts / sub * (frames.euler_rate_matrix(euler[0], euler[1]) @ w_native)
        errs.append(float(np.linalg.norm(out.p_T)))
        t += Ts
    errs = np.array(errs)
    assert errs[0] == pytest.approx(50.0, rel=1e-9)
    assert pf.finished and 450.0 < t < 560.0           # gamma reached Tf = 500 s near t = 500 s
    assert errs[-int(50 / Ts):].max() < 0.3             # last 50 s within 0.3 m
    assert errs[int(100 / Ts)] < 0.6 * errs[0]          # converging, not merely bounded


def test_compact_attitude_error_equals_paper_formula():
    rng = np.random.default_rng(7)
    Pi = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    M = np.eye(3) - Pi.T @ Pi
    for R in Rotation.random(20, random_state=rng).as_matrix():
        S = M @ R - R.T @ M
        vee = np.array([S[2, 1], S[0, 2], S[1, 0]])
        paper = 0.5 * Pi @ vee
        Psi, e = attitude_error(R)
        np.testing.assert_allclose(e, paper, atol=1e-15)
        assert Psi == pytest.approx(0.5 * (1 - R[0, 0]))


def test_flow_frame_and_body_rate_conversion():
    R = flow_frame(np.array([5.0, 0.0, 0.0]))
    np.testing.assert_allclose(R, np.eye(3), atol=1e-15)
    assert flow_to_body_rates(0.01, 0.02, np.array([5.0, 0.0, 0.0])) == pytest.approx((-0.01, 0.02))
    v = np.array([5.0, 0.3, -0.4])                 # sideslip to port, descending
    R = flow_frame(v)
    np.testing.assert_allclose(R[:, 0], v / np.linalg.norm(v), atol=1e-15)
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-14)
    assert np.linalg.det(R) == pytest.approx(1.0)
    assert R[2, 1] == 0.0 and R[1, 1] > 0          # w2 horizontal in body, to port
    w_b = R @ np.array([0.0, 0.01, 0.02])
    assert flow_to_body_rates(0.01, 0.02, v) == pytest.approx((-w_b[1], w_b[2]))


def _matrix_form_tick(law: PathFollowing3D, p, R_BI, v, prev):
    """The law's tick written with the frame functions and matrix products (the paper's form, with the angles of
    the flow frame): (q_c, r_c, gamma_dot, p_T, R_TI, R_DT)."""
    g = law.gains
    gam = min(max(law.gamma, law.path.t0), law.path.tf)
    p_d, dp = law.path(gam), law.path.velocity(gam)
    R_TI = path_frame(dp)
    R_WI = R_BI @ flow_frame(v)
    gamma_dot = max(g.gamma_dot_min, float((np.linalg.norm(v) * R_WI[:, 0] + g.k_gamma * (p - p_d)) @ R_TI[:, 0])
                    / np.linalg.norm(dp))
    p_T = R_TI.T @ (p - p_d)
    R_DT = desired_frame(p_T[1], p_T[2], g.d)
    R_tilde = R_DT.T @ R_TI.T @ R_WI
    _, e_R = attitude_error(R_tilde)
    pT, pD = prev if prev is not None else (R_TI, R_DT)
    w_T, w_D = vee(R_TI.T @ (R_TI - pT) / g.Ts), vee(R_DT.T @ (R_DT - pD) / g.Ts)
    w_c = PI_R @ R_tilde.T @ (R_DT.T @ w_T + w_D) - 2.0 * g.k_R * e_R
    return w_c[0], w_c[1], gamma_dot, p_T, R_TI, R_DT


def _drifting_inputs(path, rng, gam):
    """A vehicle near the path at gam: offset up to 30 m, heading and flow angles of a few degrees."""
    t1 = path.tangent(gam)
    R = Rotation.from_euler("zyx", [math.atan2(t1[1], t1[0]) + rng.normal(0, 0.2), rng.normal(0, 0.1),
                                    rng.normal(0, 0.05)]).as_matrix()
    p = np.asarray(path(gam)) + rng.normal(0, 10.0, 3)
    v = np.array([rng.uniform(2.0, 6.0), rng.normal(0, 0.3), rng.normal(0, 0.3)])
    return p, R, v


def test_the_tick_in_components_is_the_matrix_form_of_the_law():
    """step() computes on components (no atan2: the flow frame from the velocity's ratios); over random states
    near three paths it gives the matrix form's commands to round-off, first tick and later ones."""
    rng = np.random.default_rng(11)
    for name in ("circle_r400", "synthetic_canyon", "straight_line_x4000"):
        path = planner.load_path(name, frame="native")
        law = PathFollowing3D(path, PFGains(**{**PFGains.from_config().__dict__, "d": rng.uniform(150, 350)}))
        prev = None
        for _ in range(60):
            p, R, v = _drifting_inputs(path, rng, law.gamma + 3.0)
            q, r, gdot, p_T, R_TI, R_DT = _matrix_form_tick(law, p, R, v, prev)
            out = law.step(p, R, v)
            assert out.q_c == pytest.approx(q, rel=1e-9, abs=1e-13) and out.r_c == pytest.approx(r, rel=1e-9, abs=1e-13)
            assert out.gamma_dot == pytest.approx(gdot, rel=1e-12)
            np.testing.assert_allclose(out.p_T, p_T, rtol=0, atol=1e-9)
            prev = (R_TI, R_DT)


def _fields(out):
    return (out.q_c, out.r_c, out.gamma, out.gamma_dot, out.Psi, out.finished, out.p_d.tolist(), out.p_T.tolist(),
            out.e_R.tolist())


def test_laws_prepared_together_give_each_its_own_tick_bit_for_bit():
    """prepare_steps over laws of three paths (two degrees), four look-aheads, one law reset mid-run (its first
    tick among others' later ones), an analytic one and a non-finite input (both left alone), and one stepped with
    other inputs than prepared: every tick equals its twin's stepped alone, to the last bit."""
    rng = np.random.default_rng(5)
    paths = [planner.load_path(n, frame="native") for n in ("circle_r400", "synthetic_canyon", "synthetic_canyon",
                                                           "straight_line_x4000", "circle_r400", "synthetic_canyon")]
    base = PFGains.from_config().__dict__
    gains = [PFGains(**{**base, "d": d}) for d in (200.0, 250.0, 300.0, 275.0, 250.0)]
    gains.append(PFGains(**{**base, "frame_rates": "analytic"}))
    together = [PathFollowing3D(pa, g) for pa, g in zip(paths, gains)]
    alone = [PathFollowing3D(pa, g) for pa, g in zip(paths, gains)]
    for k in range(80):
        ins = [_drifting_inputs(law.path, rng, law.gamma + 2.0) for law in alone]
        if k == 30:
            together[2].reset()
            alone[2].reset()
        if k == 40:
            ins[1] = (np.array([np.nan, 0.0, 0.0]), ins[1][1], ins[1][2])
        ok = prepare_steps(together, np.array([i[0] for i in ins]), np.array([i[1] for i in ins]),
                           np.array([i[2] for i in ins]))
        assert ok.tolist() == [True, k != 40, True, True, True, False], k
        if k == 50:                      # stepped with other inputs than it was prepared for: computed alone
            ins[3] = (ins[3][0] + 1.0, ins[3][1], ins[3][2])
        for law_t, law_a, (p, R, v) in zip(together, alone, ins):
            if k == 40 and law_a is alone[1]:
                for law in (law_t, law_a):
                    with pytest.raises(NonFiniteInputError):
                        law.step(p, R, v)
                continue
            assert _fields(law_t.step(p, R, v)) == _fields(law_a.step(p, R, v)), k
            assert law_t.gamma == law_a.gamma


def test_analytic_frame_rates_match_finite_differences(circle_native):
    gains = PFGains.from_config()
    fd = PathFollowing3D(circle_native, gains)
    an = PathFollowing3D(circle_native, PFGains(**{**gains.__dict__, "frame_rates": "analytic"}))
    p = _offset_start(circle_native, 5.0, 2.0)
    t1 = circle_native.tangent(0.0)
    R = np.column_stack([t1, [-t1[1], t1[0], 0.0], [0.0, 0.0, 1.0]])
    v = np.array([4.7, 0.0, 0.0])
    for k in range(40):
        a, b = fd.step(p, R, v), an.step(p, R, v)
        p = p + 0.05 * 4.7 * R[:, 0]
        if k >= 2:   # first tick of the FD version has zero frame rates by construction
            assert a.r_c == pytest.approx(b.r_c, rel=2e-2, abs=2e-5)
            assert a.q_c == pytest.approx(b.q_c, abs=2e-5)
    assert abs(b.r_c) > 5e-3                           # the path turns: the feed-forward is not trivial


def test_gamma_dot_floor_and_non_finite_input(circle_native):
    pf = PathFollowing3D(circle_native)
    p0 = circle_native(0.0)
    t1 = circle_native.tangent(0.0)
    R_back = np.column_stack([-t1, [t1[1], -t1[0], 0.0], [0.0, 0.0, 1.0]])   # facing backwards
    out = pf.step(p0, R_back, np.array([4.0, 0.0, 0.0]))
    assert out.gamma_dot == pytest.approx(pf.gains.gamma_dot_min)
    g = pf.gamma
    with pytest.raises(NonFiniteInputError):
        pf.step(np.array([np.nan, 0.0, 0.0]), R_back, np.array([4.0, 0.0, 0.0]))
    assert pf.gamma == g
    pf.reset()
    assert pf.gamma == circle_native.t0


def test_bad_gains_raise():
    with pytest.raises(ControlConfigError, match="d must be positive"):
        PFGains(d=0.0)
    with pytest.raises(ControlConfigError, match="frame_rates"):
        PFGains(frame_rates="exact")
    with pytest.raises(ValueError, match="k_gamma"):
        LOSGains(k_gamma=-1.0)


def test_guidance_gains_carried_from_shared(shared):
    src = json.loads(shared("bb2_control", "params.json").read_text())["path_following"]
    own = load_data("guidance")
    a, b = src["paper_3d_rates"], own["pf_3d_so3_2022"]
    assert (b["k_gamma_per_s"], b["k_R_per_s"], b["d_m"], b["gamma_dot_min"]) == (
        a["k_gamma"], a["k_R"], a["d_m"], a["gamma_dot_min"])
    a, b = src["los2d_depth_2023"], own["los_2d_depth_2023"]
    assert (b["k_gamma_per_s"], b["d_m"]) == (a["k_gamma"], a["d_m"])


# ------------------------------------------------------------------------------------------ LOS
def test_los_heading_sign_and_unwrap():
    path = planner.load_path("straight_line_x4000", frame="native")
    los = LineOfSightDepth(path)
    p0 = np.asarray(path(0.0))
    chi = math.atan2(*np.asarray(path.velocity(0.0))[[1, 0]])
    left = p0 + 20.0 * np.array([-math.sin(chi), math.cos(chi), 0.0])
    out = los.step(left, chi, 5.0)
    assert out.y_T == pytest.approx(20.0)
    assert out.psi_d == pytest.approx(chi - math.atan2(20.0, 50.0))    # left of the path -> steer right
    los.reset()
    out = los.step(left, chi + 4 * math.pi, 5.0)                       # continuous heading, two turns later
    assert abs(out.psi_d - (chi + 4 * math.pi)) < math.pi
    assert wrap_to_pi(out.psi_d) == pytest.approx(wrap_to_pi(chi - math.atan2(20.0, 50.0)))


def test_los_kinematic_convergence(circle_native):
    """Heading follows psi_d with a 5 s lag: the cross-track error decays from 50 m to the lag-induced bias.

    With a first-order heading lag tau on a circle of radius R, the steady heading deficit is tau V / R, which
    LOS turns into a cross-track bias y_T = -d tan(tau V / R) (outside the circle).
    """
    los = LineOfSightDepth(circle_native)
    p = _offset_start(circle_native, 50.0, 0.0)
    t1 = circle_native.tangent(0.0)
    psi = math.atan2(t1[1], t1[0])
    V, Ts = 4.7, 0.05
    ys = []
    for _ in range(int(250 / Ts)):
        out = los.step(p, psi, V)
        psi += Ts * (out.psi_d - psi) / 5.0
        p = p + Ts * V * np.array([math.cos(psi), math.sin(psi), 0.0])
        ys.append(out.y_T)
    assert ys[0] == pytest.approx(-50.0, rel=1e-3)                   # outside the CCW circle = right of it
    assert ys[-1] == pytest.approx(-50.0 * math.tan(5.0 * V / 400.0), rel=0.15)


def test_rejoin_sets_the_virtual_time_to_the_closest_path_point(circle_native):
    """A law restarted mid-run (issue 10, point 3) starts at the path point closest to the vehicle, not at gamma0:
    a vehicle 3 m outside the path at t = 120 s rejoins at gamma = 120 s, 3 m away; the law then steps from there."""
    path = circle_native
    pf = PathFollowing3D(path, PFGains.from_config())
    t_true = path.t0 + 120.0
    p0 = np.asarray(path(t_true))
    radial = np.array([p0[0], p0[1], 0.0]) / math.hypot(p0[0], p0[1])
    gamma, dist = pf.rejoin(p0 + 3.0 * radial)
    assert gamma == pytest.approx(t_true, abs=0.05) and dist == pytest.approx(3.0, abs=0.01)  # a Bernstein "circle"
    assert pf.gamma == gamma
    pf.reset()
    assert pf.gamma == path.t0 + pf.gains.gamma0
