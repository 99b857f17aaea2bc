"""Issue 11, point 6: the fast (grid) wave loads of an irregular sea stay within 0.5 % of each load's range
of a direct full-resolution pressure integration (every point, every component) along a flown run."""
import math

import numpy as np
import pytest

from bb2_sim.frames import rotation_native
from bb2_sim.integrator import Simulator
from bb2_sim.maneuvers import ManeuverCommander, maneuver_settings
from bb2_sim.model import BB2Model
from bb2_sim.sea import ComponentSea, Cos2sSpreading, JonswapSpectrum, discretise
from bb2_sim.waves import Wave


def _fly(model: BB2Model, s, every: int):
    """(t, x, actual plane deflections) every ``every`` major steps of maneuver ``s`` (grid wave loads)."""
    sim, cmd = Simulator(model, s.initial_state()), ManeuverCommander(s)
    out = []
    for k in range(int(round(s.duration / sim.h))):
        planes, rps = cmd.step(sim.t, sim.x)
        rec = sim.step(planes, rps)
        if k % every == 0:
            out.append((rec.t, rec.x.copy(), rec.act.planes_deg.copy()))
    return out


def _errors(model: BB2Model, samples):
    """Max |grid - direct| per load over the samples, as a fraction of the range of the direct wave loads."""
    H, sea = model.hydro, model.sea
    direct, grid, calm = [], [], []
    for t, x, defl in samples:
        R, pos = rotation_native(*x[3:6]), x[0:3]
        direct.append(H.loads(pos, R, t, None, defl, sea=sea, wave_load_method="direct"))
        grid.append(H.loads(pos, R, t, None, defl, sea=sea, wave_load_method="grid"))
        calm.append(H.loads(pos, R, t, Wave(), defl))
    direct, grid, calm = np.array(direct), np.array(grid), np.array(calm)
    return np.abs(grid - direct).max(axis=0) / np.ptp(direct - calm, axis=0)


@pytest.mark.parametrize("case", ["self-propulsion, head seas", "turning in oblique seas"])
def test_grid_wave_loads_within_half_a_percent_of_direct_integration_over_a_run(case):
    if case.startswith("self"):   # the benchmark's sea (benchmarks/rom_speed.py) and run, 60 s of it
        sea = ComponentSea(discretise(JonswapSpectrum(3.25, 9.7, 3.3), 64, seed=1, spreading=Cos2sSpreading(0.0, 4.0)))
        s = maneuver_settings("self-propulsion", duration=60.0, sea_state=0)
    else:                         # a 20 deg rudder turn at periscope-ish depth through a sea from 30 deg
        sea = ComponentSea(discretise(JonswapSpectrum(3.25, 9.7), 64, seed=11,
                                      spreading=Cos2sSpreading(math.radians(30.0), 4.0), mean_direction_deg=30.0))
        s = maneuver_settings("turning-circle", duration=60.0, depth=15.3724, sea_state=0)
    model = BB2Model(profile=s.profile, sea=sea)
    err = _errors(model, _fly(model, s, every=10))          # every 0.5 s
    assert np.all(err < 0.005), err


def test_grid_wave_loads_stay_finite_where_k_z_passes_float32s_exp_range():
    """The grid evaluates exp(k z) in float32 (overflow at k z = 88.7): a hull lifted 40 m out of a short sea
    (k z up to ~150 at its top) still gets finite loads, capped rather than inf * 0 = NaN."""
    sea = ComponentSea(discretise(JonswapSpectrum(1.0, 3.0), 16, seed=3))   # k up to ~3.7 rad/m
    model = BB2Model(sea=sea)
    assert sea.components.wavenumber.max() * 40.0 > 88.7
    loads = model.hydro.loads(np.array([0.0, 0.0, 40.0]), rotation_native(0.0, 0.0, 0.0), 1.0, None, np.zeros(5),
                              sea=sea, wave_load_method="grid")
    assert np.all(np.isfinite(loads)), loads
