"""Regular deep-water waves of the BB2 ROM (SPEC 7.4): parameters per sea state, pressure and orbital velocity.

Earth frame: native, z up, z = 0 on the calm surface; the wave travels towards +x_earth.
"""
from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from .parameters import RomParameters


class SeaStateError(ValueError):
    """Sea state outside the table."""


@dataclass(frozen=True)
class Wave:
    """A regular wave: amplitude A (m), wavenumber k (rad/m), frequency omega (rad/s); A = 0 is calm."""

    amplitude: float = 0.0
    wavenumber: float = 0.0
    omega: float = 0.0
    phase: float = 0.0
    heading_param: float = 0.0
    sea_state: int = 0

    @property
    def calm(self) -> bool:
        return self.amplitude == 0.0

    @property
    def length(self) -> float:
        return 2 * math.pi / self.wavenumber if self.wavenumber else math.inf

    @property
    def period(self) -> float:
        return 2 * math.pi / self.omega if self.omega else math.inf


def wave_for_sea_state(sea_state: float, params: RomParameters, *, strict: bool = True) -> Wave:
    """The model's wave for an integer sea state (0 and 1 are calm, 2..7 tabulated).

    With ``strict`` a value outside 0..7 or a non-integer raises :class:`SeaStateError`; without it the
    model's own rule applies (anything not in the table is calm water).
    """
    if not math.isfinite(sea_state):
        raise SeaStateError(f"sea state must be finite, got {sea_state!r}")
    ss = int(sea_state) if float(sea_state).is_integer() else None
    table = params.sea_states
    if ss is None or (strict and not (0 <= ss <= max(table))):
        if strict:
            raise SeaStateError(f"sea state {sea_state!r} is outside the table (integers 0..{max(table)}; "
                                f"0 and 1 are calm)")
        return Wave()
    if ss not in table:
        return Wave(sea_state=ss)
    Lw, A = table[ss]
    k = 2 * math.pi / Lw
    return Wave(A, k, math.sqrt(params.g * k), params.wave_phase, params.wave_heading_param, ss)


def orbital_velocity_earth(wave: Wave, x: np.ndarray, z: np.ndarray, t: float,
                           in_phase_with_pressure: bool = False) -> np.ndarray:
    """Orbital velocity (u, v, w) in earth axes at points (x, z), shape x.shape + (3,).

    Default (quirk Q12, as implemented): the field of the elevation -A cos(kx - wt), 90 deg out of phase
    with the pressure. ``in_phase_with_pressure``: the field of A sin(kx - wt), consistent with the pressure.
    """
    x = np.asarray(x, dtype=float)
    if wave.calm:
        return np.zeros(x.shape + (3,))
    return orbital_velocity_of(wave.wavenumber, wave.omega, wave.phase, wave.amplitude * wave.omega,
                               math.cos(math.pi * wave.heading_param), math.sin(math.pi * wave.heading_param),
                               x, np.asarray(z, dtype=float), t, in_phase_with_pressure)


def orbital_velocity_of(k, omega, phase, a_omega, cos_heading, sin_heading, x: np.ndarray, z: np.ndarray, t,
                        in_phase_with_pressure: bool) -> np.ndarray:
    """:func:`orbital_velocity_earth` from the wave's numbers: wavenumber k, frequency omega, phase, A omega and the
    heading's cosine and sine -- floats for one wave, or arrays broadcasting against the points (x, z) for several
    (the batch ROM's boats: every operation element by element, so each boat's values are its own call's)."""
    out = np.zeros(np.shape(x) + (3,))
    th = k * x - omega * t + phase
    amp = a_omega * np.exp(k * z)
    if in_phase_with_pressure:
        horiz = amp * np.sin(th)
        out[..., 2] = -amp * np.cos(th)
    else:
        horiz = -amp * np.cos(th)
        out[..., 2] = -amp * np.sin(th)
    out[..., 0] = horiz * cos_heading
    out[..., 1] = -horiz * sin_heading
    return out


def pressure(wave: Wave, x: np.ndarray, z: np.ndarray, t: float, rho: float, g: float) -> np.ndarray:
    """Hydrostatic + Froude-Krylov pressure at earth points (x, z): -rho g (z - A exp(kz) sin(kx - wt)), Pa."""
    z = np.asarray(z, dtype=float)
    if wave.calm:
        return (-rho * g) * z
    return (-rho * g) * (z - wave.amplitude * np.exp(wave.wavenumber * z)
                         * np.sin(wave.wavenumber * np.asarray(x, dtype=float) - wave.omega * t))


class PhaseSine:
    """Vectorised sine of wave phases given in *turn units* (phase / (2 pi / n)), exact to round-off.

    numpy's float64 ``sin`` is a scalar libm call per element on most machines (~9 ns); this evaluates
    sin(2 pi tau / n) as the angle sum of a tabulated grid angle and a remainder |eps| <= pi / n:

        sin(g + eps) = sin g + sin g (cos eps - 1) + cos g sin eps,

    with the short Taylor series of sin eps and cos eps - 1 truncated far below one ulp (n = 4096:
    |eps| <= 7.7e-4, first dropped terms eps^5/120 and eps^6/720 are < 3e-18). The result agrees with
    ``np.sin`` of the same angle to a few ulp; the only other difference is where the argument is rounded.
    """

    def __init__(self, n: int = 4096):
        if n < 4096 or n & (n - 1):
            raise ValueError(f"PhaseSine needs a power of two >= 4096 grid points, got {n}")
        self.n = n
        self.turn = 2.0 * math.pi / n            # rad per turn unit
        # sin and cos of the grid angles from the first octant only (there the rounding of the angle is
        # relative, so every entry is accurate to an ulp of its own size), unfolded by symmetry
        j = np.arange(n // 8 + 1) * self.turn
        s8, c8 = np.sin(j), np.cos(j)
        r = np.arange(n // 4)
        lo = r <= n // 8
        sin_q = np.where(lo, s8[np.minimum(r, n // 8)], c8[np.minimum(n // 4 - r, n // 8)])
        cos_q = np.where(lo, c8[np.minimum(r, n // 8)], s8[np.minimum(n // 4 - r, n // 8)])
        self._sin = np.concatenate([sin_q, cos_q, -sin_q, -cos_q])
        self._cos = np.roll(self._sin, -(n // 4))

    def __call__(self, tau: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """sin(tau * 2 pi / n) for a float64 array tau (turn units); ``out`` may be tau itself."""
        q = np.rint(tau)
        idx = q.astype(np.int64)
        np.bitwise_and(idx, self.n - 1, out=idx)
        eps = tau - q
        eps *= self.turn
        s = self._sin.take(idx)
        c = self._cos.take(idx)
        e2 = np.multiply(eps, eps, out=q)
        c *= eps
        sin_eps_ratio = e2 * (-1.0 / 6.0)
        sin_eps_ratio += 1.0
        c *= sin_eps_ratio                        # cos g * sin eps
        e4 = np.multiply(e2, e2, out=sin_eps_ratio)
        e4 *= 1.0 / 24.0
        e2 *= -0.5
        e2 += e4                                  # cos eps - 1
        e2 *= s
        c += e2                                   # + sin g (cos eps - 1)
        return np.add(s, c, out=out)
