"""Currents in the ROM: zero current = no current; a free boat drifts with the current; a turning circle in a
uniform current is the calm-water one displaced by the current times the elapsed time."""
import math

import numpy as np
import pytest

from bb2_sim.current import Current
from bb2_sim.frames import rotation_native
from bb2_sim.integrator import Simulator
from bb2_sim.model import BB2Model
from bb2_sim.sea import SeaInputError
from bb2_sim.xplane import plane_angles_deg

X0 = np.array([0, 0, -35.0624, 0, 0, 0, -5.1444, 0, 0, 0, 0, 0.0])


def _run(model, x0, planes, rps, n):
    sim = Simulator(model, x0)
    out = [sim.x.copy()]
    for _ in range(n):
        sim.step(planes, rps)
        out.append(sim.x.copy())
    return np.array(out)


def test_zero_current_equals_no_current():
    planes = np.array([2.0, -1.0, 1.0, -2.0, 3.0])
    a = _run(BB2Model(), X0, planes, 1.2, 60)
    b = _run(BB2Model(current=Current(0.0, 45.0)), X0, planes, 1.2, 60)
    assert np.array_equal(a, b)


def test_neutral_boat_drifts_with_a_uniform_current():
    cur = Current(0.8, 60.0)
    m = BB2Model(profile="corrected", current=cur, trim_to_buoyancy=True)
    x0 = np.zeros(12)
    x0[2] = -40.0
    x0[6:9] = cur.velocity_earth(-40.0) @ rotation_native(0, 0, 0)     # moving with the water
    xs = _run(m, x0, np.zeros(5), 0.0, 600)                             # 30 s, no thrust, planes at zero
    t = 0.05 * np.arange(len(xs))
    rel = np.array([x[6:9] - cur.velocity_earth(x[2]) @ rotation_native(*x[3:6]) for x in xs])
    assert np.abs(rel).max() < 0.02
    drift = xs[-1, 0:2] - x0[0:2]
    np.testing.assert_allclose(drift, cur.speed * t[-1] * np.array([math.cos(math.radians(60)),
                                                                     math.sin(math.radians(60))]), atol=0.3)
    # from rest over ground the relative velocity decays
    x1 = x0.copy()
    x1[6:9] = 0.0
    ys = _run(m, x1, np.zeros(5), 0.0, 1200)
    rel0 = np.linalg.norm(x1[6:9] - cur.velocity_earth(-40.0))
    rel = [np.linalg.norm(y[6:9] - cur.velocity_earth(y[2]) @ rotation_native(*y[3:6])) for y in ys[::200]]
    assert np.all(np.diff(rel) < 0) and rel[-1] < 0.6 * rel0        # quadratic drag: 0.8 -> 0.45 m/s in 60 s


def test_turning_circle_in_a_current_drifts_by_current_times_time():
    cur = Current(1.0, 30.0)
    planes = np.asarray(plane_angles_deg(0.0, -20.0), dtype=float)
    n = 1200                                                            # 60 s
    calm = _run(BB2Model(), X0, planes, 1.2861, n)
    x0 = X0.copy()
    x0[6:9] += cur.velocity_earth(X0[2]) @ rotation_native(*X0[3:6])   # same start relative to the water
    drift = _run(BB2Model(current=cur), x0, planes, 1.2861, n)
    t = 0.05 * np.arange(n + 1)
    expect = calm[:, 0:3] + np.outer(t, cur.velocity_earth(0.0))
    assert np.ptp(calm[:, 5]) > 0.5                                     # it does turn
    np.testing.assert_allclose(drift[:, 0:3], expect, atol=0.01)        # 1 cm over a 300 m track
    np.testing.assert_allclose(drift[:, 3:6], calm[:, 3:6], atol=1e-5)


def test_profiles_and_bad_input():
    c = Current(1.0, 0.0, ("power", 100.0, 1 / 7))
    assert c.factor(0.0) == 1.0 and c.factor(-100.0) == 0.0 and c.factor(-150.0) == 0.0
    assert c.factor(-50.0) == pytest.approx(0.5 ** (1 / 7))
    t = Current(2.0, 90.0, ("table", [0.0, 50.0], [1.0, 0.5]))
    np.testing.assert_allclose(t.velocity_earth(-25.0), [2.0 * 0.75 * math.cos(math.pi / 2), 1.5, 0.0], atol=1e-15)
    for bad in (lambda: Current(-1.0), lambda: Current(float("nan")), lambda: Current(1.0, 0.0, ("x",)),
                lambda: Current(1.0, 0.0, ("table", [10.0, 5.0], [1.0, 1.0]))):
        with pytest.raises(SeaInputError):
            bad()
