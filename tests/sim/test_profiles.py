"""The `corrected` physics profile: each fix is a named switch; the iowa profile is untouched by it."""
import math

import numpy as np
import pytest

from bb2_sim.actuators import ActuatorOutputs
from bb2_sim.added_mass import DerivativeMemory
from bb2_sim.maneuvers import build_model, maneuver_settings, run_maneuver
from bb2_sim.model import BB2Model
from bb2_sim.profiles import ProfileError, get_profile, switch_docs
from bb2_sim.propeller import propeller_load


@pytest.fixture(scope="module")
def iowa():
    return BB2Model()


@pytest.fixture(scope="module")
def corrected():
    return BB2Model(profile="corrected")


def _forces(model, x, planes=(0, 0, 0, 0, 0), rps=1.2, t=0.0):
    act = ActuatorOutputs(np.array(planes, float), rps, 0.0)
    return model.evaluate(t, np.asarray(x, float), act, DerivativeMemory()).forces


def test_profiles_and_switches_are_named_and_documented():
    assert not any(get_profile("iowa").switches().values())
    assert all(get_profile("corrected").switches().values())
    docs = switch_docs()
    assert set(docs) == set(get_profile("corrected").switches())
    assert all(d.startswith("Q") for d in docs.values())
    p = get_profile({"base": "iowa", "kpp_once": True})
    assert p.kpp_once and sum(p.switches().values()) == 1
    with pytest.raises(ProfileError, match="unknown profile switch"):
        get_profile({"base": "iowa", "warp_drive": True})
    with pytest.raises(ProfileError, match="unknown physics profile"):
        get_profile("matlab")


def test_each_switch_changes_only_what_it_fixes(iowa):
    """Ablation: turning one fix on changes the loads in a state where that quirk matters."""
    heeled_turn = [0, 0, -60, 0.2, 0.05, 0, -5.0, 0.4, 0.1, 0.02, 0.01, -0.03]
    base = _forces(iowa, heeled_turn)
    changed = {}
    for sw in ["euler_roll_inertia", "zuvw_b_abs_beta", "kpp_once", "thrust_deduction_wired",
               "static_forces_correct", "n_planes_clamped_depth"]:
        m = BB2Model(profile={"base": "iowa", sw: True})
        F = _forces(m, heeled_turn)
        ev = m.evaluate(0.0, np.asarray(heeled_turn, float), ActuatorOutputs(np.zeros(5), 1.2),
                        DerivativeMemory())
        changed[sw] = (F, ev.xdot)
    base_xdot = iowa.evaluate(0.0, np.asarray(heeled_turn, float), ActuatorOutputs(np.zeros(5), 1.2),
                              DerivativeMemory()).xdot
    # Q1 acts on the roll acceleration only (not on F)
    F, xd = changed["euler_roll_inertia"]
    assert np.array_equal(F, base) and xd[9] != base_xdot[9] and np.array_equal(xd[:9], base_xdot[:9])
    # Q7: K_pp counted once -> only K changes, by exactly one K_pp term
    F, _ = changed["kpp_once"]
    hc = iowa.params.hc
    kpp = iowa.params.rho * iowa.params.L ** 3 * hc["K_pp"] * 0.02 * abs(0.02)
    assert np.allclose(np.delete(F, 3), np.delete(base, 3)) and F[3] - base[3] == pytest.approx(-kpp, rel=1e-9)
    # Q10: with W = B the flipped Y signs cancel in calm water; Z gains the missing cos(phi) on the weight
    F, _ = changed["static_forces_correct"]
    W = iowa.Mb * iowa.params.g
    phi, theta = heeled_turn[3], heeled_turn[4]
    assert F[0] == base[0] and F[1] == pytest.approx(base[1], abs=1e-3)
    assert F[2] - base[2] == pytest.approx(W * math.cos(theta) * (1 - math.cos(phi)), rel=1e-9)
    # Q5 (signed beta in Z'uvw(b)): identical for starboard drift (beta > 0 here), different for port drift
    F, _ = changed["zuvw_b_abs_beta"]
    assert np.array_equal(F, base)
    port_drift = list(heeled_turn)
    port_drift[7] = -0.4
    m5 = BB2Model(profile={"base": "iowa", "zuvw_b_abs_beta": True})
    F5, F0 = _forces(m5, port_drift), _forces(iowa, port_drift)
    assert F5[2] != F0[2] and np.array_equal(np.delete(F5, 2), np.delete(F0, 2))
    # Q8: thrust deduction wired -> X changes (thrust) only
    F, _ = changed["thrust_deduction_wired"]
    assert F[0] != base[0] and np.array_equal(F[1:], base[1:])
    # Q20 matters only deeper than the clamp: at z = -60 it changes N
    F, _ = changed["n_planes_clamped_depth"]
    assert F[5] != base[5] and np.array_equal(F[:5], base[:5])


def test_thrust_deduction_varies_with_speed_and_depth_only_when_corrected(iowa):
    P, td = iowa.params, iowa.tables.thrust_deduction
    ts_iowa = {propeller_load(u, z, 1.2, P, td).t for u in (-5.14, -3.0, -1.6) for z in (-15, -18, -40)}
    assert len(ts_iowa) == 1 and ts_iowa.pop() == pytest.approx(P.thrust_deduction_const)  # Q8: constant
    fixed = {(u, z): propeller_load(u, z, 1.2, P, td, wired_correctly=True).t
             for u in (-5.14444, -3.086664, -1.543332) for z in (-14.0, -18.3724, -36.3724)}
    assert len(set(np.round(list(fixed.values()), 9))) >= 6
    assert fixed[(-5.14444, -36.3724)] == pytest.approx(0.245958)  # deep, 10 kt: the intended value


def test_free_surface_clipping_removes_suction_above_the_surface(iowa):
    m = BB2Model(profile={"base": "iowa", "free_surface_clipping": True})
    deep = [0, 0, -60, 0, 0, 0, -5, 0, 0, 0, 0, 0]
    assert np.allclose(_forces(m, deep), _forces(iowa, deep))  # fully submerged: identical
    broached = [0, 0, -2.0, 0, 0, 0, -5, 0, 0, 0, 0, 0]          # sail and deck above the surface
    h_iowa = iowa.hydro.loads(np.array([0, 0, -2.0]), np.eye(3), 0.0, iowa.wave, np.zeros(5))
    h_clip = m.hydro.loads(np.array([0, 0, -2.0]), np.eye(3), 0.0, m.wave, np.zeros(5), clip_emerged=True)
    W = iowa.Mb * iowa.params.g
    assert h_iowa[2] == pytest.approx(W, rel=1e-6)       # Q11: full buoyancy although emerged
    assert h_clip[2] < 0.97 * W                          # clipped: buoyancy lost with the emerged volume
    assert _forces(m, broached)[2] < _forces(iowa, broached)[2]


def test_wave_velocity_phase_fix():
    from bb2_sim.waves import orbital_velocity_earth, pressure, wave_for_sea_state
    from bb2_sim.parameters import load_parameters
    P = load_parameters()
    w = wave_for_sea_state(5, P)
    x = np.linspace(0, w.length, 100, endpoint=False)
    z = np.zeros_like(x)
    # elevation of the pressure field: p(z=0) = rho g eta
    eta = pressure(w, x, z, 3.0, P.rho, P.g) / (P.rho * P.g)
    v_fix = orbital_velocity_earth(w, x, z, 3.0, in_phase_with_pressure=True)
    v_iowa = orbital_velocity_earth(w, x, z, 3.0)
    # linear theory: the horizontal velocity is in phase with the elevation (u = omega eta)
    assert np.allclose(v_fix[:, 0], w.omega * eta, atol=1e-12)
    assert abs(np.corrcoef(v_iowa[:, 0], eta)[0, 1]) < 1e-6  # Q12: 90 deg out of phase


def test_port_turning_circle_diverges_in_iowa_and_not_in_corrected():
    s = maneuver_settings("turning-circle", rudder_deg=-20.0, duration=220.0)
    r_iowa = run_maneuver(s, build_model(s))
    assert not r_iowa.completed and "diverged" in str(r_iowa.error)  # REFERENCE.md 5: port TC diverges
    s_c = maneuver_settings("turning-circle", rudder_deg=-20.0, duration=220.0, profile="corrected")
    r = run_maneuver(s_c, build_model(s_c))
    assert r.completed
    theta = r.traj["theta_deg"]
    assert np.all(np.isfinite(theta)) and np.max(np.abs(theta)) < 25.0
    assert r.traj["r_deg_s"][-1] > 2.0  # a steady port turn (r > 0 = bow to port)


def test_starting_from_rest_needs_the_zero_speed_guard():
    s = maneuver_settings("self-propulsion", speed_mps=0.0, rps=1.2861, depth=50.0, duration=60.0)
    r_iowa = run_maneuver(s, build_model(s))
    assert not r_iowa.completed and r_iowa.error.t == 0.0   # Q13: singular at zero relative speed
    from bb2_sim.profiles import at_rest_hint  # said beside the error, only where it applies

    assert "it started at rest: the iowa profile is singular" in at_rest_hint("iowa", 0.0, r_iowa.error.t)
    assert at_rest_hint("corrected", 0.0, 0.0) == at_rest_hint("iowa", 2.0, 0.0) == at_rest_hint("iowa", 0.0, 3.5) == ""
    assert "the corrected-zero_speed_guard profile is singular" in at_rest_hint(
        {"base": "corrected", "zero_speed_guard": False}, 0.0, 0.0)  # an ablation of the guard
    s_c = maneuver_settings("self-propulsion", speed_mps=0.0, rps=1.2861, depth=50.0, duration=60.0,
                            profile="corrected")
    r = run_maneuver(s_c, build_model(s_c))
    assert r.completed
    assert r.traj["u_m_s"][-1] < -2.0                      # accelerating ahead
    assert abs(r.traj["z_m"][-1] + 50.0) < 2.0              # depth held


def test_iowa_untouched_by_building_a_corrected_model(iowa):
    x = [0, 0, -30, 0.1, 0.02, 0.3, -5, 0.2, 0.05, 0.01, 0.005, -0.02]
    before = _forces(iowa, x).copy()
    BB2Model(profile="corrected")
    assert np.array_equal(_forces(BB2Model(), x), before)


def test_speed_pi_feedforward_sign():
    """Q14: as implemented the speed PI's feed-forward is negative, n starts at the 0.01 rps floor and the boat
    slows down while the integrator winds up; corrected, n starts at U/4 and the speed is held. Both settle at
    the self-propulsion point n = 1.193 rps at 10 kt (SPEC 16)."""
    runs = {}
    for prof in ("iowa", "corrected"):
        s = maneuver_settings("self-propulsion", propeller="speed-pi", depth=60.0, duration=200.0, profile=prof)
        runs[prof] = run_maneuver(s, build_model(s)).traj
    iowa, corr = runs["iowa"], runs["corrected"]
    assert np.all(iowa["n_rps"][:20] == 0.01) and corr["n_rps"][1] > 1.2
    assert np.max(iowa["u_m_s"]) > -5.05 and np.max(corr["u_m_s"]) < -5.14
    for tr in (iowa, corr):
        assert tr["n_rps"][-1] == pytest.approx(1.193, abs=2e-3)
        assert tr["u_m_s"][-1] == pytest.approx(-5.1444, abs=1e-3)
