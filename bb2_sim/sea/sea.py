"""The sea seen by the ROM: free-surface elevation, dynamic pressure and orbital velocity at earth points.

Earth frame: native (z up, z = 0 the calm surface). Points are (n, 3) arrays [x_E, y_E, z_E] (m), t in s.
Linear deep-water theory for every component (the authors' formulas, SPEC 7.3-7.4, generalised):

    eta      = sum a cos(th),  th = k (x cos mu + y sin mu) - omega t + eps
    p_dyn    = rho g sum a exp(k z) cos(th)                       (the Froude-Krylov pressure)
    u_E, v_E = sum a omega exp(k z) cos(th') (cos mu, sin mu),  w_E = sum a omega exp(k z) sin(th')

with th' = th (the velocity of this elevation) or, with ``q12=True``, th' = th - pi/2: the authors' field
90 deg out of phase with the pressure (quirk Q12), which the ``iowa`` profile uses.

Implementations: :class:`ComponentSea` (any list of components: regular, irregular, short-crested, CSV)
and :class:`AuthorsTableSea` (the authors' sea-state table, evaluated by :mod:`bb2_sim.waves` so that it
equals today's runs bit for bit). Its component form is a cos wave with eps = -pi/2 (A sin(kx - wt)).
"""
from __future__ import annotations

import math

import numpy as np

from ..constants import G_M_S2
from ..waves import Wave, orbital_velocity_earth, pressure
from .components import WaveComponents

HALF_PI = 0.5 * math.pi


def _points(points_earth) -> np.ndarray:
    p = np.asarray(points_earth, dtype=float)
    if p.shape[-1] != 3:
        raise ValueError(f"earth points must have shape (..., 3), got {p.shape}")
    return p


class Sea:
    """Interface: ``calm``, ``elevation``, ``pressure_head``, ``orbital_velocity``, ``components``."""

    calm: bool = True

    def elevation(self, x_earth, y_earth, t: float) -> np.ndarray:
        """Free-surface elevation eta (m, z up) at earth (x, y)."""
        raise NotImplementedError

    def pressure_head(self, points_earth, t: float) -> np.ndarray:
        """Dynamic (wave) pressure over rho g (m) at earth points, shape points.shape[:-1]."""
        raise NotImplementedError

    def orbital_velocity(self, points_earth, t: float, *, q12: bool = False) -> np.ndarray:
        """Orbital velocity (m/s, earth axes) at earth points, shape points.shape."""
        raise NotImplementedError

    @property
    def components(self) -> WaveComponents | None:
        """The linear components (None = calm)."""
        raise NotImplementedError

    def pressure(self, points_earth, t: float, rho: float, g: float) -> np.ndarray:
        """Hydrostatic + dynamic pressure (Pa) -rho g (z - p_dyn / (rho g)) at earth points."""
        p = _points(points_earth)
        return (-rho * g) * (p[..., 2] - self.pressure_head(p, t))


class ComponentSea(Sea):
    """A linear sea from :class:`WaveComponents` (vectorised over points and components)."""

    def __init__(self, comps: WaveComponents):
        self._c = comps
        self.calm = not np.any(comps.amplitude > 0)
        self._k = comps.wavenumber
        self._kx = self._k * np.cos(comps.direction)
        self._ky = self._k * np.sin(comps.direction)
        self._kxy = np.array([self._kx, self._ky])                          # (2, I)
        self._dir2 = np.column_stack([np.cos(comps.direction), np.sin(comps.direction)])   # (I, 2)
        self._aw = comps.amplitude * comps.omega

    @property
    def components(self) -> WaveComponents:
        return self._c

    def _phase(self, x, y, t):
        c = self._c
        return (np.multiply.outer(x, self._kx) + np.multiply.outer(y, self._ky)) - c.omega * t + c.phase

    def elevation(self, x_earth, y_earth, t: float) -> np.ndarray:
        x = np.asarray(x_earth, dtype=float)
        y = np.broadcast_to(np.asarray(y_earth, dtype=float), x.shape)
        return np.cos(self._phase(x, y, t)) @ self._c.amplitude

    def pressure_head(self, points_earth, t: float) -> np.ndarray:
        p = _points(points_earth)
        th = self._phase(p[..., 0], p[..., 1], t)
        decay = np.exp(np.multiply.outer(p[..., 2], self._k))
        return (decay * np.cos(th)) @ self._c.amplitude

    def orbital_velocity(self, points_earth, t: float, *, q12: bool = False) -> np.ndarray:
        p = _points(points_earth)
        c = self._c
        # the phase th' from one product with [kx; ky], the constant part (and Q12's -pi/2) per component
        th = p[..., :2] @ self._kxy
        th += (c.phase - HALF_PI if q12 else c.phase) - c.omega * t
        amp = np.exp(np.multiply.outer(p[..., 2], self._k))
        amp *= self._aw
        out = np.empty(p.shape)
        out[..., :2] = (amp * np.cos(th)) @ self._dir2
        amp *= np.sin(th)
        out[..., 2] = amp.sum(axis=-1)
        return out


class AuthorsTableSea(Sea):
    """The authors' regular head-sea wave of a sea state (SPEC 7.4), through :mod:`bb2_sim.waves` as is."""

    def __init__(self, wave: Wave, g: float = G_M_S2):
        self.wave = wave
        self.g = g
        self.calm = wave.calm

    @classmethod
    def for_sea_state(cls, sea_state: float, params=None, *, strict: bool = True) -> "AuthorsTableSea":
        from ..parameters import load_parameters
        from ..waves import wave_for_sea_state
        params = params or load_parameters()
        return cls(wave_for_sea_state(sea_state, params, strict=strict), params.g)

    @property
    def components(self) -> WaveComponents | None:
        w = self.wave
        if w.calm:
            return None
        # pressure A sin(kx - wt) = A cos(kx - wt - pi/2); the heading parameter only splits u/v (SPEC 7.4)
        return WaveComponents([w.amplitude], [w.omega], [-math.pi * w.heading_param], [-HALF_PI], self.g)

    def elevation(self, x_earth, y_earth, t: float) -> np.ndarray:
        w = self.wave
        x = np.asarray(x_earth, dtype=float)
        if w.calm:
            return np.zeros(x.shape)
        return w.amplitude * np.sin(w.wavenumber * x - w.omega * t)

    def pressure_head(self, points_earth, t: float) -> np.ndarray:
        p = _points(points_earth)
        return pressure(self.wave, p[..., 0], p[..., 2], t, 1.0, 1.0) + p[..., 2]

    def pressure(self, points_earth, t: float, rho: float, g: float) -> np.ndarray:
        p = _points(points_earth)
        return pressure(self.wave, p[..., 0], p[..., 2], t, rho, g)

    def orbital_velocity(self, points_earth, t: float, *, q12: bool = False) -> np.ndarray:
        p = _points(points_earth)
        return orbital_velocity_earth(self.wave, p[..., 0], p[..., 2], t, in_phase_with_pressure=not q12)


def calm_sea() -> ComponentSea:
    return ComponentSea(WaveComponents([0.0], [1.0], [0.0], [0.0]))
