"""ROM sub-steps (``Simulator(..., substeps=k)``): the authors' fixed ode3 step h = 0.05 s is numerically unstable
in a steady cruise from about 11.6 m/s; k ode3 steps of h/k per major step fly there, converge as k grows, and change
little at the speeds the reference runs at.  k = 1 is the reference's step (the reference tests check it bit for
bit).  The fastest cruise each k flies is measured data (``bb2_sim/data/substeps_stability.yaml``), from which a
diverged run is advised its sub-steps."""
from __future__ import annotations

import numpy as np
import pytest

from bb2_sim.integrator import NonFiniteStateError, Simulator
from bb2_sim.step_stability import (cruise_limits, cruise_speed, hint_from, hint_margin, speed_warning, substeps_for,
                                    substeps_hint)
from bb2_sim.model import BB2Model

T_S = 10.0


@pytest.fixture(scope="module")
def model():
    return BB2Model()


def _fly(model: BB2Model, substeps: int, u0_mps: float, rps: float, duration_s: float = T_S) -> Simulator:
    x0 = np.zeros(12)
    x0[2], x0[6] = -20.0, -u0_mps  # native: z up, u < 0 ahead
    sim = Simulator(model, x0, substeps=substeps)
    while sim.t < duration_s - 1e-9:
        sim.step(np.zeros(5), rps)
    return sim


def test_the_reference_step_diverges_at_15_m_s_and_sub_steps_fly_there_and_converge(model):
    with pytest.raises(NonFiniteStateError, match="diverged at t = "):
        _fly(model, 1, 15.0, 4.0)
    two, four = _fly(model, 2, 15.0, 4.0), _fly(model, 4, 15.0, 4.0)
    assert two.t == pytest.approx(T_S) and two.n == round(T_S / two.h)  # the major steps: still 50 Hz
    assert np.all(np.isfinite(two.x)) and -two.x[6] > 15.0           # flying faster, not stopped
    np.testing.assert_allclose(two.x[:3], four.x[:3], rtol=0, atol=2e-3)    # m after 150 m
    np.testing.assert_allclose(two.x[6:9], four.x[6:9], rtol=0, atol=1e-3)  # m/s


def test_at_the_reference_speeds_sub_steps_change_little(model):
    one, two = _fly(model, 1, 8.0, 2.0), _fly(model, 2, 8.0, 2.0)
    np.testing.assert_allclose(one.x[:3], two.x[:3], rtol=0, atol=1e-3)
    np.testing.assert_allclose(one.x[6:9], two.x[6:9], rtol=0, atol=1e-4)
    assert not np.array_equal(one.x, two.x)  # (they are integrated differently)


def test_a_divergence_inside_a_sub_step_is_said_at_its_stage_time_and_leaves_the_step_undone(model):
    x0 = np.zeros(12)
    x0[2], x0[6] = -20.0, -25.0  # 25 m/s at full propeller: two sub-steps cruise to about 15 m/s
    sim = Simulator(model, x0, substeps=2)
    with pytest.raises(NonFiniteStateError) as err:
        for _ in range(100):  # (5 s: it diverges within the first second)
            before = (sim.t, sim.x.copy())
            sim.step(np.zeros(5), 10.0)
    assert (sim.t, sim.n) == (before[0], 15) and np.array_equal(sim.x, before[1])  # left at t_n = 0.75 s
    # at the second sub-step's third stage: t_n + h/2 + (3/4) h/2 = 0.79375 s
    assert "diverged at t = 0.79 s" in str(err.value) and err.value.t == pytest.approx(0.79375)


@pytest.mark.parametrize("bad", [0, -1, 1.5, True, "2"])
def test_bad_substeps_are_refused_naming_them(model, bad):
    with pytest.raises(ValueError, match="substeps must be an integer >= 1"):
        Simulator(model, np.r_[0, 0, -20, 0, 0, 0, -8, 0, 0, 0, 0, 0], substeps=bad)


def test_the_measured_cruise_limits_hold_where_the_advice_relies_on_them(model):
    """Two rows of the data the advice reads, flown as measured (4.2 m/s per rps, planes 0, 20 m deep): the
    authors' step diverges at its slowest diverged cruise (11.6 m/s, about 45 s in) where two sub-steps fly on; at
    the sprint's 16.8 m/s two diverge (about 10 s in) and three, the advice for it, fly on."""
    limits = cruise_limits()
    assert limits[1][1] == pytest.approx(4.2 * 2.75, abs=0.05) and limits[2][0] > limits[1][1]
    with pytest.raises(NonFiniteStateError):
        _fly(model, 1, 4.2 * 2.75, 2.75, duration_s=60.0)
    assert np.all(np.isfinite(_fly(model, 2, 4.2 * 2.75, 2.75, duration_s=60.0).x))
    with pytest.raises(NonFiniteStateError):
        _fly(model, 2, 4.2 * 4.0, 4.0, duration_s=20.0)
    assert substeps_for(16.0) == 3  # the sprint held 16 m/s when it diverged with one
    three = _fly(model, 3, 4.2 * 4.0, 4.0, duration_s=30.0)
    assert np.all(np.isfinite(three.x)) and -three.x[6] > 16.0


def test_the_advice_is_the_fewest_sub_steps_measured_to_cruise_with_a_margin_above_the_speed_held():
    limits = cruise_limits()
    assert sorted(limits) == list(range(1, len(limits) + 1))
    assert all(limits[k][0] < limits[k][1] <= limits[k + 1][0] + 1.0 for k in list(limits)[:-1])
    for speed in np.arange(8.0, 22.0, 0.25):
        for current in limits:
            k = substeps_for(speed, current)
            if k in limits:
                assert k > current and limits[k][0] >= hint_margin() * speed, (speed, current, k)
                assert all(limits[j][0] < hint_margin() * speed for j in range(current + 1, k)), (speed, current, k)
            else:  # none measured above the current fits: twice the larger of the current and the largest
                assert k == 2 * max(current, max(limits)), (speed, current, k)
                assert all(limits[j][0] < hint_margin() * speed for j in limits if j > current), (speed, current, k)
    t = np.arange(0.0, 5.0, 0.05)
    flown = limits[1][0]
    held = np.full_like(t, hint_from() * flown)
    hint = substeps_hint(t, held, 1, "--substeps")
    assert hint.startswith(f"the boat held {hint_from() * flown:.1f} m/s") and hint.endswith(
        f"--substeps {substeps_for(hint_from() * flown)} integrates it in {substeps_for(hint_from() * flown)}"), hint
    assert substeps_hint(t, held - 0.05, 1, "--substeps") == ""  # slower: a capsize, not the step
    slowed = np.where(t > t[-1] - 1.0, held, 5.0)  # fast only over its last second: not held for 2 s
    assert substeps_hint(t, slowed, 1, "--substeps") == ""
    assert substeps_hint([], [], 1, "--substeps") == ""
    assert substeps_hint(t, np.full_like(t, 16.8), 2, "x:").endswith("x: 4 integrates it in 4")  # 1.1 x 16.8: past 3
    # a boat that diverged while it sped up towards a faster cruise: the advice is for where it was heading (the
    # sub-steps for the speed it held would diverge again, a little faster), none from below the margin
    on_way = substeps_hint(t, held, 1, "--substeps", toward_mps=limits[2][0])
    assert f"on its way to about {limits[2][0]:.1f} m/s" in on_way and on_way.endswith("--substeps 2 integrates it "
                                                                                         "in 2"), on_way
    assert substeps_hint(t, held, 1, "--substeps", toward_mps=held[0] * hint_margin()) == hint
    assert substeps_hint(t, held - 0.05, 1, "--substeps", toward_mps=100.0) == ""  # the held speed decides
    assert substeps_hint(t, held, 1, "--substeps", toward_mps=431.0).endswith(
        f"--substeps {2 * max(limits)} integrates it in {2 * max(limits)} or more (faster than measured: "
        "benchmarks/substeps_stability.py)")


def test_a_run_faster_than_its_sub_steps_fly_is_warned_before_it_starts(model):
    """``speed_warning``: above the fastest steady cruise of its sub-steps (not at it), with the fewest that fly
    the speed; beyond the measured table, twice its largest.  ``cruise_speed`` is the measured steady speed per rps:
    a boat started there stays there."""
    limits = cruise_limits()
    assert speed_warning(limits[1][0], 1, "--substeps") == ""
    said = speed_warning(limits[1][0] + 0.1, 1, "--substeps", "maneuver x")
    assert said.startswith(f"maneuver x at about {limits[1][0] + 0.1:.1f} m/s is faster than") and said.endswith(
        f"will likely diverge; --substeps 2 flies to about {limits[2][0]:.1f} m/s"), said
    assert speed_warning(17.2, 2, "k:").endswith(f"k: 3 flies to about {limits[3][0]:.1f} m/s")
    assert speed_warning(30.0, 1, "k:").endswith(f"k: {2 * max(limits)} flies faster than measured "
                                                 "(benchmarks/substeps_stability.py)")
    assert speed_warning(30.0, 2 * max(limits), "k:") == ""  # not measured: no warning
    u = cruise_speed(2.0)
    sim = _fly(model, 1, u, 2.0, duration_s=30.0)
    assert float(np.linalg.norm(sim.x[6:9])) == pytest.approx(u, rel=0.02)
