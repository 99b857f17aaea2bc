"""Unit tests of the ROM's parts: lookup semantics, pressure integration, actuators, derivative block, published
sanity figures (SPEC 16), frames."""
import math

import numpy as np
import pytest

from bb2_sim import frames
from bb2_sim.actuators import Actuators
from bb2_sim.added_mass import DerivativeMemory
from bb2_sim.model import BB2Model
from bb2_sim.parameters import load_parameters
from bb2_sim.tables import LookupTable, load_tables
from bb2_sim.waves import SeaStateError, Wave, wave_for_sea_state


def _reference_lookup(bps, values, clamps, *x):
    """Independent multilinear lookup (corner weights), SPEC 4."""
    vals = np.asarray(values, float)
    idx, frac = [], []
    for xi, b, c in zip(x, bps, clamps):
        if c is not None:
            xi = min(max(xi, c[0]), c[1])
        b = np.asarray(b, float)
        i = 0 if xi <= b[0] else (len(b) - 2 if xi >= b[-1] else int(np.searchsorted(b, xi, side="right") - 1))
        idx.append(i)
        frac.append((xi - b[i]) / (b[i + 1] - b[i]))
    out = 0.0
    for corner in range(2 ** len(x)):
        w, ii = 1.0, []
        for d in range(len(x)):
            bit = (corner >> d) & 1
            w *= frac[d] if bit else 1 - frac[d]
            ii.append(idx[d] + bit)
        out += w * vals[tuple(ii)]
    return out


def test_every_table_matches_an_independent_lookup_inside_outside_and_on_breakpoints():
    T = load_tables()
    rng = np.random.default_rng(1)
    tables = list(T.hull.values()) + [t for lst in T.planes.values() for t in lst] + [T.thrust_deduction]
    assert len(tables) == 14 + 27 + 1
    for t in tables:
        for _ in range(40):
            x = []
            for b in t.breakpoints:
                lo, hi = b[0], b[-1]
                span = hi - lo
                choice = rng.integers(3)
                x.append(float(rng.choice(b)) if choice == 0 else float(rng.uniform(lo - span, hi + span)))
            want = t.gain * _reference_lookup(t.breakpoints, t.values, t.clamps, *x)
            assert t(*x) == pytest.approx(want, rel=1e-12, abs=1e-18), t.name


def test_linear_extrapolation_and_clamp_semantics():
    t = LookupTable.from_dict("t", {"axes": [{"name": "a", "breakpoints": [0, 1, 3], "clamp": None},
                                            {"name": "b", "breakpoints": [0, 10], "clamp": [0, 5]}],
                                   "values": [[0, 10], [1, 11], [5, 15]]})
    assert t(2.0, 0.0) == pytest.approx(3.0)      # inside
    assert t(-1.0, 0.0) == pytest.approx(-1.0)    # extrapolated from the first segment
    assert t(5.0, 0.0) == pytest.approx(9.0)      # extrapolated from the last segment
    assert t(1.0, 100.0) == pytest.approx(6.0)    # input clamped to 5 first
    with pytest.raises(ValueError, match="shape"):
        LookupTable.from_dict("bad", {"axes": [{"name": "a", "breakpoints": [0, 1]}], "values": [1, 2, 3]})


def test_tables_on_one_axis_share_its_segment_search_and_its_last_answer_is_exact():
    """Tables with the same breakpoints and clamp share one axis function that remembers its last input object:
    the same float passed again gets the same answer, another float (equal or not) a fresh search; a table's
    value never depends on what another table on its axis was asked before (the hull tables on the speed axis
    asked in an interleaved order equal each asked alone, bit for bit)."""
    a = LookupTable.from_dict("a", {"axes": [{"name": "u", "breakpoints": [0, 1, 3], "clamp": [0, 2.5]}],
                                    "values": [0, 10, 30]})
    b = LookupTable.from_dict("b", {"axes": [{"name": "u", "breakpoints": [0.0, 1.0, 3.0], "clamp": [0, 2.5]}],
                                    "values": [5, 6, 9]})
    from bb2_sim.tables import _axis_fn
    assert _axis_fn([0, 1, 3], [0, 2.5]) is _axis_fn([0.0, 1.0, 3.0], (0.0, 2.5))
    assert _axis_fn([0, 1, 3], None) is not _axis_fn([0, 1, 3], [0, 2.5])
    x = 2.9                                            # clamped to 2.5
    assert a(x) == pytest.approx(25.0) and b(x) == pytest.approx(6 + 0.75 * 3)
    assert a(-1.0) == 0.0 and a(x) == pytest.approx(25.0) and a(0.5) == pytest.approx(5.0)
    T = load_tables()
    rng = np.random.default_rng(7)
    tabs = [t for t in T.hull.values() if len(t.breakpoints) == 2]
    inputs = [tuple(float(v) for v in rng.uniform(-1.0, 1.0, 2) * 12) for _ in range(50)]
    alone = [[t(*xs) for xs in inputs] for t in tabs]
    for k, xs in enumerate(inputs):                    # interleaved: every table on the same input objects
        for j, t in enumerate(tabs):
            assert t(*xs) == alone[j][k], t.name


@pytest.fixture(scope="module")
def model():
    return BB2Model()


@pytest.mark.parametrize("att", [(0, 0, 0), (0.3, 0, 0), (0, 0.2, 1.0), (-0.4, 0.3, -2.0)])
def test_calm_water_pressure_integral_is_exact_buoyancy_at_the_centroid(model, att):
    R = frames.rotation_native(*att)
    F = model.hydro.loads(np.array([10.0, -5.0, -40.0]), R, 0.0, Wave(), np.zeros(5))
    B = model.params.rho * model.params.g * model.volume
    assert F[0:3] == pytest.approx(R.T @ np.array([0, 0, B]), rel=1e-9, abs=1e-3 * B * 1e-6)
    c = model.surfaces.centroid()
    assert F[3:6] == pytest.approx(np.cross(c, F[0:3]), rel=1e-6, abs=B * 1e-7)


def test_deflected_planes_keep_the_buoyancy_and_move_its_moment(model):
    R = np.eye(3)
    F0 = model.hydro.loads(np.array([0, 0, -40.0]), R, 0.0, Wave(), np.zeros(5))
    F1 = model.hydro.loads(np.array([0, 0, -40.0]), R, 0.0, Wave(), np.array([30.0, -30, 30, -30, 30]))
    assert F1[2] == pytest.approx(F0[2], rel=1e-9)       # volume conserved by a rigid rotation
    assert not np.allclose(F1[3:], F0[3:])                # but the centroid moves


def test_wave_pressure_loads_oscillate_with_the_encounter(model):
    w = model.wave.__class__(**{**wave_for_sea_state(5, model.params).__dict__})
    loads = [model.hydro.loads(np.array([0, 0, -20.0]), np.eye(3), t, w, np.zeros(5))[2]
             for t in np.linspace(0, w.period, 24, endpoint=False)]
    B = model.params.rho * model.params.g * model.volume
    assert np.mean(loads) == pytest.approx(B, rel=1e-3)
    assert np.ptp(loads) > 1e4                           # Froude-Krylov heave force in sea state 5


def test_sea_state_table_and_errors():
    P = load_parameters()
    assert wave_for_sea_state(0, P).calm and wave_for_sea_state(1, P).calm
    w5 = wave_for_sea_state(5, P)
    assert w5.amplitude == 1.625 and w5.length == pytest.approx(140.9) and w5.period == pytest.approx(9.4997, 1e-4)
    for bad in (8, -1, 2.5, float("nan"), float("inf")):
        with pytest.raises(SeaStateError):
            wave_for_sea_state(bad, P)
    assert wave_for_sea_state(8, P, strict=False).calm  # the model's own rule: not in the table = calm


def test_actuator_rate_limit_saturation_and_memory():
    a = Actuators(load_parameters())
    out = a.step([40, -40, 0, 0, 0], 5.0, 1e6)
    assert out.planes_deg[0] == pytest.approx(7.11 * 0.05) and out.rps == pytest.approx(14.65 * 0.05)
    assert out.dmass_kg == pytest.approx(5.0)
    for _ in range(200):
        out = a.step([40, -40, 0, 0, 0], 0.0, 0.0)
    assert out.planes_deg[0] == 30.0 and out.planes_deg[1] == -30.0   # saturated
    assert a.memory[0] == pytest.approx(40.0)                          # the limiter keeps the unsaturated value
    assert out.rps == 0.01                                              # propeller floor


def test_derivative_block_semantics():
    d = DerivativeMemory()
    assert np.all(d.derivative(0.0, np.ones(3)) == 0)          # no earlier sample
    d.store(0.0, np.zeros(3))
    assert d.derivative(0.025, np.ones(3)) == pytest.approx(np.full(3, 40.0))
    d.store(0.05, np.ones(3))
    # at the major time t = 0.05 the most recent sample strictly before it is t = 0
    assert d.derivative(0.05, np.ones(3) * 2) == pytest.approx(np.full(3, 40.0))
    assert d.derivative(0.075, np.ones(3) * 2) == pytest.approx(np.full(3, 40.0))


def test_published_sanity_figures(model):
    """SPEC 16: straight-ahead resistance 64.9 kN at 10 kt (deep, zero planes); T = R at n = 1.193 rps, J = 0.862."""
    from bb2_sim.actuators import ActuatorOutputs
    from bb2_sim.propeller import propeller_load
    u = -5.14444
    x = np.array([0, 0, -100.0, 0, 0, 0, u, 0, 0, 0, 0, 0])
    ev = model.evaluate(0.0, x, ActuatorOutputs(np.zeros(5), 1.193), DerivativeMemory())
    resistance = ev.forces[0] + ev.prop.thrust          # X without the thrust: drag (positive aft)
    assert resistance == pytest.approx(64.9e3, rel=2e-3)
    n = 1.193
    assert propeller_load(u, -100, n, model.params, model.tables.thrust_deduction).thrust == \
        pytest.approx(resistance, rel=5e-3)
    assert ev.prop.J == pytest.approx(0.862, abs=1e-3)


@pytest.mark.parametrize("seed", range(5))
def test_frame_conversions_round_trip(seed):
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(4, 3))
    assert np.allclose(frames.body_flu_to_native(frames.body_native_to_flu(v)), v, atol=0)
    assert np.allclose(frames.earth_enu_to_native(frames.earth_native_to_enu(v)), v, atol=0)
    assert np.allclose(frames.ned_to_enu(frames.enu_to_ned(v)), v, atol=0)
    assert np.allclose(frames.frd_to_flu(frames.flu_to_frd(v)), v, atol=0)
    phi, theta, psi = rng.uniform(-1, 1), rng.uniform(-1.2, 1.2), rng.uniform(-3, 3)
    # ENU attitude: R_enu_flu maps FLU to ENU consistently with the vector conversions
    R = frames.rotation_native(phi, theta, psi)
    vb = rng.normal(size=3)
    assert frames.rotation_enu_flu(phi, theta, psi) @ frames.body_native_to_flu(vb) == \
        pytest.approx(frames.earth_native_to_enu(R @ vb))
    assert frames.euler_enu_to_native(*frames.euler_native_to_enu(phi, theta, psi)) == (phi, theta, psi)
    back = frames.euler_ned_to_native(*frames.euler_native_to_ned(phi, theta, psi))
    assert back == pytest.approx((phi, theta, psi), abs=1e-12)
    q = frames.quaternion_from_rotation(R)
    assert frames.rotation_from_quaternion(q) == pytest.approx(R, abs=1e-14)


@pytest.mark.parametrize("seed", range(20))
def test_closed_form_quaternion_equals_the_rotation_matrix_one(seed):
    """frames.quaternion_enu_flu (what the odometry and IMU carry) = scipy's quaternion of R_enu_flu,
    w >= 0, over the whole attitude range (incl. |psi| > pi/2 and w -> 0 where the sign flips)."""
    rng = np.random.default_rng(seed)
    phi, theta, psi = rng.uniform(-math.pi, math.pi), rng.uniform(-1.5, 1.5), rng.uniform(-math.pi, math.pi)
    if seed == 0:
        phi, theta, psi = 0.0, 0.0, math.pi  # w = 0 exactly: either sign is the same rotation
    q = np.array(frames.quaternion_enu_flu(phi, theta, psi))
    ref = frames.quaternion_from_rotation(frames.rotation_enu_flu(phi, theta, psi))
    assert np.linalg.norm(q) == pytest.approx(1.0, abs=1e-15)
    assert q[3] >= 0.0
    assert min(np.abs(q - ref).max(), np.abs(q + ref).max()) < 1e-15 * 8
    assert frames.rotation_from_quaternion(q) == pytest.approx(frames.rotation_enu_flu(phi, theta, psi), abs=1e-14)


def test_frame_conventions_match_the_paper():
    # psi = 0: the bow points along -x native = +x ENU = east; NED heading 90 deg
    R = frames.rotation_native(0, 0, 0)
    bow_native = R @ np.array([-1.0, 0, 0])
    assert frames.earth_native_to_enu(bow_native) == pytest.approx([1, 0, 0])
    assert frames.euler_native_to_ned(0, 0, 0)[2] == pytest.approx(math.pi / 2)
    # theta > 0 bow up: NED pitch > 0; phi > 0 starboard up: NED roll < 0 (starboard down positive)
    r, p, _ = frames.euler_native_to_ned(0.1, 0.2, 0.0)
    assert p == pytest.approx(0.2) and r == pytest.approx(-0.1)


def test_phase_sine_equals_numpy_sine_to_round_off():
    """waves.PhaseSine (table + short series, used for the wave pressure) against np.sin, over wave phases far
    beyond 2 pi and near the zeros, where a relative error would show."""
    from bb2_sim.waves import PhaseSine

    ps = PhaseSine()
    rng = np.random.default_rng(3)
    x = np.concatenate([rng.uniform(-2000.0, 2000.0, 200_000), rng.normal(0, 1e-6, 1000),
                        np.pi * np.arange(-50, 50) + rng.normal(0, 1e-9, 100)])
    tau = x / ps.turn
    got = ps(tau.copy())
    want = np.sin(tau * ps.turn)
    # equal up to one rounding of the angle itself (|x| * 2^-52), i.e. as exact as np.sin of a computed phase
    assert np.all(np.abs(got - want) <= 1e-15 + np.abs(x) * 2.3e-16)
    assert np.max(np.abs(got - want)[np.abs(x) < 8]) <= 1e-15
