"""The batch ROM (bb2_sim.batch) equals N single Simulator runs on every state at every step.

Tolerance: 1e-12 relative to each state component's magnitude over the run (floor 1: absolute 1e-12 m, rad,
m/s, rad/s for the small components). The default batch folds the small plane blocks of the pressure integral
(1-ulp differences of ~1e5 N terms), and the ROM amplifies ulp-level noise: a single run whose state is perturbed
by 1 ulp per step drifts ~1e-12 from itself within 300 steps. So the default batch keeps the large terms bit for
bit (the buoyancy block; boats in a sea run the scalar wave code) and the comparisons run 200-300 steps (10-15 s).
``exact=True`` follows the scalar kernels everywhere, the C library's sin/cos/atan/acos included where the scalar
code calls math (numpy's AVX-512 kernels differ from it in the last bit: acos for 1 argument in 10 here): bit for
bit equal on every machine.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from bb2_sim.batch import BatchModel, BatchSimulator
from bb2_sim.batch.maneuvers import batch_for_maneuvers
from bb2_sim.integrator import Simulator
from bb2_sim.maneuvers import ManeuverCommander, maneuver_settings
from bb2_sim.model import BB2Model
from bb2_sim.waves import Wave, wave_for_sea_state

TOL = 1e-12


@pytest.fixture(scope="module")
def calm_model():
    return BB2Model()


def _single(model: BB2Model, sea_state, profile: str = "iowa") -> BB2Model:
    """A single-boat model on the same hull surfaces (no second mesh load)."""
    return BB2Model(model.surfaces, profile=profile, sea_state=sea_state)


def _assert_close(batch: np.ndarray, single: np.ndarray) -> float:
    """batch, single: (steps, N, 12). Returns the largest error relative to the component scales."""
    scale = np.maximum(1.0, np.abs(single).max(axis=(0, 1)))
    err = np.abs(batch - single) / scale
    worst = float(err.max())
    step, boat, comp = np.unravel_index(int(err.argmax()), err.shape)
    assert worst <= TOL, f"boat {boat}, state {comp}, step {step}: error {worst:.3g} > {TOL:g}"
    return worst


def _assert_exact(batch: np.ndarray, single: np.ndarray) -> None:
    """The exact mode: bit for bit (and so within the tolerance)."""
    _assert_close(batch, single)
    assert np.array_equal(batch, single), f"{int((batch != single).sum())} states differ in exact mode"


# ------------------------------------------------------------------------------------------------ (a) open loop
SEA_STATES = [0, 3, 4, 5, 0, 5]
HEADINGS_DEG = [0.0, 90.0, 180.0, 45.0, 30.0, 270.0]
DEPTHS = [-100.0, -30.0, -40.0, -25.0, -60.0, -20.0]
SPEEDS = [5.1444, 4.0, 3.0, 5.5, 2.5, 4.5]
PLANES = np.array([[0, 0, 0, 0, 0], [3, -2, 1, 4, -5], [-5, 5, -5, 5, 2], [10, 10, -10, -10, 0],
                   [1, 2, 3, 4, 5], [-3, 0, 3, 0, -3]], dtype=float)
RPS = np.array([1.2861, 1.0, 0.8, 1.4, 0.6, 1.1])


def _mixed_x0() -> np.ndarray:
    x0 = np.zeros((6, 12))
    x0[:, 2] = DEPTHS
    x0[:, 5] = np.radians(HEADINGS_DEG)
    x0[:, 6] = [-s for s in SPEEDS]
    return x0


def test_mixed_open_loop_batch_equals_single_runs(calm_model):
    assert all(not wave_for_sea_state(s, calm_model.params).calm for s in (3, 4, 5))
    x0 = _mixed_x0()
    batch = BatchSimulator(BatchModel.from_sea_states(calm_model, SEA_STATES), x0)
    exact = BatchSimulator(BatchModel.from_sea_states(calm_model, SEA_STATES, exact=True), x0)
    singles = [Simulator(_single(calm_model, s), x0[i]) for i, s in enumerate(SEA_STATES)]
    n = 300
    xb, xe, xs = np.empty((n, 6, 12)), np.empty((n, 6, 12)), np.empty((n, 6, 12))
    ballast = np.array([0.0, 0.0, 500.0, 0.0, -300.0, 0.0])
    for k in range(n):
        rec = batch.step(PLANES, RPS, ballast)
        exact.step(PLANES, RPS, ballast)
        assert rec.t == singles[0].t
        for i, s in enumerate(singles):
            r1 = s.step(PLANES[i], RPS[i], ballast[i])
            np.testing.assert_array_equal(rec.act.planes_deg[i], r1.act.planes_deg)
            if k in (0, n - 1):   # the loads of the major evaluation: to round-off of the 4e7 N pressure terms
                scale = np.abs(r1.ev.hydrostatic).max()
                np.testing.assert_allclose(rec.ev.forces[i], r1.ev.forces, rtol=0, atol=1e-12 * scale)
                np.testing.assert_allclose(rec.ev.hydrostatic[i], r1.ev.hydrostatic, rtol=0, atol=1e-12 * scale)
                assert rec.ev.prop.thrust[i] == pytest.approx(r1.ev.prop.thrust, rel=1e-12)
        xb[k], xe[k] = batch.x, exact.x
        xs[k] = [s.x for s in singles]
    assert not batch.diverged.any()
    _assert_close(xb, xs)
    _assert_exact(xe, xs)


def test_boats_in_spectrum_seas_and_currents_equal_single_runs(calm_model):
    """Each boat its own sea and current (``seas=``, ``currents=``): short-crested and long-crested spectrum seas
    (two boats sharing one), currents with and without a sea, the authors' regular sea with a current, calm water,
    near the surface where the waves act. Bit for bit the single runs in the exact mode (the boats' flow and
    pressure integral are the scalar code's, boat by boat), within the tolerance in the default mode."""
    from bb2_sim.current import Current
    from bb2_sim.sea import ComponentSea, Cos2sSpreading, JonswapSpectrum, PiersonMoskowitzSpectrum, discretise
    short = ComponentSea(discretise(JonswapSpectrum(3.25, 9.7, 3.3), 16, seed=5, spreading=Cos2sSpreading(np.pi / 2, 10.0),
                                    mean_direction_deg=90.0))
    long_ = ComponentSea(discretise(PiersonMoskowitzSpectrum(2.0), 8, seed=1))
    seas = [short, None, long_, None, short, None, None]
    currents = [None, Current(0.5, 45.0), Current(0.3, 0.0), None, None, Current(0.4, 200.0), None]
    states = [0, 0, 0, 5, 0, 3, 0]
    waves = [wave_for_sea_state(s, calm_model.params) for s in states]
    x0 = np.zeros((7, 12))
    x0[:, 2] = [-18.0, -30.0, -20.0, -22.0, -25.0, -19.0, -40.0]
    x0[:, 5] = np.radians([0.0, 90.0, 180.0, 45.0, 30.0, 270.0, 10.0])
    x0[:, 6] = [-4.0, -5.0, -3.0, -4.5, -2.5, -4.0, -5.1444]
    planes = np.vstack([PLANES, PLANES[1]])
    rps = np.append(RPS, 1.2861)
    singles = [Simulator(BB2Model(calm_model.surfaces, sea_state=states[i], sea=seas[i], current=currents[i]), x0[i])
               for i in range(7)]
    batch = BatchSimulator(BatchModel(calm_model, waves, seas=seas, currents=currents), x0)
    exact = BatchSimulator(BatchModel(calm_model, waves, seas=seas, currents=currents, exact=True), x0)
    n = 200
    xb, xe, xs = np.empty((n, 7, 12)), np.empty((n, 7, 12)), np.empty((n, 7, 12))
    for k in range(n):
        batch.step(planes, rps)
        exact.step(planes, rps)
        for s, p_, r in zip(singles, planes, rps):
            s.step(p_, r)
        xb[k], xe[k], xs[k] = batch.x, exact.x, [s.x for s in singles]
    _assert_close(xb, xs)
    _assert_exact(xe, xs)
    # the environment acts: each boat differs from the same boat in calm water
    calm = BatchSimulator(BatchModel(calm_model, n_boats=7, exact=True), x0)
    for _ in range(n):
        calm.step(planes, rps)
    moved = np.abs(exact.x - calm.x)[:, [0, 1, 2, 3, 4]].max(axis=1)
    assert (moved[[0, 1, 2, 3, 4, 5]] > 1e-3).all() and moved[6] == 0.0, moved


def test_boats_in_spectrum_seas_with_free_surface_clipping_take_the_scalar_code_boat_by_boat():
    """The corrected profile clips the emerged hull points, so a boat in a spectrum sea takes the scalar code's
    whole flow and pressure integral (not the grid's fused pass); near the surface, per-boat times: bit for bit."""
    from bb2_sim.current import Current
    from bb2_sim.sea import ComponentSea, JonswapSpectrum, discretise
    model = BB2Model(profile="corrected")
    sea = ComponentSea(discretise(JonswapSpectrum(3.0, 8.0, 3.3), 8, seed=2, mean_direction_deg=60.0))
    seas, currents = [sea, sea, None], [None, Current(0.5, 90.0), Current(0.3, 10.0)]
    x0 = np.zeros((3, 12))
    x0[:, 2] = [-12.0, -13.0, -15.0]
    x0[:, 6] = [-4.0, -3.0, -5.0]
    batch = BatchSimulator(BatchModel(model, seas=seas, currents=currents, exact=True), x0)
    singles = [Simulator(BB2Model(model.surfaces, profile="corrected", sea=seas[i], current=currents[i]), x0[i])
               for i in range(3)]
    for _ in range(40):
        batch.step(PLANES[:3], RPS[:3])
        for i, s in enumerate(singles):
            s.step(PLANES[i], RPS[i])
        assert np.array_equal(batch.x, np.array([s.x for s in singles]))
    assert abs(batch.x[0, 2] - batch.x[1, 2]) > 1e-3


def test_batch_evaluation_equals_single_evaluation_with_per_boat_times_and_profile():
    """One evaluation, the corrected profile (every switch: clipping, guards, ...), per-boat times."""
    model = BB2Model(profile="corrected")
    waves = [Wave(), wave_for_sea_state(5, model.params), wave_for_sea_state(3, model.params)]
    bm = BatchModel(model, waves)
    rng = np.random.default_rng(4)
    x = np.zeros((3, 12))
    x[:, 2] = [-12.0, -14.0, -30.0]          # near the surface: the clipping matters
    x[:, 3:6] = rng.normal(0.0, 0.1, (3, 3))
    x[:, 6:9] = [[-4.0, 0.2, 0.1], [-3.0, -0.1, 0.05], [-5.0, 0.0, -0.1]]
    x[:, 9:12] = rng.normal(0.0, 0.01, (3, 3))
    t = np.array([0.3, 1.7, 2.45])
    sim = BatchSimulator(bm, x)
    act = sim.actuators.step(rng.normal(0.0, 3.0, (3, 5)), np.array([1.0, 1.2, 0.9]), np.array([0.0, 100.0, 0.0]))
    x_before = x.copy()                      # the Derivative blocks' sample: an evaluation 0.05 s before
    x_before[:, 6:12] += rng.normal(0.0, 0.05, (3, 6))
    mem = bm.new_memory()
    mem.store(t - 0.05, bm.evaluate(t - 0.05, x_before, act, bm.new_memory()).added_mass_inputs)
    ev = bm.evaluate(t, x, act, mem)
    assert np.abs(ev.added_mass).max() > 1e3   # the added mass matters here
    from bb2_sim.actuators import ActuatorOutputs
    from bb2_sim.added_mass import DerivativeMemory
    for i, w in enumerate(waves):
        single = BB2Model(model.surfaces, profile="corrected")
        single.wave = w
        act1 = ActuatorOutputs(act.planes_deg[i], act.rps[i], act.dmass_kg[i])
        dm = DerivativeMemory()
        dm.store(t[i] - 0.05, single.evaluate(t[i] - 0.05, x_before[i], act1, DerivativeMemory()).urel_sections)
        e1 = single.evaluate(t[i], x[i], act1, dm)
        np.testing.assert_allclose(ev.added_mass[i], e1.added_mass, rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(ev.xdot[i], e1.xdot, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(ev.hydrostatic[i], e1.hydrostatic, rtol=1e-12, atol=1e-6)
        assert ev.alpha_deg[i] == pytest.approx(e1.alpha_deg, abs=1e-12)


def test_batch_lookups_equal_the_scalar_simulink_lookups_bit_for_bit(calm_model):
    """Every table (hull, planes stacked per group, thrust deduction), inputs inside, on and beyond the
    breakpoints and the clamps (linear extrapolation from the end segments)."""
    from bb2_sim.batch.lookup import BatchRomTables, Segments
    T, B = calm_model.tables, BatchRomTables(calm_model.tables)
    rng = np.random.default_rng(7)

    def inputs(table, n=400):
        cols = []
        for bp in table.breakpoints:
            lo, hi = bp[0], bp[-1]
            span = hi - lo
            x = rng.uniform(lo - 0.5 * span, hi + 0.5 * span, n)
            x[:len(bp)] = bp                                   # exactly on every breakpoint too
            cols.append(x)
        return cols

    for name, table in list(T.hull.items()) + [("thrust_deduction", T.thrust_deduction)]:
        xs = inputs(table)
        batch = (B.hull[name] if name in B.hull else B.thrust_deduction)(
            Segments(), *[(f"x{k}", x) for k, x in enumerate(xs)])
        single = np.array([table.lookup(*v) for v in zip(*[x.tolist() for x in xs])])
        np.testing.assert_array_equal(batch, single, err_msg=name)
    for comp, groups in B.planes.items():
        for planes, table in groups:
            xs = inputs(T.planes[comp][planes[0]], 200)
            cols = [np.stack([x] * len(planes), axis=1) for x in xs]
            for j in range(len(planes)):                         # members see different inputs
                for c in cols:
                    rng.shuffle(c[:, j])
            got = table(Segments(), *[(f"x{k}", c) for k, c in enumerate(cols)], stacked=True)
            for j, i in enumerate(planes):
                want = [T.planes[comp][i].lookup(*v) for v in zip(*[c[:, j].tolist() for c in cols])]
                np.testing.assert_array_equal(got[:, j], want, err_msg=f"{comp} plane {i + 1}")


# ------------------------------------------------------------------------------------------------ (b) autopilot
def test_v12_autopilot_maneuvers_batch_equals_single_runs(calm_model):
    settings = [
        maneuver_settings("self-propulsion"),
        maneuver_settings("depth-heading"),                         # sea state 5, depth and heading change
        maneuver_settings("turning-circle"),
        maneuver_settings("hzz", sea_state=3),
        maneuver_settings("vzz", amplitude_deg=5.0, check_deg=0.5, sail_planes="pid"),
        maneuver_settings("open-loop", planes_deg=(2, -2, 2, -2, 1), sea_state=4),
        maneuver_settings("self-propulsion", propeller="speed-pi", speed_mps=4.0, heading_ref_deg=20.0),
    ]
    sim, cmd = batch_for_maneuvers(settings, calm_model)
    sim_e, cmd_e = batch_for_maneuvers(settings, calm_model, exact=True)
    singles = [(Simulator(_single(calm_model, s.sea_state), s.initial_state()), ManeuverCommander(s))
               for s in settings]
    n = 200
    xb, xe, xs = (np.empty((n, len(settings), 12)) for _ in range(3))
    for k in range(n):
        sim_e.step(*cmd_e.step(sim_e.t, sim_e.x))
        planes, rps = cmd.step(sim.t, sim.x)
        for i, (s, c) in enumerate(singles):
            p1, r1 = c.step(s.t, s.x)
            np.testing.assert_allclose(planes[i], p1, rtol=1e-12, atol=1e-9)
            assert rps[i] == pytest.approx(r1, rel=1e-12, abs=1e-12)
            s.step(p1, r1)
        sim.step(planes, rps)
        xb[k], xe[k] = sim.x, sim_e.x
        xs[k] = [s.x for s, _ in singles]
    _assert_close(xb, xs)
    _assert_exact(xe, xs)
    assert cmd.zigzag.reversals[4] == singles[4][1].zigzag.reversals and cmd.zigzag.reversals[4]


# ------------------------------------------------------------------------------------------------ (c) divergence
def test_a_diverging_boat_is_reported_frozen_and_leaves_the_others_alone(calm_model):
    x0 = _mixed_x0()[:3]
    x0[1, 6] = 0.0                        # at rest: the iowa profile divides by |u| = 0 (quirk Q13) -> NaN
    batch = BatchSimulator(BatchModel.from_sea_states(calm_model, SEA_STATES[:3]), x0)
    single = Simulator(_single(calm_model, SEA_STATES[1]), x0[1])
    with pytest.raises(Exception) as e1:
        single.step(PLANES[1], RPS[1])
    rec = batch.step(PLANES[:3], RPS[:3])
    assert rec.newly_diverged.tolist() == [1]
    assert batch.diverged.tolist() == [False, True, False]
    assert type(batch.errors[1]) is type(e1.value) and "diverged" in str(batch.errors[1])
    np.testing.assert_array_equal(batch.x[1], x0[1])          # frozen at t_n
    others = [Simulator(_single(calm_model, SEA_STATES[i]), x0[i]) for i in (0, 2)]
    for r in others:
        r.step(PLANES[[0, 2][others.index(r)]], RPS[[0, 2][others.index(r)]])
    bad_cmd = PLANES[:3].copy()
    bad_cmd[1] = np.nan                     # a diverged boat's commands are ignored
    for _ in range(20):
        rec = batch.step(bad_cmd, RPS[:3])
        assert rec.boats.tolist() == [0, 2] and len(rec.newly_diverged) == 0
        for j, i in enumerate((0, 2)):
            others[j].step(PLANES[i], RPS[i])
    np.testing.assert_array_equal(batch.x[1], x0[1])
    xs = np.array([[r.x for r in others]])
    _assert_close(batch.x[None, [0, 2]], xs)



def test_sub_steps_in_a_batch_equal_single_runs_and_a_boat_diverging_in_a_sub_step_is_said_alike(calm_model):
    """``substeps``: boats in seas and calm, one fast (15 m/s at 4 rps: only sub-steps fly it), one at 25 m/s at
    full propeller diverging within a second -- in the same step, with the same error and stage time as its single
    run, frozen there -- and the others equal to their single runs (bit for bit in the exact mode)."""
    seas = [0, 5, 3, 0]
    x0 = _mixed_x0()[:4]
    x0[0, 6], x0[3, 6] = -15.0, -25.0
    planes, rps = PLANES[:4], np.array([4.0, RPS[1], RPS[2], 10.0])
    batch = BatchSimulator(BatchModel.from_sea_states(calm_model, seas), x0, substeps=2)
    exact = BatchSimulator(BatchModel.from_sea_states(calm_model, seas, exact=True), x0, substeps=2)
    singles = [Simulator(_single(calm_model, s), x0[i], substeps=2) for i, s in enumerate(seas)]
    n = 200
    xb, xe, xs = np.empty((n, 4, 12)), np.empty((n, 4, 12)), np.empty((n, 4, 12))
    single_error = None
    for k in range(n):
        rec = batch.step(planes, rps)
        exact.step(planes, rps)
        for i, sim in enumerate(singles):
            if i == 3 and single_error is not None:
                continue
            try:
                sim.step(planes[i], rps[i])
            except Exception as e:  # noqa: BLE001 - compared with the batch's below
                single_error = e
                assert rec.newly_diverged.tolist() == [3] and k < 50
        xb[k], xe[k] = batch.x, exact.x
        xs[k] = [sim.x for sim in singles]
    assert single_error is not None and batch.diverged.tolist() == [False, False, False, True]
    for b in (batch, exact):
        assert str(b.errors[3]) == str(single_error) and b.errors[3].t == single_error.t  # the same stage
    _assert_close(xb, xs)
    _assert_exact(xe, xs)
    assert -xs[-1, 0, 6] > 15.0

# ------------------------------------------------------------------------------------------------ (d) bad input
def test_boats_retired_mid_run_leave_the_others_added_mass_memories_alone(calm_model):
    """Boats in seas and in calm water; two retired mid-run (one in a sea): the others' Derivative blocks (the
    motion's and the sections' wave velocities, kept per boat) go on as their single runs'."""
    seas = [3, 5, 0, 4, 0]
    x0 = _mixed_x0()[:5]
    batch = BatchSimulator(BatchModel.from_sea_states(calm_model, seas), x0)
    singles = [Simulator(_single(calm_model, s), x0[i]) for i, s in enumerate(seas)]
    live = [0, 1, 2, 3, 4]
    xb, xs = [], []
    for k in range(120):
        if k == 40:
            batch.retire([1, 2])
            live = [0, 3, 4]
        rec = batch.step(PLANES[:5], RPS[:5])
        assert rec.boats.tolist() == live or (k < 40 and rec.boats.tolist() == [0, 1, 2, 3, 4])
        for i in live:
            singles[i].step(PLANES[i], RPS[i])
        if k >= 40:
            xb.append(batch.x[live])
            xs.append([singles[i].x for i in live])
    assert np.abs(rec.ev.added_mass).max() > 1e3          # the added mass matters here
    _assert_close(np.array(xb), np.array(xs))


def test_bad_shapes_and_mismatched_environments_give_clear_errors(calm_model):
    bm = BatchModel(calm_model, n_boats=2)
    with pytest.raises(ValueError, match=r"initial states must be \(2, 12\)"):
        BatchSimulator(bm, np.zeros((3, 12)))
    with pytest.raises(ValueError, match="finite"):
        BatchSimulator(bm, np.full((2, 12), np.nan))
    sim = BatchSimulator(bm, _mixed_x0()[:2])
    with pytest.raises(ValueError, match=r"plane commands must be \(2, 5\)"):
        sim.step(np.zeros(5), 1.0)
    with pytest.raises(ValueError, match=r"rps commands must be a scalar or \(2,\)"):
        sim.step(np.zeros((2, 5)), np.ones(3))
    with pytest.raises(ValueError, match=r"ballast commands"):
        sim.step(np.zeros((2, 5)), 1.0, np.zeros((2, 1)))
    with pytest.raises(ValueError, match="commands must be finite"):
        sim.step(np.zeros((2, 5)), np.array([1.0, math.inf]))
    with pytest.raises(ValueError, match=r"states must be \(2, 12\)"):
        bm.evaluate(0.0, np.zeros((2, 11)), sim.actuators.step(np.zeros((2, 5)), np.ones(2), np.zeros(2)),
                    bm.new_memory())
    with pytest.raises(ValueError, match="give the waves of the boats or n_boats"):
        BatchModel(calm_model)
    with pytest.raises(ValueError, match=r"boat 1: a wave must be a bb2_sim.waves.Wave .*give an irregular sea as seas"):
        BatchModel(calm_model, [Wave(), object()])
    from bb2_sim.sea import ComponentSea, JonswapSpectrum, discretise
    sea = ComponentSea(discretise(JonswapSpectrum(2.0, 8.0, 3.3), 8, seed=1))
    with pytest.raises(ValueError, match=r"batch: the model must be calm: give each boat its sea \(seas="):
        BatchModel(BB2Model(calm_model.surfaces, sea=sea), n_boats=2)
    from bb2_sim.current import Current
    with pytest.raises(ValueError, match=r"batch: the model must have no current: give each boat its current"):
        BatchModel(BB2Model(calm_model.surfaces, current=Current(0.5, 45.0)), n_boats=2)
    with pytest.raises(ValueError, match="batch: waves for 2 boats, seas for 3 boats"):
        BatchModel(calm_model, [Wave(), Wave()], seas=[None, sea, None])
    with pytest.raises(ValueError, match="batch: boat 0: give either a sea state"):
        BatchModel(calm_model, [wave_for_sea_state(3, calm_model.params)], seas=[sea])
    assert sim.n == 0 and not sim.diverged.any()          # nothing stepped by the refused calls


# ------------------------------------------------------------------------------------------------ (e) whole runs
@pytest.mark.parametrize("substeps", [1, 2])
def test_maneuvers_flown_together_give_each_run_maneuver_result(calm_model, substeps):
    """``run_maneuvers_batch``: what ``run_maneuver`` gives each maneuver alone -- trajectory (every logged column,
    the sea's elevation included), zig-zag reversals, divergence -- bit for bit in the exact mode, with boats of
    different durations and one that diverges at its first step (at rest: quirk Q13); with the ROM's step in one
    ode3 step (the authors') and in two (``substeps``)."""
    from bb2_sim.batch.maneuvers import batch_for_maneuvers, run_maneuvers_batch
    from bb2_sim.maneuvers import OUTPUT_COLUMNS, run_maneuver

    settings = [
        maneuver_settings("hzz", sea_state=3, duration=14.0),
        maneuver_settings("turning-circle", duration=9.0),
        maneuver_settings("vzz", amplitude_deg=5.0, check_deg=0.5, sail_planes="pid", duration=12.0),
        maneuver_settings("open-loop", planes_deg=(2, -2, 2, -2, 1), sea_state=5, duration=6.0),
        maneuver_settings("self-propulsion", propeller="speed-pi", speed_mps=0.0, duration=5.0),
        maneuver_settings("depth-heading", duration=11.0),
    ]
    settings = [replace(s, substeps=substeps) for s in settings]
    with pytest.raises(ValueError, match="share one substeps"):
        batch_for_maneuvers([settings[0], replace(settings[1], substeps=substeps + 1)], calm_model)
    told: list[float] = []
    batch = run_maneuvers_batch(settings, calm_model, on_progress=told.append)
    # a campaign's progress while the batch flies: maneuvers' worth of steps (the diverged boat 1 at once), to all
    assert told[0] == 0.0 and told[-1] == len(settings) and told == sorted(told), told
    assert any(1 <= v < len(settings) - 1 for v in told), told
    for s, b in zip(settings, batch):
        one = run_maneuver(s, _single(calm_model, s.sea_state))
        assert b.settings is s and list(b.traj) == OUTPUT_COLUMNS
        for c in OUTPUT_COLUMNS:
            assert b.traj[c].shape == one.traj[c].shape, (s.name, c)
            assert np.array_equal(b.traj[c], one.traj[c], equal_nan=True), (s.name, c)
        assert b.reversals == one.reversals, s.name
        # (a divergence is found in the same step; its message says what the batch saw: a non-finite stage, where
        # the single run may have stopped at the exception that made it)
        assert type(b.error) is type(one.error), s.name
    assert batch[2].reversals                                           # the vertical zig-zag switched
    assert batch[4].error is not None and len(batch[4].traj["t_s"]) == 0  # diverged at once, nothing logged
    assert batch[1].traj["t_s"][-1] == pytest.approx(9.0) and batch[0].traj["t_s"][-1] == pytest.approx(14.0)
    assert np.abs(batch[3].traj["eta_cg_m"]).max() > 0.1                # the sea state 5 boat's surface


def test_maneuvers_in_their_own_seas_and_currents_fly_together_as_alone(calm_model):
    """A maneuver's environment (a spectrum sea, a current: ``with_sea``, as ``bb2-sim maneuver --sea-spectrum``
    and a campaign's maneuver options give it) flies in the batch: every logged column, the sea's elevation above
    the CG included, bit for bit what ``run_maneuver`` gives it alone."""
    from bb2_sim.batch.maneuvers import run_maneuvers_batch
    from bb2_sim.maneuvers import OUTPUT_COLUMNS, build_model, run_maneuver, with_sea

    settings = [
        with_sea(maneuver_settings("turning-circle", duration=8.0, depth=20.0), {"spectrum": "jonswap", "hs": 2.5,
                 "tp": 8.0, "components": 12, "seed": 4, "heading_deg": 90.0}, {"speed_mps": 0.4}),
        with_sea(maneuver_settings("hzz", duration=6.0, depth=18.0), {"spectrum": "pm", "hs": 2.0, "components": 8,
                 "seed": 2}, None),
        with_sea(maneuver_settings("depth-heading", duration=7.0), None, {"speed_mps": 0.5, "heading_deg": 90.0}),
        maneuver_settings("turning-circle", duration=5.0, sea_state=4),
    ]
    assert all(s.environment is not None for s in settings[:3])
    batch = run_maneuvers_batch(settings, calm_model)
    for s, b in zip(settings, batch):
        one = run_maneuver(s, build_model(s))
        for c in OUTPUT_COLUMNS:
            assert np.array_equal(b.traj[c], one.traj[c], equal_nan=True), (s.name, c)
    assert np.abs(batch[0].traj["eta_cg_m"]).max() > 0.1 and np.abs(batch[1].traj["eta_cg_m"]).max() > 0.1


def test_the_exact_modes_transcendentals_are_the_c_librarys_element_by_element():
    """bb2_sim.batch.libm: math's acos/atan/sin/cos of every element (numpy's AVX-512 kernels differ from them in
    the last bit for some arguments), the array's shape kept, NaN outside the domain as numpy gives."""
    from bb2_sim.batch import libm
    rng = np.random.default_rng(3)
    x = rng.uniform(-1.0, 1.0, (40, 5))
    for ours, theirs in ((libm.arccos, math.acos), (libm.arctan, math.atan), (libm.sin, math.sin),
                         (libm.cos, math.cos)):
        got = ours(x)
        assert got.shape == x.shape
        assert got.tolist() == [[theirs(v) for v in row] for row in x.tolist()]
    bad = libm.arccos(np.array([0.5, 1.5, -1.0, np.nan]))
    assert bad[0] == math.acos(0.5) and math.isnan(bad[1]) and bad[2] == math.pi and math.isnan(bad[3])
    assert math.isnan(libm.sin(np.array([np.inf]))[0])


@pytest.mark.parametrize("exact", [True, False])
def test_boats_in_regular_seas_take_the_scalar_pressure_integral_bit_for_bit(calm_model, exact):
    """The batch's pressure loads of boats in the authors' seas (either mode: their per-point pass boat by boat,
    the rest vectorised) equal the scalar integrator's bit for bit, at their own times, deflections and attitudes
    among calm boats; the calm boats keep their mode's accuracy."""
    from bb2_sim.batch.pressure import BatchPressure
    from bb2_sim.batch.waves import BatchWaves
    from bb2_sim.frames import rotation_native
    rng = np.random.default_rng(11)
    n = 12
    pos = np.c_[rng.uniform(-50, 50, n), rng.uniform(-50, 50, n), rng.uniform(-15, -3, n)]
    phi, theta, psi = rng.uniform(-0.3, 0.3, n), rng.uniform(-0.3, 0.3, n), rng.uniform(-3, 3, n)
    R = rotation_native(phi, theta, psi)
    defl = rng.uniform(-20, 20, (n, 5))
    waves = [wave_for_sea_state(s, calm_model.params) if s else Wave() for s in [0, 3, 4, 5, 6, 0] * 2]
    t = rng.uniform(0.0, 500.0, n)
    bp = BatchPressure(calm_model.hydro, exact=exact)
    got = bp.loads(pos, R, t, BatchWaves.from_waves(waves), bp.prepare(defl))
    single = np.array([calm_model.hydro.loads(pos[i], np.ascontiguousarray(R[:, :, i]), float(t[i]), waves[i],
                                              defl[i]) for i in range(n)])
    wavy = np.array([not w.calm for w in waves])
    assert wavy.sum() == 8 and np.abs(single[wavy] - single[wavy][0]).max() > 1e3      # distinct, not trivial
    assert np.array_equal(got[wavy], single[wavy]), np.abs(got - single)[wavy].max()
    scale = np.abs(single[~wavy]).max(axis=0)
    assert (np.abs(got[~wavy] - single[~wavy]) <= 1e-12 * np.maximum(scale, 1.0)).all()
    if exact:
        assert np.array_equal(got, single)
