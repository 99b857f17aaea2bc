"""ROM sub-steps (``Simulator(..., substeps=k)``): the authors' fixed ode3 step h = 0.05 s is numerically unstable
from about 14 m/s; k ode3 steps of h/k per major step fly there, converge as k grows, and change little at the
speeds the reference runs at.  k = 1 is the reference's step (the reference tests check it bit for bit)."""
from __future__ import annotations

import numpy as np
import pytest

from bb2_sim.integrator import NonFiniteStateError, Simulator
from bb2_sim.model import BB2Model

T_S = 10.0


@pytest.fixture(scope="module")
def model():
    return BB2Model()


def _fly(model: BB2Model, substeps: int, u0_mps: float, rps: float) -> Simulator:
    x0 = np.zeros(12)
    x0[2], x0[6] = -20.0, -u0_mps  # native: z up, u < 0 ahead
    sim = Simulator(model, x0, substeps=substeps)
    while sim.t < T_S - 1e-9:
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
    x0[2], x0[6] = -20.0, -25.0  # 25 m/s at full propeller: two sub-steps hold to about 18 m/s
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
