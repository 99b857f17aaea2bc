"""Spectra, discretisation and the sea-state table of bb2_sim.sea: Hs and Tp recovered from long realisations."""
import math

import numpy as np
import pytest
from scipy.signal import welch

from bb2_sim.sea import (ComponentSea, Cos2sSpreading, ITTCSpectrum, JonswapSpectrum, PiersonMoskowitzSpectrum,
                         SeaInputError, WaveComponents, discretise, read_components_csv, sea_state_hs_tp, spectrum,
                         write_components_csv)

SPECTRA = [JonswapSpectrum(3.25, 9.7, 3.3), JonswapSpectrum(5.0, 12.4, 1.0), ITTCSpectrum(1.88, 8.8),
           PiersonMoskowitzSpectrum(3.25)]


def _estimate_hs_tp(spec, sea, duration=4 * 3600.0, dt=0.5):
    """Hs = 4 std(eta); Tp = the peak period of the spectrum's own shape fitted (least squares, Hs held at
    the estimate) to the Welch estimate of the record (a broad PM peak is too flat to locate by its maximum)."""
    t = np.arange(0.0, duration, dt)
    c = sea.components
    eta = np.cos(np.multiply.outer(t, -c.omega) + c.phase) @ c.amplitude
    assert sea.elevation(np.array([0.0]), np.array([0.0]), t[7])[0] == pytest.approx(eta[7], abs=1e-12)
    hs = 4.0 * eta.std()
    f, S = welch(eta, fs=1.0 / dt, nperseg=4096)
    w, Sw = 2 * math.pi * f, S / (2 * math.pi)                      # one-sided, m^2 s / rad
    tps = np.linspace(0.8, 1.2, 801) * spec.tp
    kw = {"gamma": spec.gamma} if isinstance(spec, JonswapSpectrum) else {}
    cost = [np.sum((Sw - type(spec).__mro__[0](hs=hs, tp=tp, **kw)(w)) ** 2) if not isinstance(
        spec, PiersonMoskowitzSpectrum) else np.sum((Sw - ITTCSpectrum(hs, tp)(w)) ** 2) for tp in tps]
    return hs, float(tps[int(np.argmin(cost))]), eta


@pytest.mark.parametrize("method", ["equal_energy", "equal_domega"])
@pytest.mark.parametrize("spec", SPECTRA, ids=lambda s: f"{s.name}-{s.hs}")
def test_long_realisation_recovers_hs_and_tp(spec, method):
    sea = ComponentSea(discretise(spec, 256, seed=3, method=method))
    hs, tp, _ = _estimate_hs_tp(spec, sea)
    assert abs(hs / spec.hs - 1) < 0.03, hs
    assert abs(tp / spec.tp - 1) < 0.03, tp


def test_spectrum_integrates_to_hs_and_peaks_at_tp():
    for spec in SPECTRA:
        w = np.linspace(0.01, 40.0, 400001)
        S = spec(w)
        assert abs(4 * math.sqrt(np.trapezoid(S, w)) / spec.hs - 1) < 2e-3
        assert abs(w[np.argmax(S)] / spec.omega_p - 1) < 1e-3
    assert abs(PiersonMoskowitzSpectrum(3.25).tp - 2 * math.pi / (0.4012 * math.sqrt(9.81 / 3.25))) < 0.01


def test_seed_repeats_and_changes():
    spec = JonswapSpectrum(3.25, 9.7)
    a, b, c = (discretise(spec, 64, seed=s) for s in (1, 1, 2))
    assert np.array_equal(a.phase, b.phase) and np.array_equal(a.omega, b.omega)
    assert not np.array_equal(a.phase, c.phase)
    assert len(a) == 64 and len(discretise(spec, 16, spreading=Cos2sSpreading(0.0, 5), n_directions=4)) == 64


@pytest.mark.parametrize("make", [
    lambda: JonswapSpectrum(-1.0, 9.0), lambda: JonswapSpectrum(3.0, 0.0), lambda: JonswapSpectrum(3.0, -2.0),
    lambda: JonswapSpectrum(3.0, 9.0, 0.9), lambda: JonswapSpectrum(float("nan"), 9.0),
    lambda: JonswapSpectrum(3.0, float("nan")), lambda: JonswapSpectrum(3.0, 9.0, float("nan")),
    lambda: ITTCSpectrum(0.0, 9.0), lambda: PiersonMoskowitzSpectrum(float("inf")),
    lambda: discretise(ITTCSpectrum(2.0, 8.0), 0), lambda: discretise(ITTCSpectrum(2.0, 8.0), -3),
    lambda: discretise(ITTCSpectrum(2.0, 8.0), 8, method="nope"), lambda: Cos2sSpreading(0.0, -1.0),
    lambda: Cos2sSpreading(float("nan"), 2.0), lambda: spectrum("nope", hs=1.0),
    lambda: WaveComponents([1.0], [float("nan")], [0.0], [0.0]), lambda: WaveComponents([-1.0], [1.0], [0.0], [0.0]),
    lambda: WaveComponents([], [], [], []), lambda: sea_state_hs_tp(11),
])
def test_bad_input_raises_a_clear_value_error(make):
    with pytest.raises(SeaInputError) as e:
        make()
    assert isinstance(e.value, ValueError) and str(e.value)


def test_sea_state_table_is_the_authors_regular_table():
    """A = Hs/2 and T = Tp of the documented table, except sea state 5 (their 9.50 s, the table's 9.7 s)."""
    from bb2_sim.parameters import load_parameters
    from bb2_sim.waves import wave_for_sea_state
    p = load_parameters()
    for ss in range(2, 8):
        hs, tp = sea_state_hs_tp(ss)
        w = wave_for_sea_state(ss, p)
        assert w.amplitude == pytest.approx(hs / 2, abs=0.005)
        assert w.period == pytest.approx(tp, abs=0.01 if ss != 5 else 0.21)


def test_component_csv_round_trip(tmp_path):
    comps = discretise(JonswapSpectrum(3.25, 9.7), 12, seed=5, spreading=Cos2sSpreading(0.5, 8))
    path = tmp_path / "sea.csv"
    write_components_csv(path, comps)
    back = read_components_csv(path)
    for name in ("amplitude", "omega", "direction", "phase"):
        np.testing.assert_allclose(getattr(back, name), getattr(comps, name), rtol=1e-14, atol=1e-14)
    (tmp_path / "bad.csv").write_text("amplitude_m,omega_rad_s\n1,2\n")
    with pytest.raises(SeaInputError):
        read_components_csv(tmp_path / "bad.csv")
