"""cos-2s spreading: the discretised directions reproduce the directional moments."""
import math

import numpy as np
import pytest

from bb2_sim.sea import ComponentSea, Cos2sSpreading, JonswapSpectrum, discretise


@pytest.mark.parametrize("s", [1.0, 4.0, 15.0])
def test_density_integrates_to_one_and_has_the_moments(s):
    D = Cos2sSpreading(0.3, s)
    th = np.linspace(0.3 - math.pi, 0.3 + math.pi, 200001)
    d = D(th)
    assert np.trapezoid(d, th) == pytest.approx(1.0, abs=1e-6)
    m1, m2 = D.moments()
    assert np.trapezoid(d * np.cos(th - 0.3), th) == pytest.approx(m1, abs=1e-6)
    assert np.trapezoid(d * np.cos(2 * (th - 0.3)), th) == pytest.approx(m2, abs=1e-6)


@pytest.mark.parametrize("n_directions", [None, 8])
@pytest.mark.parametrize("s", [2.0, 10.0])
def test_discretised_components_reproduce_the_directional_moments(s, n_directions):
    mean = math.radians(40.0)
    comps = discretise(JonswapSpectrum(3.25, 9.7), 256 if n_directions is None else 64, seed=7,
                       method="equal_energy", spreading=Cos2sSpreading(mean, s), mean_direction_deg=40.0,
                       n_directions=n_directions)
    e = comps.amplitude ** 2
    m1, m2 = Cos2sSpreading(mean, s).moments()
    d = comps.direction - mean
    assert np.sum(e * np.cos(d)) / e.sum() == pytest.approx(m1, abs=0.01)
    assert np.sum(e * np.cos(2 * d)) / e.sum() == pytest.approx(m2, abs=0.02)
    assert abs(np.sum(e * np.sin(d)) / e.sum()) < 0.01            # symmetric about the mean


def test_direction_convention_waves_travel_towards_the_direction():
    """90 deg = towards +y_E: a crest moves to +y."""
    from bb2_sim.sea import regular_components
    sea = ComponentSea(regular_components(1.0, 10.0, 90.0))
    k = (2 * math.pi / 10.0) ** 2 / 9.81
    y = np.linspace(-20, 20, 40001)
    y0 = y[np.argmax(sea.elevation(np.zeros_like(y), y, 0.0))]
    y1 = y[np.argmax(sea.elevation(np.zeros_like(y), y, 0.5))]
    assert y1 > y0 and (y1 - y0) == pytest.approx(0.5 * (2 * math.pi / 10.0) / k, abs=0.01)
    assert np.ptp(sea.elevation(np.linspace(-50, 50, 11), np.zeros(11), 0.0)) < 1e-12   # no x dependence
